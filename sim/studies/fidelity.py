"""``python -m sim.study fidelity``: how closely a generated family resembles a reference family.

The reference is any family: RVO2's scenes (``orca_radius``), or a user's own recordings through
a ``files`` family. Domains pair by position (the first of ``--scenario`` with the first of
``--reference``, and so on). Per pair the report gives

- the realised statistics side by side and their relative difference (within ``TOLERANCE``
  counts as matched): minimum separation, median closest approach, mean speed, heading change per
  frame and speed over the first step;
- the distance between the per-scene distributions of closest approach, speed, heading change
  and first-step speed (1-Wasserstein, in the quantity's units), and their histograms;
- transfer: a model trained on each domain alone (``--method``, default fine-tuning) tested on
  every domain of both families, beside constant velocity. The telling ratio is the error of the
  generated-trained model on the reference over that of the reference-trained one.

It writes ``fidelity.json``, ``fidelity.md`` and ``fidelity.png`` to ``--out``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from c2inet.errors import InputError
from c2inet.lazy import lazy_module
from sim.data import Domain
from sim.scenario import parse_scenario
from sim.stats import PROFILES, realised_summary, relative_difference, scene_profiles
from sim.studies.base import Study, register

if TYPE_CHECKING:  # the learner and the engine load once there is work (``sim.studies.base``)
    from c2inet.trainer import Task
    from sim.experiment import Execution, ExperimentConfig

# the learner, the engine and the figures load once there is work (sim.studies.base)
evaluation = lazy_module("c2inet.evaluation")
training = lazy_module("c2inet.trainer")
scipy_stats = lazy_module("scipy.stats")
engine = lazy_module("sim.experiment")
cell_runs = lazy_module("sim.experiment.cells")
curriculum = lazy_module("sim.experiment.curriculum")
study_figures = lazy_module("viz.study_figures")

TOLERANCE = 0.10  # relative difference of a statistic that still counts as matched
TRANSFER_TARGET = 1.2  # generated-trained over reference-trained error on the reference
SIDES = ("generated", "reference")


def compare_statistics(generated: Domain, reference: Domain) -> dict[str, Any]:
    """Realised statistics of two domains (all splits), their relative differences, and the
    distances and histograms of their per-scene distributions."""
    stats, profiles = {}, {}
    for side, domain in zip(SIDES, (generated, reference), strict=True):
        scenes = [scene for split in domain.scenes.values() for scene in split]
        profiles[side] = scene_profiles(scenes, domain.dt)
        stats[side] = realised_summary(scenes, domain.dt, profiles[side])
    relative = {
        name: relative_difference(stats["generated"][name], value)
        for name, value in stats["reference"].items()
    }
    distances, histograms = {}, {}
    for name in PROFILES:
        a, b = (profiles[side][name] for side in SIDES)
        a, b = a[np.isfinite(a)], b[np.isfinite(b)]
        if not (a.size and b.size):
            distances[name], histograms[name] = None, None
            continue
        distances[name] = float(scipy_stats.wasserstein_distance(a, b))
        edges = np.histogram_bin_edges(np.concatenate([a, b]), bins=30)
        histograms[name] = {
            "edges": edges.tolist(),
            "generated": np.histogram(a, edges)[0].tolist(),
            "reference": np.histogram(b, edges)[0].tolist(),
        }
    return {
        **stats,
        "relative": relative,
        "matched": all(abs(r) <= TOLERANCE for r in relative.values()),
        "wasserstein": distances,
        "histograms": histograms,
    }


def transfer_cell(
    seed_index: int, trained_on: int, config: ExperimentConfig, method: str, tasks: list[Task]
) -> dict[str, list[float]]:
    """One row of the transfer matrix (a cell): ADE and FDE on every task of a model trained on
    task ``trained_on`` alone."""
    train = replace(config.train_config(seed_index), diagnostics=False, val_every=0)
    trainer = training.ContinualTrainer(config.method(method), [tasks[trained_on]], train)
    trainer.run()
    scores = [
        evaluation.evaluate(trainer.model, t.test, train.k, train.seed + j)
        for j, t in enumerate(tasks)
    ]
    return {"ade": [s["ade"] for s in scores], "fde": [s["fde"] for s in scores]}


def transfer_matrix(
    config: ExperimentConfig,
    method: str,
    tasks: list[Task],
    execution: Execution | None = None,
    folder: Path | None = None,
    resume: bool = False,
) -> dict[str, Any]:
    """ADE and FDE (best of K, metres) of a model trained on each task alone and tested on every
    task (rows: trained on; columns: tested on), the mean over ``config.seeds`` seeds, and
    constant velocity's on every task. The trainings run as cells on ``execution``."""
    n = len(tasks)
    cells = {f"seed_{s}-task_{i}": (s, i) for s in range(config.seeds) for i in range(n)}
    data = [t.test.positions for t in tasks] + [t.train.positions for t in tasks]
    identity = cell_runs.cell_identity("fidelity", config.to_json(), method, arrays=data)
    done = cell_runs.run_cells(
        transfer_cell,
        cells,
        (config, method, tasks),
        execution or engine.Execution(),
        folder,
        identity,
        resume,
    )
    rows = [[done[f"seed_{s}-task_{i}"] for i in range(n)] for s in range(config.seeds)]
    ade = np.array([[row["ade"] for row in seed] for seed in rows])
    fde = np.array([[row["fde"] for row in seed] for seed in rows])
    cv = config.method("cv").build_model()
    baseline = [
        evaluation.evaluate(cv, t.test, config.k, config.seed + j) for j, t in enumerate(tasks)
    ]
    return {
        "tasks": [t.name for t in tasks],
        "ade": ade.mean(0).tolist(),
        "ade_std": ade.std(0).tolist(),
        "fde": fde.mean(0).tolist(),
        "cv_ade": [b["ade"] for b in baseline],
        "cv_fde": [b["fde"] for b in baseline],
    }


