"""GCRL (Bagi et al., ICML 2023): invariant Z and variant S, S under a learnable mixture prior.

GCRL's own network: the decoder sees [z, c] alone (``decoder_input="latents"``), the past is
reconstructed from [z, c] (E1, weight 1), Z is read from X alone and held to N(0, I), and no
free bits, MI floor or stopped gradient into C; GCRL's prior on the variant latent (here C)
is one mixture of ``components`` Gaussians with learnt means, variances and weights, trained
with the model on every task in turn: nothing protects it from forgetting. Test-time C comes
from the posterior, as GCRL evaluates. Left out: the RealNVP coupling flows of GCRL's
``--coupling`` variant (this is its learnable-prior variant, the one without flows). No hooks.
Example: ``--methods gcrl``
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch

from c2inet.methods.base import Method
from c2inet.model import C2INetModel
from c2inet.model_config import LATENT_SPACE
from c2inet.options import require
from c2inet.prior import LearnablePrior


@dataclass(frozen=True)
class GCRLOptions:
    components: int = 5  # GCRL's num_envs: Gaussians of the prior

    def __post_init__(self):
        require(self, 1, "components")


class GCRL(Method):
    """The causal STGAT model with a learnt Gaussian-mixture prior, trained sequentially."""

    name = "gcrl"
    search_space = LATENT_SPACE
    Options = GCRLOptions

    def build_model(self) -> torch.nn.Module:
        config = dataclasses.replace(
            self.model_config,
            decoder_input="latents",
            z_given_c=False,
            past_from="zc",
            beta_x=1.0,
            free_bits_c=0.0,
            mi_floor_c=0.0,
            c_detached=False,
            context_dropout=0.0,
        )
        prior = LearnablePrior(config.c_dim, self.options.components, learn_weights=True)
        return C2INetModel(config, prior=prior)
