"""``python -m sim.study drift``: a knob drifting within one stream, learnt without task boundaries.

``--scenario crowd_noise_0.1..0.6`` gives the family, the drift (from the first value to the
last, linearly over ``--scenes`` scenes, each simulated at its own value) and the probe bins (a
fixed test set at each value). The stream arrives in ``--chunks`` chunks; after each, every
method is evaluated on every probe: the error-over-time matrix. Task hooks run only at the
boundaries ``--boundaries`` gives: ``detect`` (a shift detector on the data,
``c2inet.stream.ShiftDetector``), ``none``, or ``chunks`` (every chunk, the oracle of a
task-based protocol). Methods whose mechanism lives in those hooks are marked as needing them.

Per method: the final and the anytime (mean over time) probe error, and forgetting without task
boundaries: per probe, its final error minus the lowest it had once the stream had reached its
value. It writes ``drift.json``, ``drift.md`` and ``drift.png`` to ``--out``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from c2inet.errors import InputError
from c2inet.lazy import lazy_module
from c2inet.options import check_range
from sim.domains import domain_seed
from sim.generators import child_seed
from sim.scenario import DomainSpec
from sim.studies.base import Study, register
from viz.cli import bounded_float, bounded_int

if TYPE_CHECKING:  # the learner and the engine load once there is work (``sim.studies.base``)
    from c2inet.data import Windows
    from sim.experiment import Execution, ExperimentConfig

# the learner, the engine and the figures load once there is work (sim.studies.base)
streaming = lazy_module("c2inet.stream")
engine = lazy_module("sim.experiment")
cell_runs = lazy_module("sim.experiment.cells")
curriculum = lazy_module("sim.experiment.curriculum")
study_figures = lazy_module("viz.study_figures")

BOUNDARIES = ("detect", "none", "chunks")
DEFAULT_METHODS = "finetune,ewc,derpp,c2inet-online"


@dataclass(frozen=True)
class DriftOptions:
    """The stream: its length in scenes, how many chunks it arrives in, where boundaries are."""

    scenes: int = 600
    chunks: int = 12
    boundaries: str = "detect"
    threshold: float = 0.15  # the detector's relative change of a feature

    def __post_init__(self):
        check_range("scenes", self.scenes, 2, 100_000)
        check_range("chunks", self.chunks, 1, self.scenes)
        check_range("threshold", self.threshold, 0, 10, open_low=True)
        if self.boundaries not in BOUNDARIES:
            raise InputError(
                f"boundaries={self.boundaries!r} is unknown (known: {', '.join(BOUNDARIES)})"
            )


def drift_specs(config: ExperimentConfig) -> list[DomainSpec]:
    """The probe domains: one numeric family that can simulate single scenes, two values or
    more."""
    where = f"scenario {config.scenario!r} (a drift)"
    return curriculum.knob_grid(config.specs, where, "crowd_noise_0.1..0.6", single_scenes=True)


def drift_stream(
    specs: list[DomainSpec], options: DriftOptions, seed: int
) -> tuple[list[Windows], np.ndarray]:
    """The stream's chunks of windows, in order, and the knob value at each chunk's middle.

    Scene ``i`` is simulated at ``start + (end - start) * i / (scenes - 1)`` from its own child
    seed, so the stream is the same whatever the chunking.
    """
    family, start, end = specs[0].family, specs[0].value, specs[-1].value
    values = np.linspace(start, end, options.scenes)
    root = domain_seed(seed, replace(specs[0], label="drift"))
    seeds = [child_seed(root, i) for i in range(options.scenes)]
    bounds = np.linspace(0, options.scenes, options.chunks + 1).round().astype(int)
    pieces = list(zip(bounds[:-1], bounds[1:], strict=True))
    chunks = [curriculum.scene_windows(family, values[a:b], seeds[a:b]) for a, b in pieces]
    middles = np.array([values[(a + b - 1) // 2] for a, b in pieces])
    return chunks, middles


def stream_run(
    method: str, seed_index: int, config: ExperimentConfig, chunks, probes, options
) -> dict[str, list]:
    """One method and seed through the stream (a cell): the (chunks x probes) ADE and FDE, and
    the boundaries the detector found and the method was given."""
    train = replace(config.train_config(seed_index), diagnostics=False, val_every=0)
    learner = streaming.StreamLearner(config.method(method), train)
    detector = streaming.ShiftDetector(options.threshold)
    ade, fde, found = np.zeros((len(chunks), len(probes))), np.zeros((len(chunks), len(probes))), []
    for c, chunk in enumerate(chunks):
        if detector(chunk):
            found.append(c)
        boundary = {"detect": c in found, "none": False, "chunks": c > 0}[options.boundaries]
        learner.learn(chunk, boundary)
        for j, probe in enumerate(probes):
            scores = learner.evaluate(probe, train.seed + j)
            ade[c, j], fde[c, j] = scores["ade"], scores["fde"]
    return {"ade": ade.tolist(), "fde": fde.tolist(), "found": found, "given": learner.boundaries}


def forgetting(errors: np.ndarray, middles: np.ndarray, probe_values: list[float]) -> np.ndarray:
    """Per probe: final error minus the lowest error from the chunk whose middle first reached
    the probe's value (the stream has seen that regime) to the end."""
    out = []
    for j, value in enumerate(probe_values):
        reached = np.flatnonzero(middles >= value - 1e-9)
        first = reached[0] if len(reached) else len(middles) - 1
        out.append(errors[-1, j] - errors[first:, j].min())
    return np.array(out)


