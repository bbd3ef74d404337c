"""``python -m sim.study calibrate``: fit a crowd family's knobs to a recording's statistics.

``--reference`` names the recording (any family's domains, e.g. ``eth_ucy_eth``), of which only
the *training* split is read: the fit never sees a validation or test file. ``--scenario`` names
the crowd family to fit and its starting value (``crowd_noise_0.1``). Optuna's TPE sampler,
seeded by ``--seed``, tries ``--trials`` settings of the knobs in :data:`SPACE` (the family's
defaults first), each generating ``--scenes`` training scenes; the studies live in SQLite beside
the report, so an interrupted fit resumes to the same choices.

The objective is the distance between the two sides' per-window distributions of the realised
statistics (closest approach, speed, heading change, first-step speed: ``sim.stats``), each a
1-Wasserstein distance divided by the reference's own spread, averaged. The reference's long
recordings are cut into the generator's window (20 frames), so both sides are measured on the
same span. The fit writes ``calibrated_REF.toml``: the family with the fitted knobs as its
defaults, the reference's hash and the distances before and after, ready for ``--scenarios-dir``.
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError
from c2inet.files import write_text_atomic
from c2inet.lazy import lazy_module
from sim.data import Scene
from sim.domains import build_domain
from sim.families import Splits
from sim.scenario import DomainSpec, parse_scenario
from sim.stats import PROFILES, scene_profiles
from sim.studies.base import Study, register

# the learner, the engine and the figures load once there is work (sim.studies.base)
optuna = lazy_module("optuna")
scipy_stats = lazy_module("scipy.stats")
crowd = lazy_module("sim.generators.crowd")
study_figures = lazy_module("viz.study_figures")

# knob -> (low, high, integer); speed_spread is searched as a share of speed (it must stay below
# half of it); the categorical knobs among the generator's options (choices())
SPACE: dict[str, tuple[float, float, bool]] = {
    "agents": (2, 40, True),
    "speed": (0.5, 3.0, False),
    "speed_spread": (0.0, 0.5, False),
    "noise": (0.0, 0.6, False),
    "radius": (0.15, 0.4, False),
    "horizon": (0.5, 4.0, False),
}


def choices() -> dict[str, tuple[str, ...]]:
    """The categorical knobs: the crowd generator's own options (loaded with the simulator)."""
    # start: from rest, or at the preferred velocity (a recording's agents are moving)
    return {"layout": crowd.LAYOUTS, "start": crowd.STARTS, "controller": crowd.CONTROLLERS}


WINDOW = 20  # frames of a compared span: the generator's scene, a window of the learner


def windows_of(scenes: list[Scene], frames: int = WINDOW) -> list[Scene]:
    """``scenes`` cut into spans of ``frames`` frames that share none, each keeping the agents
    present in it: a long recording measured on the span a generated scene has."""
    out = []
    for scene in scenes:
        for start in range(0, scene.num_frames - frames + 1, frames):
            positions = scene.positions[start : start + frames]
            present = np.isfinite(positions).all(-1).any(0)
            if present.sum() >= 1:
                out.append(Scene(positions[:, present], scene.agent_ids[present]))
    return out


def profile_distances(
    generated: dict[str, np.ndarray], reference: dict[str, np.ndarray]
) -> dict[str, float | None]:
    """Per profile, the 1-Wasserstein distance of the two sides' finite values divided by the
    reference's spread (its standard deviation; 1 where it has none)."""
    out: dict[str, float | None] = {}
    for name in PROFILES:
        a, b = generated[name], reference[name]
        a, b = a[np.isfinite(a)], b[np.isfinite(b)]
        if not (a.size and b.size):
            out[name] = None
            continue
        spread = float(np.std(b)) or 1.0
        out[name] = float(scipy_stats.wasserstein_distance(a, b)) / spread
    return out


def objective_of(distances: dict[str, float | None]) -> float:
    """The mean of the profiles' scaled distances (a profile one side lacks counts as 10)."""
    return float(np.mean([10.0 if d is None else d for d in distances.values()]))


def knobs_of(params: dict[str, Any]) -> dict[str, Any]:
    """A trial's parameters as generator knobs (the spread back from its share of speed)."""
    knobs = dict(params)
    if "speed_spread" in knobs:
        knobs["speed_spread"] = round(knobs["speed_spread"] * knobs.get("speed", 1.0), 6)
    return knobs