def pair_transfer(matrix: dict[str, Any], i: int, n: int) -> dict[str, float]:
    """Pair ``i``'s cells of the transfer matrix (generated tasks first, then the reference's)."""
    ade, cv = np.asarray(matrix["ade"]), matrix["cv_ade"]
    g, r = i, n + i
    return {
        "generated_on_reference": float(ade[g, r]),
        "reference_on_reference": float(ade[r, r]),
        "ratio": float(ade[g, r] / ade[r, r]),
        "reference_on_generated": float(ade[r, g]),
        "generated_on_generated": float(ade[g, g]),
        "reverse_ratio": float(ade[r, g] / ade[g, g]),
        "cv_on_reference": float(cv[r]),
        "cv_on_generated": float(cv[g]),
    }


def fidelity_report(
    scenario: str,
    reference: str,
    config: ExperimentConfig,
    method: str = "finetune",
    transfer: bool = True,
    execution: Execution | None = None,
    folder: Path | None = None,
    resume: bool = False,
) -> dict[str, Any]:
    """The fidelity report of ``scenario`` against ``reference`` as a dictionary (see the
    module docstring); ``config`` gives the training options of the transfer runs, which run
    as cells on ``execution`` (kept in ``folder``, if given, for ``resume``)."""
    execution = execution or engine.Execution()
    extra = list(config.scenarios_dir)
    data = config.settings.get("data")
    generated_specs = parse_scenario(scenario, extra, data)
    reference_specs = parse_scenario(reference, extra)  # --set data.* shapes the generated side
    if len(generated_specs) != len(reference_specs):
        raise InputError(
            f"--reference {reference!r} has {len(reference_specs)} domains and --scenario "
            f"{scenario!r} {len(generated_specs)}: they pair by position, so give as many"
        )
    specs = generated_specs + reference_specs
    tasks, domains = curriculum.experiment_tasks(specs, config, execution)
    n = len(generated_specs)
    pairs = []
    for i in range(n):
        names = [domains[i].name, domains[n + i].name]
        pairs.append({"domains": names, **compare_statistics(domains[i], domains[n + i])})
    report: dict[str, Any] = {
        "scenario": scenario,
        "reference": reference,
        "tolerance": TOLERANCE,
        "transfer_target": TRANSFER_TARGET,
        "pairs": pairs,
    }
    if transfer:
        matrix = transfer_matrix(config, method, tasks, execution, folder, resume)
        for i, pair in enumerate(pairs):
            pair["transfer"] = pair_transfer(matrix, i, n)
        report["transfer"] = {
            "method": method,
            "epochs": config.epochs,
            "k": config.k,
            "seeds": config.seeds,
            **matrix,
        }
    return report


