"""The race: each method's best trials scored again on more tuning seeds, each drawing its own
data, so the choice is the best mean rather than the best single score (``TuneConfig.race``;
measured on radius in ``docs/benchmark.md``)."""

from __future__ import annotations

import math
import zlib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from optuna.trial import TrialState

from sim.experiment.config import Execution
from sim.experiment.sweep import layered, plan, run_together
from sim.experiment.trials import (
    TRIAL_TRAIN,
    as_settings,
    objective_so_far,
    trial_seconds,
    validation_inputs,
)


def race_seed(seed: int, index: int) -> int:
    """The root seed of a race's ``index``-th extra seed (from 1): drawn from the tuning's seed,
    so two tunings with different seeds never share a race's data."""
    derived = np.random.SeedSequence([seed, index, zlib.crc32(b"race")])
    return int(derived.generate_state(1)[0] % 2**31)


def race_best(
    tune, out: Path, execution: Execution, studies: dict[str, Any], methods: list[str]
) -> dict[str, dict[int, list[float]]]:
    """Score each method's ``tune.race`` best complete trials (``tune``: the tuning's
    ``TuneConfig``, untyped here: the tuning imports this module) again on ``tune.race_seeds`` more
    seeds, all in one round; returns per method and trial number its objectives, its own first
    (a diverged run's as infinity)."""

    base = replace(tune.base, seeds=1, record=False)
    entrants, planned = [], []
    for method in methods:
        complete = studies[method].get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
        best = sorted(
            (t for t in complete if math.isfinite(t.value)), key=lambda t: (t.value, t.number)
        )
        for trial in best[: tune.race]:
            entrants.append((method, trial))
            settings = as_settings(method, trial.params)
            settings["train"] = {**settings.get("train", {}), **TRIAL_TRAIN}
            for index in range(1, tune.race_seeds + 1):
                config = replace(
                    base.only(method, layered(base, settings)), seed=race_seed(base.seed, index)
                )
                folder = out / "trials" / method / f"race_{trial.number:03d}_seed_{index}"
                resumed = (folder / "config.json").is_file()
                label = f"{method} {trial.number} race {index}"
                label, config, folder, curriculum = plan(label, config, folder, execution, resumed)
                curriculum.inputs = validation_inputs(curriculum)
                planned.append((label, config, folder, curriculum))
    costs = [trial_seconds(out, config.methods[0]) for _, config, *_ in planned]
    done = iter(run_together(planned, execution, resume=True, argv=[], costs=costs, figures=False))
    raced: dict[str, dict[int, list[float]]] = {}
    for method, trial in entrants:
        scores = [trial.value]
        for _ in range(tune.race_seeds):
            _, (job,) = next(done)
            final = round(float(objective_so_far(job.result, tune.metric)[-1]), 6)
            scores.append(final if math.isfinite(final) else math.inf)
        raced.setdefault(method, {})[trial.number] = scores
    return raced