def generated_spec(base: DomainSpec, knobs: dict[str, Any]) -> DomainSpec:
    """``base``'s family with ``knobs``: the family's own knob sets its value, the others its
    defaults (as ``--set data.KNOB`` would)."""
    family = base.family
    value = knobs.pop(family.knob, base.value) if family.knob else base.value
    family = replace(family, defaults={**family.defaults, **knobs})
    return DomainSpec(family, value, f"{value:g}" if isinstance(value, float) else str(value))


def reference_profiles(reference: str, seed: int, execution, extra: list[Path]) -> tuple:
    """The reference's training windows' profiles, its dt and a hash of what was read."""
    profiles, dts, digest = [], [], hashlib.sha256()
    for spec in parse_scenario(reference, extra):
        domain = build_domain(spec, seed, execution.cache, workers=execution.workers)
        scenes = windows_of(domain.scenes["train"])  # never val or test
        if not scenes:
            raise InputError(f"--reference {reference}: {spec.name} has no {WINDOW}-frame span")
        profiles.append(scene_profiles(scenes, domain.dt))
        dts.append(domain.dt)
        digest.update(f"{spec.name}:{domain.hash}".encode())
    if len(set(dts)) != 1:
        raise InputError(f"--reference {reference}: its domains differ in frame spacing")
    merged = {name: np.concatenate([p[name] for p in profiles]) for name in PROFILES}
    return merged, dts[0], digest.hexdigest()[:16]


def evaluate_knobs(
    base: DomainSpec,
    knobs: dict[str, Any],
    scenes: int,
    seed: int,
    reference: dict,
    workers: int = 1,
) -> tuple[float, dict[str, float | None]]:
    """Generate ``scenes`` training scenes with ``knobs`` and score them against ``reference``;
    a combination the generator refuses (too many agents for the area) scores infinity."""
    try:
        spec = generated_spec(base, dict(knobs))
        domain = build_domain(spec, seed, None, Splits(scenes, 1, 1), workers)
    except InputError:
        return math.inf, {}
    generated = scene_profiles(domain.scenes["train"], domain.dt)
    distances = profile_distances(generated, reference)
    return objective_of(distances), distances


@dataclass(frozen=True)
class CalibrateConfig:
    """A fit: the crowd family and its starting value (``scenario``), the recording
    (``reference``), Optuna's ``trials``, generated training ``scenes`` a trial, the ``seed`` of
    the sampler and of every generation, and extra family folders."""

    scenario: str
    reference: str
    trials: int = 40
    scenes: int = 60
    seed: int = 0
    extra: tuple[Path, ...] = ()


def starting_point(base: DomainSpec) -> dict[str, Any]:
    """The family's own knobs as a trial's parameters (the spread as a share of speed)."""
    point = {k: base.knobs[k] for k in SPACE}
    point["speed_spread"] = point["speed_spread"] / max(point["speed"], 1e-9)
    return {**point, **{name: base.knobs[name] for name in choices()}}


def suggest(trial) -> dict[str, Any]:
    """A trial's parameters over :data:`SPACE` and :func:`choices`."""
    params = {
        name: (trial.suggest_int if integer else trial.suggest_float)(name, low, high)
        for name, (low, high, integer) in SPACE.items()
    }
    return {**params, **{n: trial.suggest_categorical(n, list(c)) for n, c in choices().items()}}


def _side(trial) -> dict[str, Any]:
    return {
        "knobs": knobs_of(trial.params),
        "objective": trial.value,
        "distances": trial.user_attrs.get("distances", {}),
    }


def calibrate(fit: CalibrateConfig, execution, out: Path) -> dict[str, Any]:
    """Fit the knobs of ``fit.scenario``'s (first) family to the reference's training windows;
    returns the report and writes the calibrated family file into ``out``."""
    extra = list(fit.extra)
    base = parse_scenario(fit.scenario, extra)[0]
    if base.family.generator != "crowd":
        raise InputError(f"--scenario {fit.scenario}: calibrate fits a crowd family's knobs")
    target, dt, digest = reference_profiles(fit.reference, fit.seed, execution, extra)
    out.mkdir(parents=True, exist_ok=True)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(
        study_name=f"calibrate:{base.family.name}:{digest}:{fit.scenes}",
        storage=f"sqlite:///{(out / 'calibration.db').resolve()}",
        sampler=optuna.samplers.TPESampler(seed=fit.seed),
        direction="minimize",
        load_if_exists=True,
    )
    if not study.trials:
        study.enqueue_trial(starting_point(base))  # the family as it is comes first: "before"

    def objective(trial) -> float:
        knobs = knobs_of(suggest(trial))
        value, distances = evaluate_knobs(
            base, knobs, fit.scenes, fit.seed, target, execution.workers
        )
        trial.set_user_attr("distances", distances)
        return value if math.isfinite(value) else 1e9

    remaining = fit.trials - len([t for t in study.trials if t.state.is_finished()])
    if remaining > 0:
        study.optimize(objective, n_trials=remaining)
    stem = re.sub(r"[^a-z0-9]+", "_", fit.reference.split("+")[0].lower()).strip("_")
    report = {
        "scenario": fit.scenario,
        "family": base.family.name,
        "reference": fit.reference,
        "reference_hash": digest,
        "dt": dt,
        "trials": len(study.trials),
        "scenes": fit.scenes,
        "before": _side(study.trials[0]),
        "after": _side(study.best_trial),
        "history": [t.value for t in study.trials if t.value is not None],
        "family_file": f"calibrated_{stem}.toml",
    }
    fitted = report["after"]["knobs"]
    write_text_atomic(out / report["family_file"], family_toml(base, fitted, report))
    return report


