"""``python -m sim.study NAME``: the paper's studies, each one command writing its table, JSON and
figure: ``table4`` (each C2INet part switched off in turn), ``fig9`` (the queue's capacity
gamma) and ``fig10`` (task order).

A study is a preset of the sweep (``sim.sweep``): named variants of options over a few
curricula, every job run together on one backend, resumable. Its folder holds the sweep's
outputs (a run per curriculum and variant, ``results.parquet``) plus ``study.md``,
``study.json`` and ``study.png``. ``--scenario`` replaces the presets' curricula (small runs).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from c2inet.errors import InputError, did_you_mean
from c2inet.files import write_atomic
from sim.cli import parse, parser
from sim.experiment import ExperimentConfig
from sim.outputs import write_report
from sim.run import add_experiment_options, execution_of, experiment_options
from sim.sweep import SweepConfig, run_sweep
from viz.cli import guarded

ETH_UCY = "eth_ucy_univ,eth,zara1,zara2,hotel"  # the paper's order U-E-Z1-Z2-H
C2INET = "c2inet-online"
OFF = {
    "full": {},
    "no weight optimisation": {C2INET: {"weight_opt": False}},
    "no divergence": {C2INET: {"divergence": False}},
    "no weight optimisation, divergence or KL of Z": {
        C2INET: {"weight_opt": False, "divergence": False},
        "model": {"beta_z": 0.0},
    },
}


@dataclass(frozen=True)
class Study:
    """Variants (label -> settings by scope) of one method over curricula; ``by`` says what the
    figure compares: the variants (``variant``) or the curricula (``order``)."""

    title: str
    scenarios: tuple[str, ...]
    variants: dict[str, dict[str, dict[str, Any]]]
    by: str = "variant"
    paper: str = ""


STUDIES = {
    "table4": Study(
        "Table 4: C2INet-online with each part switched off",
        (ETH_UCY, "crowd_radius_0.1..0.6"),
        OFF,
        paper="ETH-UCY (U-E-Z1-Z2-H): every removal raises the error; removing everything most "
        "(up to 21.6 %), the divergence term next (5 to 17 %), weight optimisation least (3.7 %)",
    ),
    "fig9": Study(
        "Fig 9: the queue's capacity gamma",
        (ETH_UCY,),
        {f"gamma={g}": {C2INET: {"capacity": g}} for g in (15, 30, 45, 60)},
        paper="gamma = 45 best, 15 worst: too small and too large a queue both hurt",
    ),
    "fig10": Study(
        "Fig 10: task order",
        (
            ETH_UCY,
            "eth_ucy_hotel,univ,eth,zara1,zara2",  # H-U-E-Z1-Z2, the paper's best
            "eth_ucy_univ,eth,zara1,hotel,zara2",  # U-E-Z1-H-Z2, its second worst
            "crowd_radius_0.1..0.6",
            "crowd_radius_0.6,0.5,0.4,0.3,0.2,0.1",  # reversed
            "crowd_radius_0.3,0.6,0.1,0.5,0.2,0.4",  # shuffled (fixed)
        ),
        {"default": {}},
        by="order",
        paper="the order changes the final average by about 7.6 % (best H-U-E-Z1-Z2); the noisy "
        "hotel task is best learnt early",
    ),
}


def study_sweep(study: Study, base: ExperimentConfig, scenarios: tuple[str, ...] | None):
    return SweepConfig(
        replace(base, methods=(C2INET,)),
        scenarios or study.scenarios,
        variants=tuple(study.variants.items()),
    )


def summarise_study(study: Study, entries: list[tuple[str, ExperimentConfig, dict]]) -> dict:
    """Per curriculum and variant: average ADE/FDE over seen tasks after each task, and the
    final ones, mean and std over seeds."""
    rows = []
    for label, config, metrics in entries:
        m = metrics["methods"][C2INET]
        rows.append(
            {
                "scenario": config.scenario,
                "variant": label,
                "labels": metrics["labels"],
                "seeds": m["seeds"],
                **{
                    key: m[key]
                    for key in (
                        "avg_seen_ade",
                        "avg_seen_ade_std",
                        "avg_seen_fde",
                        "avg_seen_fde_std",
                        "forgetting_final_ade",
                    )
                },
            }
        )
    return {"study": study.title, "paper": study.paper, "rows": rows}


def order_table(summary: dict) -> list[str]:
    """For order studies: each family's orders side by side, final averages and the change
    against the family's first order."""
    lines = [
        "| family | order | final ADE/FDE | ± std | change of ADE |",
        "|---|---|---|---|---|",
    ]
    reference: dict[str, float] = {}
    for r in summary["rows"]:
        family, order = r["scenario"].rsplit("_", 1)
        ade, fde = r["avg_seen_ade"][-1], r["avg_seen_fde"][-1]
        base = reference.setdefault(family, ade)
        lines.append(
            f"| {family} | {order} | {ade:.3f}/{fde:.3f} | {r['avg_seen_ade_std'][-1]:.3f} | "
            f"{100 * (ade / base - 1):+.1f} % |"
        )
    return [*lines, ""]


