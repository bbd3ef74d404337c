"""``python -m sim.shift``: forgetting and transfer against the size of the shift.

Each ``--scenario`` (e.g. ``crowd_noise_0.1..0.6``) names a base domain, its first value, and
the shifted ones, the rest: every method runs the two-task curriculum base then shifted, for
every shifted domain, on the sweep's backend (``sim.sweep``: parallel jobs, resumable). The
shift is measured in knob units and as the distance between the two domains' realised
statistics (the root mean square of their relative differences). Per method and shift it reports

- forgetting: the base's error after learning the shifted domain minus right after the base;
- the transfer gap: the shifted domain's error before learning it (the base model) minus after.

It writes ``shift.json``, ``shift.md`` and ``shift.png`` to ``--out`` beside the sweep's runs.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
from scipy.stats import spearmanr

from c2inet.files import write_atomic
from sim.cli import parse, parser
from sim.curriculum import knob_grid, make_tasks
from sim.data import Domain
from sim.experiment import Execution, ExperimentConfig
from sim.fidelity import relative_difference
from sim.outputs import write_report
from sim.run import add_experiment_options, execution_of, experiment_options
from sim.scenario import DomainSpec, parse_scenario
from sim.sweep import SweepConfig, run_sweep
from viz.cli import guarded

DEFAULT_METHODS = "finetune,ewc,derpp,c2inet-online"
COUNTS = ("overlaps", "crashes")  # statistics that count events rather than measure motion


def shift_grid(scenario: str, extra_dirs: list[Path]) -> tuple[DomainSpec, list[DomainSpec]]:
    """The base domain and the shifted ones of one ``--scenario``."""
    where = f"--scenario {scenario!r} (the base value first, the shifted ones after)"
    specs = knob_grid(parse_scenario(scenario, extra_dirs), where, "crowd_noise_0.1..0.6")
    return specs[0], specs[1:]


def statistics_distance(base: Domain, shifted: Domain) -> float:
    """Root mean square of the relative differences of the two domains' realised statistics,
    those their generator reports for the family (``sim.generate`` prints them; traffic's
    include vehicles per km per lane and headway), counts of overlaps and crashes left out."""
    names = [n for n in base.stats if n in shifted.stats and n not in COUNTS]
    relative = [relative_difference(shifted.stats[n], base.stats[n]) for n in names]
    return float(np.sqrt(np.mean(np.square(relative))))


def summarise_shift(
    scenarios: list[str], config: ExperimentConfig, out: Path, cache: Path
) -> dict[str, Any]:
    """Forgetting and transfer gap per family, shift and method, from the sweep's tidy
    ``results.parquet``, with both measures of each shift."""
    table = pq.read_table(out / "results.parquet").to_pandas()
    table = table[table["metric"] == "ade"]
    families = []
    for scenario in scenarios:
        base, shifted = shift_grid(scenario, list(config.scenarios_dir))
        _, domains = make_tasks([base, *shifted], config.seed, config.quick, cache, 1)
        rows = []
        for spec, domain in zip(shifted, domains[1:], strict=True):
            pair = table[table["scenario"] == f"{base.name}+{spec.name}"]
            cell = {(r.method, r.seed, r.after_task, r.on_task): r.value for r in pair.itertuples()}
            methods = {}
            for method in config.methods:
                seeds = sorted({s for m, s, *_ in cell if m == method})
                a, b = base.name, spec.name
                lost = [cell[method, s, b, a] - cell[method, s, a, a] for s in seeds]
                gap = [cell[method, s, a, b] - cell[method, s, b, b] for s in seeds]
                methods[method] = {
                    "forgetting": float(np.mean(lost)),
                    "forgetting_std": float(np.std(lost)),
                    "gap": float(np.mean(gap)),
                    "gap_std": float(np.std(gap)),
                    "seeds": len(seeds),
                }
            rows.append(
                {
                    "domain": spec.name,
                    "value": float(spec.value),
                    "knob_shift": float(spec.value) - float(base.value),
                    "statistics_distance": statistics_distance(domains[0], domain),
                    "methods": methods,
                }
            )
        families.append(
            {"family": base.family.name, "knob": base.family.knob, "base": float(base.value),
             "rows": rows, "peaks": peaks(rows, config.methods)}
        )  # fmt: skip
    return {"methods": list(config.methods), "epochs": config.epochs, "families": families}


def peaks(rows: list[dict], methods: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    """Per method: the shift that forgets most; whether it is an intermediate one (it beats the
    largest shift's forgetting by more than their two standard deviations), as toy theory
    predicts; and the rank correlation of forgetting with each measure of the shift."""
    out = {}
    for method in methods:
        lost = np.array([r["methods"][method]["forgetting"] for r in rows])
        spread = np.array([r["methods"][method]["forgetting_std"] for r in rows])
        top = int(np.argmax(lost))
        margin = lost[top] - lost[-1] - spread[top] - spread[-1]
        out[method] = {
            "shift": rows[top]["knob_shift"],
            "forgetting": float(lost[top]),
            "intermediate": bool(top < len(rows) - 1 and margin > 0),
            "rank_knob": _spearman([r["knob_shift"] for r in rows], lost),
            "rank_statistics": _spearman([r["statistics_distance"] for r in rows], lost),
        }
    return out


def _spearman(x, y) -> float:
    """Spearman's rank correlation (NaN where a side is constant)."""
    if len(set(x)) < 2 or len(set(np.round(y, 12))) < 2:
        return float("nan")
    return float(spearmanr(x, y).statistic)


def shift_markdown(summary: dict[str, Any]) -> str:
    lines = [
        "# Forgetting against the size of the shift",
        "",
        f"Two tasks each, base then shifted, {summary['epochs']} epochs a task; ADE best of K in "
        "metres, mean ± std over seeds. Forgetting: the base's error after the shifted task minus "
        "right after the base. Gap: the shifted task's error before learning it minus after. "
        "Distance: root mean square of the relative differences of the realised statistics.",
        "",
    ]
    for family in summary["families"]:
        methods = summary["methods"]
        lines += [f"## {family['family']}: {family['knob']} from {family['base']:g}", ""]
        lines.append(
            "| value | knob shift | distance | "
            + " | ".join(f"{m} forgetting | {m} gap" for m in methods)
            + " |"
        )
        lines.append("|---" * (3 + 2 * len(methods)) + "|")
        for r in family["rows"]:
            cells = []
            for m in methods:
                x = r["methods"][m]
                cells.append(f"{x['forgetting']:+.3f} ± {x['forgetting_std']:.3f}")
                cells.append(f"{x['gap']:+.3f}")
            lines.append(
                f"| {r['value']:g} | {r['knob_shift']:+g} | {r['statistics_distance']:.3f} | "
                + " | ".join(cells)
                + " |"
            )
        lines.append("")
        for m, p in family["peaks"].items():
            where = (
                "an intermediate shift, beyond the largest shift's by more than their spread"
                if p["intermediate"]
                else "no intermediate shift forgets clearly more than the largest"
            )
            lines.append(
                f"- {m}: forgets most ({p['forgetting']:+.3f}) at a shift of {p['shift']:+g}; "
                f"{where}. Rank correlation of forgetting with the knob shift "
                f"{p['rank_knob']:+.2f}, with the statistics distance {p['rank_statistics']:+.2f}."
            )
        lines.append("")
    return "\n".join(lines)


def shift_figure(summary: dict[str, Any], path: Path) -> None:
    """Per family (columns): forgetting against the knob shift, against the statistics
    distance, and the transfer gap against the knob shift (rows), one line per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    families = summary["families"]
    fig, axes = plt.subplots(3, len(families), figsize=(4.6 * len(families), 9), squeeze=False)
    for column, family in enumerate(families):
        rows = family["rows"]
        for method in summary["methods"]:
            lost = [r["methods"][method]["forgetting"] for r in rows]
            spread = [r["methods"][method]["forgetting_std"] for r in rows]
            gap = [r["methods"][method]["gap"] for r in rows]
            shifts = [r["knob_shift"] for r in rows]
            distance = [r["statistics_distance"] for r in rows]
            axes[0, column].errorbar(shifts, lost, spread, fmt="-o", ms=3, capsize=2, label=method)
            order = np.argsort(distance)
            axes[1, column].plot(np.take(distance, order), np.take(lost, order), "-o", ms=3)
            axes[2, column].plot(shifts, gap, "-o", ms=3)
        axes[0, column].set_title(f"{family['family']} from {family['base']:g}", fontsize=9)
        axes[0, column].set(xlabel=f"{family['knob']} shift", ylabel="forgetting (m)")
        axes[1, column].set(xlabel="realised-statistics distance", ylabel="forgetting (m)")
        axes[2, column].set(xlabel=f"{family['knob']} shift", ylabel="transfer gap (m)")
        for ax in axes[:, column]:
            ax.axhline(0, color="0.7", lw=0.8)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    plt.close(fig)


def run_shift(
    scenarios: list[str],
    base: ExperimentConfig,
    out: Path,
    execution: Execution,
    resume: bool = False,
    overwrite: bool = False,
    argv: list[str] | None = None,
) -> dict[str, Any]:
    """Run every two-task curriculum of ``scenarios`` as one sweep into ``out``, summarise it
    and write ``shift.json``, ``shift.md`` and ``shift.png``."""
    pairs = []
    for scenario in scenarios:
        first, shifted = shift_grid(scenario, list(base.scenarios_dir))
        pairs += [f"{first.name}+{spec.name}" for spec in shifted]
    run_sweep(SweepConfig(base, tuple(pairs)), out, execution, resume, overwrite, argv)
    summary = summarise_shift(scenarios, base, out, execution.cache)
    write_report(out, "shift", summary, shift_markdown, shift_figure)
    return summary


@guarded
def main(argv: list[str] | None = None) -> int:
    examples = (
        "  python -m sim.shift --scenario crowd_noise_0.1..0.6 --scenario crowd_radius_0.1..0.6 "
        "--seeds 3 --jobs 2\n"
        "  python -m sim.shift --scenario crowd_noise_0.1,0.3,0.6 --quick --out /tmp/shift"
    )
    p = parser("sim.shift", __doc__.splitlines()[0], examples, scenarios=True)
    add_experiment_options(p)
    p.set_defaults(methods=DEFAULT_METHODS)
    p.add_argument("--out", type=Path, default=Path("shift"), help="the folder (default shift)")
    argv = sys.argv[1:] if argv is None else argv
    args = parse(p, argv)
    if args is None:
        return 0
    options = {**experiment_options(args), "record": False}
    base = ExperimentConfig(args.scenario[0], **options)
    try:
        summary = run_shift(
            list(args.scenario), base, args.out, execution_of(args), args.resume,
            args.overwrite, ["python", "-m", "sim.shift", *argv],
        )  # fmt: skip
    except KeyboardInterrupt:
        print(f"\ninterrupted: add --resume to continue in {args.out}", file=sys.stderr)
        return 130
    print(shift_markdown(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