def run_drift(
    config: ExperimentConfig,
    options: DriftOptions,
    execution: Execution | None = None,
    folder: Path | None = None,
    resume: bool = False,
) -> dict[str, Any]:
    """Every method and seed of ``config`` through the drift stream, as cells on
    ``execution``'s backend (kept in ``folder``, if given, for ``resume``); the report."""
    execution = execution or engine.Execution()
    specs = drift_specs(config)
    if config.quick:
        options = replace(options, scenes=min(options.scenes, 24), chunks=min(options.chunks, 3))
    tasks, _ = curriculum.experiment_tasks(specs, config, execution)
    probes = [task.test for task in tasks]
    probe_values = [float(spec.value) for spec in specs]
    chunks, middles = drift_stream(specs, options, config.seed)
    cells = {f"{m}-seed_{s}": (m, s) for m in config.methods for s in range(config.seeds)}
    data = [w.positions for w in chunks + probes]
    identity = cell_runs.cell_identity("drift", config.to_json(), asdict(options), arrays=data)
    shared = (config, chunks, probes, options)
    done = cell_runs.run_cells(stream_run, cells, shared, execution, folder, identity, resume)
    methods = {
        name: {
            "needs_boundaries": config.method(name).needs_boundaries(),
            **method_summary(
                [done[f"{name}-seed_{s}"] for s in range(config.seeds)], middles, probe_values
            ),
        }
        for name in config.methods
    }
    return {
        "scenario": config.scenario,
        "family": specs[0].family.name,
        "knob": specs[0].family.knob,
        "probes": probe_values,
        "chunk_values": middles.tolist(),
        "scenes": options.scenes,
        "chunks": options.chunks,
        "boundaries": options.boundaries,
        "threshold": options.threshold,
        "epochs": config.epochs,
        "seeds": config.seeds,
        "k": config.k,
        "methods": methods,
    }


def method_summary(
    runs: list[dict[str, list]], middles: np.ndarray, probe_values: list[float]
) -> dict[str, Any]:
    """One method's seeds through the stream: the error-over-time matrix (mean and std), final,
    worst and anytime errors, forgetting per probe, and the boundaries of its first seed."""
    ade = np.array([r["ade"] for r in runs])
    fde = np.array([r["fde"] for r in runs])
    lost = np.stack([forgetting(a, middles, probe_values) for a in ade])
    return {
        "ade": ade.mean(0).tolist(),
        "ade_std": ade.std(0).tolist(),
        "fde": fde.mean(0).tolist(),
        "final_ade": float(ade[:, -1].mean()),
        "final_ade_std": float(ade[:, -1].mean(1).std()),
        "worst_final_ade": float(ade[:, -1].max(1).mean()),
        "anytime_ade": float(ade.mean()),
        "forgetting": lost.mean(0).tolist(),
        "mean_forgetting": float(lost.mean()),
        "detected": runs[0]["found"],
        "given": runs[0]["given"],
    }


def drift_markdown(report: dict[str, Any]) -> str:
    """The report's summary table and each method's error-over-time matrix."""
    lines = [
        f"# Drift: {report['family']} {report['knob']} from {report['probes'][0]:g} to "
        f"{report['probes'][-1]:g} over {report['scenes']} scenes",
        "",
        f"{report['chunks']} chunks, {report['epochs']} epochs each, {report['seeds']} seed(s); "
        f"task boundaries: {report['boundaries']}. ADE best of {report['k']} on the probe sets "
        f"(metres). Forgetting: a probe's final error minus its lowest once the stream had "
        f"reached its value, averaged over probes.",
        "",
        "| method | needs boundaries | boundaries given at chunks | final ADE | worst probe | "
        "anytime ADE | forgetting |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, m in report["methods"].items():
        given = ", ".join(map(str, m["given"]))
        lines.append(
            f"| {name} | {'yes' if m['needs_boundaries'] else 'no'} | {given} | "
            f"{m['final_ade']:.3f} ± {m['final_ade_std']:.3f} | {m['worst_final_ade']:.3f} | "
            f"{m['anytime_ade']:.3f} | {m['mean_forgetting']:+.3f} |"
        )
    first = next(iter(report["methods"].values()))
    lines += ["", f"The detector found shifts at chunks {first['detected']}.", ""]
    for name, m in report["methods"].items():
        lines += [f"## {name}: ADE after each chunk (rows) on each probe (columns)", ""]
        lines.append("| chunk (knob) | " + " | ".join(f"{v:g}" for v in report["probes"]) + " |")
        lines.append("|---" * (len(report["probes"]) + 1) + "|")
        for c, (value, row) in enumerate(zip(report["chunk_values"], m["ade"], strict=True)):
            mark = " *" if c in m["given"] and c > 0 else ""
            cells = " | ".join(f"{x:.3f}" for x in row)
            lines.append(f"| {c} ({value:.3f}){mark} | {cells} |")
        lines.append("")
    lines.append("`*`: a task boundary was given to the method before that chunk.")
    return "\n".join(lines) + "\n"


class Drift(Study):
    name = "drift"
    examples = (
        "--scenario crowd_noise_0.1..0.6 --scenes 600 --chunks 12",
        "--scenario crowd_radius_0.1..0.6 --boundaries none --quick",
    )
    methods = DEFAULT_METHODS

    markdown = staticmethod(drift_markdown)

    def figure(self, report, path):
        study_figures.drift_figure(report, path)

    def add_options(self, p):
        p.add_argument("--scenes", type=bounded_int(2, 100_000), default=600, help="stream length")
        p.add_argument("--chunks", type=bounded_int(1, 100_000), default=12, help="chunks of it")
        p.add_argument("--boundaries", choices=BOUNDARIES, default="detect")
        p.add_argument("--threshold", type=bounded_float(1e-6, 10), default=0.15)

    def run(self, args, config, execution, out, argv):
        options = DriftOptions(args.scenes, args.chunks, args.boundaries, args.threshold)
        return run_drift(config, options, execution, out, args.resume)


register(Drift())