def _percent(value: float) -> str:
    return f"{100 * value:+.1f}%" if np.isfinite(value) else "inf"


def fidelity_markdown(report: dict[str, Any]) -> str:
    """The report as Markdown tables, with a verdict line per criterion."""
    pairs = report["pairs"]
    names = list(pairs[0]["relative"])
    lines = [
        f"# Fidelity of {report['scenario']} against {report['reference']}",
        "",
        f"Realised statistics, generated / reference (relative difference; within "
        f"{100 * report['tolerance']:.0f}% counts as matched).",
        "",
        "| pair | " + " | ".join(names) + " | matched |",
        "|---" * (len(names) + 2) + "|",
    ]
    for p in pairs:
        cells = [
            f"{p['generated'][name]:.3f} / {p['reference'][name]:.3f} "
            f"({_percent(p['relative'][name])})"
            for name in names
        ]
        matched = "yes" if p["matched"] else "no"
        lines.append(f"| {_pair_label(p)} | " + " | ".join(cells) + f" | {matched} |")
    lines += [
        "",
        "Distance between per-scene distributions (1-Wasserstein, in the quantity's units).",
        "",
        "| pair | " + " | ".join(PROFILES) + " |",
        "|---" * (len(PROFILES) + 1) + "|",
    ]
    for p in pairs:
        cells = [_number(p["wasserstein"][name]) for name in PROFILES]
        lines.append(f"| {_pair_label(p)} | " + " | ".join(cells) + " |")
    matched = sum(p["matched"] for p in pairs)
    lines += ["", f"Statistics matched in {matched} of {len(pairs)} pairs."]
    if "transfer" in report:
        t = report["transfer"]
        lines += [
            "",
            f"Transfer: {t['method']} trained on one domain ({t['epochs']} epochs, "
            f"{t['seeds']} seed(s)), ADE best of {t['k']} in metres; ratio = trained on the "
            f"generated domain over trained on the reference, tested on the reference "
            f"(target at most {report['transfer_target']}).",
            "",
            "| pair | gen on ref | ref on ref | ratio | ref on gen | gen on gen | reverse ratio "
            "| CV on ref | CV on gen |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for p in pairs:
            x = p["transfer"]
            lines.append(
                f"| {_pair_label(p)} | {x['generated_on_reference']:.3f} | "
                f"{x['reference_on_reference']:.3f} | {x['ratio']:.2f} | "
                f"{x['reference_on_generated']:.3f} | {x['generated_on_generated']:.3f} | "
                f"{x['reverse_ratio']:.2f} | {x['cv_on_reference']:.3f} | "
                f"{x['cv_on_generated']:.3f} |"
            )
        within = sum(p["transfer"]["ratio"] <= report["transfer_target"] for p in pairs)
        lines += ["", f"Transfer ratio within the target in {within} of {len(pairs)} pairs."]
    return "\n".join(lines) + "\n"


def _pair_label(pair: dict[str, Any]) -> str:
    return " ~ ".join(pair["domains"])


def _number(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4f}"


class Fidelity(Study):
    name = "fidelity"
    examples = (
        "--scenario crowd_radius_0.1..0.6 --reference orca_radius_0.1..0.6",
        "--scenario crowd_radius_0.3 --reference orca_radius_0.3 --no-transfer",
    )
    one_method = True

    markdown = staticmethod(fidelity_markdown)

    def figure(self, report, path):
        study_figures.fidelity_figure(report, path)

    def add_options(self, p):
        p.add_argument(
            "--reference",
            required=True,
            help="the family to compare with, e.g. orca_radius_0.1..0.6",
        )
        p.add_argument("--no-transfer", action="store_true", help="statistics only (no training)")

    def run(self, args, config, execution, out, argv):
        if not args.reference:
            raise InputError("the following arguments are required: --reference")
        return fidelity_report(
            args.scenario,
            args.reference,
            config,
            config.methods[0],
            not args.no_transfer,
            execution,
            out,
            args.resume,
        )


register(Fidelity())
