"""Is the confounder live? Figures measured after each task on the test splits of seen tasks.

For every learner: task-id accuracy of a linear probe from raw observed features (is the domain
visible in X at all?) and from the backbone's context. For C2INet's model, also: KL_C and KL_Z
in nats, an estimate of MI(X; C), the probe from C's posterior mean, the queue (size, weights,
each task's share of the responsibilities), ADE with C at its posterior mean against C from one
prior sample (and how far that moves the prediction), and confounder recovery: the adjusted
Rand index and NMI between each agent's most responsible component's owner task and its true
domain, and the cross-validated R^2 of the knob value predicted from C.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from c2inet.batch import make_batch
from c2inet.data import Windows
from c2inet.device import model_device, seeded
from c2inet.gaussians import (
    gaussian_log_prob,
    gaussian_sample,
    kl_standard_normal,
    minibatch_mutual_information,
    responsibilities,
)
from c2inet.lazy import lazy_module

# scikit-learn (a second of import) loads where a probe first runs, not in every process that
# imports the trainer
sk_linear = lazy_module("sklearn.linear_model")
sk_metrics = lazy_module("sklearn.metrics")
sk_selection = lazy_module("sklearn.model_selection")
sk_pipeline = lazy_module("sklearn.pipeline")
sk_preprocessing = lazy_module("sklearn.preprocessing")

PROBE_FOLDS = 4
MI_INPUTS = 2000  # inputs of the MI estimate (its cost grows with their square)


def observed_features(windows: Windows) -> np.ndarray:
    """Per scene, hand-made statistics of the observed frames only (scenes, 10).

    Mean velocity, speed (mean, std), acceleration, heading change, straightness, agent count
    and neighbour distances: what a domain could show in X, with no learned part.
    """
    obs = windows.positions[:, : windows.obs_len].astype(np.float64)
    steps = np.diff(obs, axis=1)  # (N, 7, 2)
    speed = np.linalg.norm(steps, axis=-1)
    heading = np.arctan2(steps[..., 1], steps[..., 0])
    turn = np.abs(np.angle(np.exp(1j * np.diff(heading, axis=1))))
    accel = np.linalg.norm(np.diff(steps, axis=1), axis=-1)
    straight = np.linalg.norm(obs[:, -1] - obs[:, 0], axis=-1) / (speed.sum(1) + 1e-9)
    velocity = steps.mean(1)  # (N, 2)
    per_agent = np.stack(
        [*velocity.T, speed.mean(1), speed.std(1), accel.mean(1), turn.mean(1), straight], axis=1
    )
    rows = []
    for s in range(len(windows)):
        agents = slice(windows.scene_start[s], windows.scene_start[s + 1])
        last = obs[agents, -1]
        gaps = np.linalg.norm(last[:, None] - last[None], axis=-1) + np.diag(
            np.full(len(last), np.inf)
        )
        nearest = gaps.min(1) if len(last) > 1 else np.array([-1.0])  # -1: nobody near
        rows.append([*per_agent[agents].mean(0), len(last), nearest.mean(), nearest.min()])
    features = np.array(rows)
    return np.nan_to_num(features, nan=-1.0, posinf=-1.0)


def _folds(labels: np.ndarray, seed: int):
    """Stratified folds, as many as the rarest class allows (None below 2 classes or 2 each)."""
    classes, counts = np.unique(labels, return_counts=True)
    if len(classes) < 2 or counts.min() < 2:
        return None
    return sk_selection.StratifiedKFold(
        min(PROBE_FOLDS, counts.min()), shuffle=True, random_state=seed
    )


def _probeable(features: np.ndarray) -> bool:
    """Features a probe can standardise: finite, with a finite variance (a diverged model's can
    be NaN, or finite but so large that their variance overflows)."""
    values = np.asarray(features, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        return bool(np.isfinite(values).all() and np.isfinite(values.var(axis=0)).all())


def probe_accuracy(features: np.ndarray, labels: np.ndarray, seed: int = 0) -> float | None:
    """Cross-validated accuracy of a linear (logistic) probe; None without 2 classes of 2, or
    for the features of a model whose training diverged (not finite)."""
    folds = _folds(labels, seed)
    if folds is None or not _probeable(features):
        return None
    probe = sk_pipeline.make_pipeline(
        sk_preprocessing.StandardScaler(), sk_linear.LogisticRegression(max_iter=1000)
    )
    predicted = sk_selection.cross_val_predict(probe, features, labels, cv=folds)
    return float((predicted == labels).mean())


def knob_r2(features: np.ndarray, values: np.ndarray, seed: int = 0) -> float | None:
    """Cross-validated R^2 of a linear (ridge) regression of the knob value on the features
    (None as for :func:`probe_accuracy`)."""
    labels = np.unique(values, return_inverse=True)[1]
    folds = _folds(labels, seed)
    if folds is None or not _probeable(features):
        return None
    model = sk_pipeline.make_pipeline(sk_preprocessing.StandardScaler(), sk_linear.Ridge(alpha=1.0))
    predicted = sk_selection.cross_val_predict(
        model, features, values, cv=folds.split(features, labels)
    )
    return float(sk_metrics.r2_score(values, predicted))


def mutual_information(mean: torch.Tensor, logvar: torch.Tensor, samples: int = 4) -> float:
    """MI(X; C) in nats, minibatch estimate E[log q(c|x_i) - log (1/n) sum_j q(c|x_j)].

    Over n inputs it is at most log n: read it against that bound.
    """
    noise = torch.randn(samples, *mean.shape, device=mean.device)
    c = gaussian_sample(mean, logvar, noise)  # (S, n, d)
    return float(minibatch_mutual_information(c, mean, logvar))


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(float(value), 4)


@torch.no_grad()
def diagnose(
    model: torch.nn.Module,
    tests: Sequence[Windows],
    values: Sequence[float | None],
    seed: int = 0,
) -> dict[str, Any]:
    """Diagnostics after a task, on the test splits of the tasks seen so far (in order)."""
    labels = np.concatenate([np.full(len(w), i) for i, w in enumerate(tests)])
    raw = np.concatenate([observed_features(w) for w in tests])
    out: dict[str, Any] = {"probe_observed": _rounded(probe_accuracy(raw, labels, seed))}
    if not hasattr(model, "context"):
        return out
    was_training = model.training
    model.eval()
    batches = [make_batch(w, device=model_device(model)) for w in tests]
    context = np.concatenate([b.pool(model.context(b)).cpu().numpy() for b in batches])
    out["probe_context"] = _rounded(probe_accuracy(context, labels, seed))
    if hasattr(model, "posteriors"):
        with seeded(seed, model_device(model)):
            out.update(_confounder(model, batches, labels, values, seed))
    model.train(was_training)
    return out


def _queue_shares(queue, responsibility, owners, labels, tasks: int) -> dict[str, Any]:
    """The queue's size, weights and owners, and ``share[j][i]``: the responsibility of task i's
    components on task j's scenes."""
    share = [
        [
            round(float(responsibility[labels == j][:, owners == i].sum(1).mean()), 4)
            for i in range(tasks)
        ]
        for j in range(tasks)
    ]
    return {
        "size": len(queue.mixture),
        "weights": [round(float(w), 5) for w in queue.mixture.weights],
        "owners": list(queue.owners),
        "share": share,
    }


