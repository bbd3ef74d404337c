"""The options of every learner's model (``ModelConfig``: sizes, loss weights, C2INet's
switches) and the latent models' search spaces, apart from the networks they configure."""

from __future__ import annotations

from dataclasses import dataclass

from c2inet.backbones import BACKBONES
from c2inet.kernels import MODES as KERNEL_MODES
from c2inet.options import Choice, Tunable, choose, require

C_SOURCES = ("posterior", "prior", "responsible")  # the test-time rules for C
DECODER_INPUTS = ("context", "latents")
PAST_INPUTS = ("z", "zc")


# the latent models' key knobs, searched by the tuner beside the learning rate (C2INet, its
# queue-free control, MoG, GCRL): the likelihood's sharpness and the two KL weights
LATENT_SPACE = {
    "model.likelihood_std": Tunable(0.03, 0.3, log=True),
    "model.beta_c": Tunable(0.01, 3.0, log=True),  # GCRL chose 0.10, the old floor
    "model.beta_z": Tunable(0.1, 3.0, log=True),
}
# C2INet's and its control's: the latent models' weights and the knobs its mechanism depends
# on (free bits of KL_C, the MI floor, the stopped gradient), so tuning, not a hand, sets them
C2INET_SPACE = {
    **LATENT_SPACE,
    # below the KL's working range (1 to 4 nats), so the tuned C2INet keeps its queue acting:
    # at 1 nat KL_C binds in >= 79 % of scenes, at 2 in 5 %, at 8 in none (c2inet_binding.py)
    "model.free_bits_c": Tunable(0.0, 1.0),
    "model.mi_floor_c": Tunable(0.0, 2.0),
    "model.c_detached": Choice((True, False)),
}


@dataclass
class ModelConfig:
    """Sizes and loss weights shared by every learner (defaults: method notes, sections 4-5, and
    the recorded sweep of ``docs/c2inet-study.md``)."""

    backbone: str = "stgat"
    # STGAT's kernels (c2inet.kernels): auto, compiled, tensor or cell, resolved where the
    # network is built (auto: compiled on the CPU, tensor elsewhere) and written to the run card
    kernels: str = "auto"
    latent_dim: int = 16  # noise size of the baselines; C2INet uses z_dim + c_dim
    # the baselines' noise: one draw per agent, or one per scene shared by its agents (STGAT's,
    # Social-GAN's "global" option: a sample moves a whole scene, as a best-of-K per scene scores
    # it)
    noise_per: str = "agent"
    z_dim: int = 8
    c_dim: int = 8
    likelihood_std: float = 0.1  # std of the Gaussian likelihood, in units of the scene scale
    beta_c: float = 1.0
    beta_z: float = 1.0
    beta_x: float = 0.0  # weight of the past reconstruction log p(X | z[, c]); 1 cost plasticity
    n_mc: int = 10  # Monte Carlo samples for the KL to the mixture and the past likelihood
    # test-time C: posterior (Q(C|X), GCRL's practice), prior (Eq 16 literally: C ~ P(C)), or
    # responsible (the queue component responsible for the observed past, then C from it)
    c_source: str = "posterior"
    c_per: str = "agent"  # one C per agent (GCRL, method notes 7.8) or per scene, train and test
    decoder_input: str = "context"  # P(Y|X,Z,C): [context, z, c]; "latents": [z, c] alone
    z_given_c: bool = True  # Q(Z|X,C) as Eq 16; off: Q(Z|X)
    past_from: str = "z"  # the past reconstruction reads z alone, or [z, c] ("zc")
    # KL_C below this many nats costs nothing. 0: the KL against the queue's prior (Eq 17) has
    # a gradient in every scene; the MI floor below keeps C from collapsing, since the mean KL
    # is at least MI(X; C). At 8 (the earlier default) Eq 17 bound in no scene of a last epoch
    free_bits_c: float = 0.0
    # liveness without a seed lottery or a cost in plasticity (docs/c2inet-study.md): a batch
    # whose MI(X; C) falls below mi_floor_c nats pays mi_weight per missing nat, and Q(C|X)
    # reads the context through a stopped gradient, so C's terms cannot reshape the backbone
    mi_floor_c: float = 1.0
    mi_weight: float = 10.0
    c_detached: bool = True
    # the share of agents whose decoder sees no context in a training step (classifier-free
    # style): the decoder must then predict from [z, c] alone, so C's value moves predictions
    # (live in every seed on both curricula of docs/c2inet-study.md; 0 is one key away)
    context_dropout: float = 0.1
    residual: bool = True  # decoder steps change the last displacement (constant-velocity prior)
    # the units of the likelihood's error (so of the variety loss, and of likelihood_std): the
    # displacements over their scene's motion scale (scale-free across scenes and domains), or
    # metres, as STGAT and Social-GAN train and as every error is reported
    loss_units: str = "scale"

    def __post_init__(self):
        if self.backbone not in BACKBONES:
            raise ValueError(
                f"backbone {self.backbone!r} is unknown (known: {', '.join(BACKBONES)})"
            )
        choose(self, "kernels", KERNEL_MODES)
        choose(self, "c_source", C_SOURCES)
        choose(self, "c_per", ("agent", "scene"))
        choose(self, "noise_per", ("agent", "scene"))
        choose(self, "decoder_input", DECODER_INPUTS)
        choose(self, "past_from", PAST_INPUTS)
        choose(self, "loss_units", ("scale", "metres"))
        require(self, 1, "latent_dim", "z_dim", "c_dim", "n_mc")
        require(self, 0, "beta_c", "beta_z", "beta_x", "free_bits_c", "mi_floor_c", "mi_weight")
        require(self, 0, "likelihood_std", open_low=True)
        require(self, 0, "context_dropout", high=1)