def study_markdown(summary: dict) -> str:
    lines = [f"# {summary['study']}", "", f"The paper: {summary['paper']}.", ""]
    if summary.get("by") == "order":
        lines += order_table(summary)
    lines += [
        "Cells: ADE/FDE in metres averaged over the tasks seen so far after each task, mean over "
        "seeds (± std of the final average); in brackets the change of the final ADE against the "
        "first row of its curriculum.",
        "",
    ]
    scenarios = dict.fromkeys(r["scenario"] for r in summary["rows"])
    for scenario in scenarios:
        rows = [r for r in summary["rows"] if r["scenario"] == scenario]
        labels = rows[0]["labels"]
        lines += [f"## {scenario}", ""]
        lines.append("| variant | " + " | ".join(labels) + " | forgetting |")
        lines.append("|---|" + "---|" * (len(labels) + 1))
        reference = rows[0]["avg_seen_ade"][-1]
        for r in rows:
            cells = [
                f"{a:.3f}/{f:.3f}"
                for a, f in zip(r["avg_seen_ade"], r["avg_seen_fde"], strict=True)
            ]
            change = r["avg_seen_ade"][-1] - reference
            cells[-1] += f" ± {r['avg_seen_ade_std'][-1]:.3f} ({change:+.3f})"
            lines.append(
                f"| {r['variant']} | "
                + " | ".join(cells)
                + f" | {r['forgetting_final_ade']:+.3f} |"
            )
        lines.append("")
    return "\n".join(lines)


def study_figure(summary: dict, path: Path) -> None:
    """Final average ADE (solid) and FDE (dashed) per variant or per order, one panel per
    curriculum (variants) or per family (orders)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = summary["rows"]
    groups: dict[str, list[dict]] = {}
    for r in rows:
        key = r["scenario"].rsplit("_", 1)[0] if summary.get("by") == "order" else r["scenario"]
        groups.setdefault(key, []).append(r)
    fig, axes = plt.subplots(1, len(groups), figsize=(5 * len(groups), 3.6), squeeze=False)
    for ax, (key, members) in zip(axes[0], groups.items(), strict=True):
        names = [m["scenario"] if summary.get("by") == "order" else m["variant"] for m in members]
        x = range(len(members))
        for metric, style in (("avg_seen_ade", "-o"), ("avg_seen_fde", "--s")):
            values = [m[metric][-1] for m in members]
            errors = [m[f"{metric}_std"][-1] for m in members]
            ax.errorbar(x, values, errors, fmt=style, capsize=3, label=metric[-3:].upper())
        ax.set_xticks(
            list(x),
            [n.replace("eth_ucy_", "").replace("crowd_radius_", "r ") for n in names],
            rotation=20,
            ha="right",
            fontsize=8,
        )
        ax.set_ylabel("final average over tasks (m)")
        ax.set_title(key, fontsize=9)
        ax.legend(fontsize=8)
    fig.suptitle(summary["study"], fontsize=10)
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
    plt.close(fig)


def run_study(
    name: str, base: ExperimentConfig, out: Path, execution, scenarios=None, **kw
) -> dict:
    """Run study ``name`` into ``out`` and write ``study.md``, ``study.json``, ``study.png``."""
    if name not in STUDIES:
        raise InputError(
            f"study {name!r}: unknown{did_you_mean(name, STUDIES)} (known: {', '.join(STUDIES)})"
        )
    study = STUDIES[name]
    entries = run_sweep(study_sweep(study, base, scenarios), out, execution, **kw)
    summary = {**summarise_study(study, entries), "by": study.by}
    write_study(summary, out)
    return summary


def write_study(summary: dict, out: Path) -> None:
    """``study.json``, ``study.md`` and ``study.png`` of a study's summary."""
    write_report(out, "study", summary, study_markdown, study_figure)


@guarded
def main(argv: list[str] | None = None) -> int:
    examples = (
        "  python -m sim.study table4 --seeds 3 --jobs 2 --out studies/table4\n"
        "  python -m sim.study fig9 --quick --scenario crowd_radius_0.1,0.2 --out /tmp/fig9"
    )
    p = parser("sim.study", __doc__.splitlines()[0], examples, scenarios=True)
    p.add_argument("study", choices=sorted(STUDIES))
    add_experiment_options(p)
    p.add_argument("--out", type=Path, help="the study's folder (default studies/NAME)")
    argv = sys.argv[1:] if argv is None else argv
    args = parse(p, argv, scenario_required=False)
    if args is None:
        return 0
    scenarios = tuple(args.scenario) if args.scenario else None
    first = (scenarios or STUDIES[args.study].scenarios)[0]
    base = ExperimentConfig(first, **{**experiment_options(args), "methods": (C2INET,)})
    out = args.out or Path("studies") / args.study
    try:
        summary = run_study(
            args.study,
            base,
            out,
            execution_of(args),
            scenarios,
            resume=args.resume,
            overwrite=args.overwrite,
            argv=["python", "-m", "sim.study", *argv],
        )
    except KeyboardInterrupt:
        print(f"\ninterrupted: add --resume to continue the study in {out}", file=sys.stderr)
        return 130
    print(study_markdown(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