def _confounder(model, batches, labels, values, seed) -> dict[str, Any]:
    """The C2INet part of :func:`diagnose`."""
    queue, cfg = model.queue, model.config
    posts = [model.posteriors(b) for b in batches]
    c_mean = torch.cat([p.c_mean for p in posts])
    c_logvar = torch.cat([p.c_logvar for p in posts])
    out: dict[str, Any] = {"kl_c": [], "kl_z": [], "ade_c_mean": [], "ade_c_prior": []}
    prior = queue.training_prior()  # the prior the KL was trained against
    shifts = []
    for batch, post in zip(batches, posts, strict=True):
        noise = torch.randn(cfg.n_mc, *post.c_mean.shape, device=post.c_mean.device)
        c = gaussian_sample(post.c_mean, post.c_logvar, noise)
        kl_c = (gaussian_log_prob(c, post.c_mean, post.c_logvar) - prior.log_prob(c)).mean(0)
        kl_z = kl_standard_normal(*model.z_posterior(batch, post, c)).mean(0)
        out["kl_c"].append(_rounded(model.per_scene(kl_c, batch).mean()))
        out["kl_z"].append(_rounded(batch.per_scene_mean(kl_z).mean()))
        at_mean = model.predict(batch, 1, "posterior_mean", z_mean=True, post=post)[0]
        at_prior = model.predict(batch, 1, "prior", z_mean=True, post=post)[0]
        for key, pred in (("ade_c_mean", at_mean), ("ade_c_prior", at_prior)):
            out[key].append(_rounded((pred - batch.fut).norm(dim=-1).mean()))
        shifts.append((at_mean - at_prior).norm(dim=-1).mean(0))
    out["c_effect"] = _rounded(torch.cat(shifts).mean())  # metres the prediction moves with C
    counts = np.concatenate([b.agent_counts.cpu().numpy() for b in batches])
    if not model.c_per_scene:  # one C per agent: pool it per scene for the probe
        c_scene = torch.cat([b.pool(p.c_mean) for b, p in zip(batches, posts, strict=True)])
        c_labels = np.repeat(labels, counts)
    else:
        c_scene, c_labels = c_mean, labels
    subset = torch.randperm(len(c_mean), device=c_mean.device)[:MI_INPUTS]
    out["mi_xc"] = _rounded(mutual_information(c_mean[subset], c_logvar[subset]))
    out["mi_bound"] = _rounded(math.log(len(subset)))
    out["probe_c"] = _rounded(probe_accuracy(c_scene.cpu().numpy(), labels, seed))
    responsibility = responsibilities(queue.mixture, c_mean, c_logvar)  # p(k | X), (n, K)
    owners = torch.tensor(queue.owners, device=c_mean.device)
    tasks = len(batches)
    out["queue"] = _queue_shares(queue, responsibility, owners, c_labels, tasks)
    # each agent's most responsible component's owner task, against its true domain
    owner_task = owners[responsibility.argmax(-1)].cpu().numpy()
    domain = np.repeat(labels, counts)
    if model.c_per_scene:
        owner_task = np.repeat(owner_task, counts)
    if tasks > 1:
        out["ari"] = _rounded(sk_metrics.adjusted_rand_score(domain, owner_task))
        out["nmi"] = _rounded(sk_metrics.normalized_mutual_info_score(domain, owner_task))
    if all(v is not None for v in values):
        knob = np.array([values[i] for i in labels], dtype=np.float64)
        out["knob_r2"] = _rounded(knob_r2(c_scene.cpu().numpy(), knob, seed))
    return out