def family_toml(base: DomainSpec, fitted: dict[str, Any], report: dict[str, Any]) -> str:
    """The calibrated family: ``base``'s family with the fitted knobs as its defaults."""
    knobs = {**base.family.defaults, **fitted}
    knobs.pop(base.family.knob, None)
    value = fitted.get(base.family.knob)
    lines = [
        f"# made by python -m sim.study calibrate from {base.family.name}, fitted to the training "
        f"windows of {report['reference']} (hash {report['reference_hash']}); objective "
        f"{report['before']['objective']:.3f} before, {report['after']['objective']:.3f} after"
        + (
            f"; fitted {base.family.knob} = {value:g} (give it as the scenario's value)"
            if value is not None
            else ""
        ),
        f'description = "{base.family.name} calibrated to {report["reference"]}"',
        f'generator = "{base.family.generator}"',
        f'knob = "{base.family.knob}"',
        "",
        "[knobs]",
        *(f"{k} = {_toml(v)}" for k, v in sorted(knobs.items())),
        "",
        "[splits]",
        *(f"{k} = {v}" for k, v in vars(base.family.splits).items()),
    ]
    return "\n".join(lines) + "\n"


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


def calibration_markdown(report: dict[str, Any]) -> str:
    before, after = report["before"], report["after"]
    rows = ["| profile | before (scaled W1) | after |", "|---|---|---|"]
    for name in PROFILES:
        b, a = before["distances"].get(name), after["distances"].get(name)
        rows.append(f"| {name} | {_num(b)} | {_num(a)} |")
    knobs = ["| knob | before | fitted |", "|---|---|---|"]
    for name in [*SPACE, *choices()]:
        knobs.append(f"| {name} | {before['knobs'].get(name)} | {after['knobs'].get(name)} |")
    return "\n".join(
        [
            f"# Calibration of `{report['family']}` to `{report['reference']}`",
            "",
            f"{report['trials']} Optuna trials (the family's own knobs first), {report['scenes']} "
            "generated scenes a trial, against the reference's training windows only (hash "
            f"`{report['reference_hash']}`). Objective: the mean over the profiles of the "
            "1-Wasserstein distance between the two sides' per-window distributions, divided "
            f"by the reference's spread: {before['objective']:.3f} before, "
            f"{after['objective']:.3f} after.",
            "",
            *rows,
            "",
            *knobs,
            "",
            f"The fitted family: `{report['family_file']}` (`--scenarios-dir` this folder).",
            "",
        ]
    )


def _num(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


class Calibrate(Study):
    name = "calibrate"
    title = "fit a crowd family's knobs to a recording's realised statistics"
    examples = (
        "--scenario crowd_noise_0.1 --reference eth_ucy_eth --trials 40",
        "--scenario crowd_noise_0.1 --reference eth_ucy_zara1 --scenes 40 --trials 20",
    )
    methods = "cv"

    markdown = staticmethod(calibration_markdown)

    def figure(self, report, path):
        study_figures.calibration_figure(report, path)

    def add_options(self, p):
        p.add_argument("--reference", required=True, help="the recording, e.g. eth_ucy_eth")
        p.add_argument("--trials", type=int, default=40, help="Optuna trials (40)")
        p.add_argument(
            "--scenes", type=int, default=60, help="generated training scenes a trial (60)"
        )

    def run(self, args, config, execution, out, argv):
        if not 1 <= args.trials <= 10_000 or not 1 <= args.scenes <= 10_000:
            raise InputError("--trials and --scenes: expected 1 to 10000")
        fit = CalibrateConfig(
            args.scenario,
            args.reference,
            args.trials,
            args.scenes,
            config.seed,
            tuple(config.scenarios_dir),
        )
        return calibrate(fit, execution, out)


register(Calibrate())
