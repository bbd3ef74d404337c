"""``python -m sim.study shift``: forgetting and transfer against the size of the shift.

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

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from c2inet.lazy import lazy_module
from sim.data import Domain
from sim.scenario import DomainSpec, parse_scenario
from sim.stats import relative_difference
from sim.studies.base import Study, register

if TYPE_CHECKING:  # the engine loads once there is work (``sim.studies.base``)
    from sim.experiment import Execution, ExperimentConfig

# the learner, the engine and the figures load once there is work (sim.studies.base)
parquet = lazy_module("pyarrow.parquet")
scipy_stats = lazy_module("scipy.stats")
curriculum = lazy_module("sim.experiment.curriculum")
sweeping = lazy_module("sim.experiment.sweep")
study_figures = lazy_module("viz.study_figures")

DEFAULT_METHODS = "finetune,ewc,derpp,c2inet-online"
COUNTS = ("overlaps", "crashes")  # statistics that count events rather than measure motion


def shift_grid(scenario: str, config: ExperimentConfig) -> tuple[DomainSpec, list[DomainSpec]]:
    """The base domain and the shifted ones of one ``--scenario``, with the ``--set data.*``
    overrides of ``config`` (the domains its sweep trains on)."""
    where = f"--scenario {scenario!r} (the base value first, the shifted ones after)"
    data = config.settings.get("data")
    specs = parse_scenario(scenario, list(config.scenarios_dir), data)
    specs = curriculum.knob_grid(specs, where, "crowd_noise_0.1..0.6")
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
    table = parquet.read_table(out / "results.parquet").to_pandas()
    table = table[table["metric"] == "ade"]
    families = []
    for scenario in scenarios:
        base, shifted = shift_grid(scenario, config)
        _, domains = curriculum.make_tasks([base, *shifted], config.seed, config.quick, cache, 1)
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


MIN_RANKED = 4  # fewer shifts than this make any rank correlation +-1 or close: not reported


def _spearman(x, y) -> float:
    """Spearman's rank correlation (NaN where a side is constant or there are fewer than
    ``MIN_RANKED`` shifts: over two points it is always +-1)."""
    if len(x) < MIN_RANKED or len(set(x)) < 2 or len(set(np.round(y, 12))) < 2:
        return float("nan")
    return float(scipy_stats.spearmanr(x, y).statistic)


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
            ranks = (
                f"Rank correlation of forgetting with the knob shift {p['rank_knob']:+.2f}, "
                f"with the statistics distance {p['rank_statistics']:+.2f}."
                if not np.isnan(p["rank_knob"])
                else f"No rank correlation: it needs {MIN_RANKED} or more shifts and a "
                "forgetting that varies."
            )
            lines.append(
                f"- {m}: forgets most ({p['forgetting']:+.3f}) at a shift of {p['shift']:+g}; "
                f"{where}. {ranks}"
            )
        lines.append("")
    return "\n".join(lines)


def run_shift(
    scenarios: list[str],
    base: ExperimentConfig,
    out: Path,
    execution: Execution,
    resume: bool = False,
    overwrite: bool = False,
    argv: list[str] | None = None,
) -> dict[str, Any]:
    """Run every two-task curriculum of ``scenarios`` as one sweep into ``out``; returns the
    summary."""
    pairs = []
    for scenario in scenarios:
        first, shifted = shift_grid(scenario, base)
        pairs += [f"{first.name}+{spec.name}" for spec in shifted]
    sweeping.run_sweep(
        sweeping.SweepConfig(base, tuple(pairs)), out, execution, resume, overwrite, argv
    )
    return summarise_shift(scenarios, base, out, execution.cache)


class Shift(Study):
    name = "shift"
    examples = (
        "--scenario crowd_noise_0.1..0.6 --scenario crowd_radius_0.1..0.6 --seeds 3 --jobs 2",
        "--scenario crowd_noise_0.1,0.3,0.6 --quick --out /tmp/shift",
    )
    methods = DEFAULT_METHODS
    sweeps = True
    scenarios = True
    records = False  # dozens of two-task runs: their numbers are the point

    markdown = staticmethod(shift_markdown)

    def figure(self, report, path):
        study_figures.shift_figure(report, path)

    def run(self, args, config, execution, out, argv):
        return run_shift(
            list(args.scenario), config, out, execution, args.resume, args.overwrite, argv
        )


register(Shift())
