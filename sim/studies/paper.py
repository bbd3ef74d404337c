"""The paper's studies: ``table4`` (each C2INet part switched off in turn), ``fig9`` (the
queue's capacity gamma) and ``fig10`` (task order).

Each is a preset of the sweep (``sim.experiment.sweep``): named variants of options over a few
curricula, every job run together on one backend, resumable. Its folder holds the sweep's
outputs (a run per curriculum and variant, ``results.parquet``) plus ``study.md``,
``study.json`` and ``study.png``. ``--scenario`` replaces the presets' curricula (small runs).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from c2inet.errors import InputError
from c2inet.lazy import lazy_module
from c2inet.significance import detectable, paired
from sim.studies.base import Study, register

if TYPE_CHECKING:  # the engine loads once there is work (``sim.studies.base``)
    from sim.experiment import ExperimentConfig

# the learner, the engine and the figures load once there is work (sim.studies.base)
sweeping = lazy_module("sim.experiment.sweep")
study_figures = lazy_module("viz.study_figures")

ETH_UCY = "eth_ucy_univ,eth,zara1,zara2,hotel"  # the paper's order U-E-Z1-Z2-H
C2INET = "c2inet-online"
OFF = {  # one switch a row, the queue's terms let through to the encoder (issue 43), then the
    # paper's last row: its composite, labelled as one
    "full": {},
    "no queue (Eq 17 and the anchors off)": {
        C2INET: {"eq17": False, "distill_decoder": False, "distill_encoder": False}
    },
    "no Eq 17 (KL of C against N(0, I))": {C2INET: {"eq17": False}},
    "no Eq 8 (no fitted components)": {C2INET: {"interval": 10**6}},
    "no weight optimisation (Eq 9)": {C2INET: {"weight_opt": False}},
    "no divergence": {C2INET: {"divergence": False}},
    "no pruning": {C2INET: {"pruning": False}},
    "mechanism connected (C's KL and MI floor reach the shared encoder)": {
        "model": {"c_detached": False}
    },
    "composite: no weight optimisation, divergence or KL of Z (the paper's last row)": {
        C2INET: {"weight_opt": False, "divergence": False},
        "model": {"beta_z": 0.0},
    },
}


@dataclass(frozen=True)
class Preset:
    """Variants (label -> settings by scope) of one method over curricula; ``by`` says what the
    figure compares: the variants (``variant``) or the curricula (``order``)."""

    title: str
    scenarios: tuple[str, ...]
    variants: dict[str, dict[str, dict[str, Any]]]
    by: str = "variant"
    paper: str = ""


PRESETS = {
    "table4": Preset(
        "Table 4: C2INet-online with each part switched off",
        (ETH_UCY, "crowd_radius_0.1..0.6"),
        OFF,
        paper="ETH-UCY (U-E-Z1-Z2-H): every removal raises the error; removing everything most "
        "(up to 21.6 %), the divergence term next (5 to 17 %), weight optimisation least (3.7 %)",
    ),
    "fig9": Preset(
        "Fig 9: the queue's capacity gamma",
        (ETH_UCY,),
        {f"gamma={g}": {C2INET: {"capacity": g}} for g in (15, 30, 45, 60)},
        paper="gamma = 45 best, 15 worst: too small and too large a queue both hurt",
    ),
    "fig10": Preset(
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


def study_sweep(study: Preset, base: ExperimentConfig, scenarios: tuple[str, ...] | None):
    return sweeping.SweepConfig(
        base, scenarios or study.scenarios, variants=tuple(study.variants.items())
    )


def summarise_study(study: Preset, entries: list[tuple[str, ExperimentConfig, dict]]) -> dict:
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
                        "final_ade_per_seed",
                        "avg_seen_ade_k1",
                        "final_ade_k1_per_seed",
                    )
                    if key in m
                },
            }
        )
    k = entries[0][1].k if entries else None
    return {"study": study.title, "paper": study.paper, "k": k, "rows": rows}


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


def paired_text(row: dict, first: dict, key: str = "final_ade_per_seed") -> str:
    """``row`` minus ``first`` over the same seeds (``key``: the per-seed finals compared): the
    mean difference, its 95 % interval and p; a dash for the first row itself or with one
    seed."""
    if row is first or key not in row or len(row[key]) < 2:
        return "-"
    result = paired(row[key], first[key])
    low, high = result.interval
    return f"{result.difference:+.4f} [{low:+.4f}, {high:+.4f}], p = {result.p_value:.3f}"


def detectable_text(rows: list[dict], k: Any) -> str:
    """What the table's seeds can see: the smallest paired difference it detects at 80 % power,
    for K = 1 and for best of K, from the median spread of its paired differences."""
    parts = []
    for key, name in (("final_ade_k1_per_seed", "K = 1"), ("final_ade_per_seed", f"best of {k}")):
        differences = [
            [a - b for a, b in zip(r[key], rows[0][key], strict=True)]
            for r in rows[1:]
            if key in r and key in rows[0]
        ]
        found = detectable(differences) if differences else None
        if found is not None:
            parts.append(f"{found:.3f} m ({100 * found / _final(rows[0], key):.0f} %) at {name}")
    if not parts:
        return ""
    seeds = rows[0]["seeds"]
    return (
        f"With {seeds} paired seeds this table detects a difference of about "
        + " and ".join(parts)
        + " (80 % power, 5 % two-sided, the median spread of its paired differences); a smaller "
        "effect reads as no effect here."
    )


def _final(row: dict, key: str) -> float:
    return sum(row[key]) / len(row[key])


def study_markdown(summary: dict) -> str:
    k = summary.get("k", "K")
    lines = [f"# {summary['study']}", "", f"The paper: {summary['paper']}.", ""]
    if summary.get("by") == "order":
        lines += order_table(summary)
    lines += [
        f"Cells: ADE/FDE in metres, best of K = {k} sampled futures, averaged over the tasks "
        "seen so far after each task, mean over seeds (± std of the final average); in brackets "
        "the change of the final ADE against the first row of its curriculum. The last columns "
        "pair each seed's final ADE with the first row's on the same seed and data, at best of "
        f"{k} and for the point prediction (K = 1, what the boards rank): the mean difference, "
        "its 95 % interval and the paired t-test's p (a difference whose interval holds 0 is "
        "within the seed spread).",
        "",
    ]
    scenarios = dict.fromkeys(r["scenario"] for r in summary["rows"])
    for scenario in scenarios:
        rows = [r for r in summary["rows"] if r["scenario"] == scenario]
        lines += [f"## {scenario}", "", *variant_table(rows, k), ""]
        found = detectable_text(rows, k)
        lines += [found, ""] if found else []
    return "\n".join(lines)


def variant_table(rows: list[dict], k: Any) -> list[str]:
    """One row a variant: the seen-task averages, forgetting, and both paired comparisons."""
    labels = rows[0]["labels"]
    lines = [
        "| variant | " + " | ".join(labels) + f" | forgetting | best of {k} vs first row | "
        "final K = 1 | K = 1 vs first row |",
        "|---|" + "---|" * (len(labels) + 4),
    ]
    reference = rows[0]["avg_seen_ade"][-1]
    for r in rows:
        cells = [
            f"{a:.3f}/{f:.3f}" for a, f in zip(r["avg_seen_ade"], r["avg_seen_fde"], strict=True)
        ]
        change = r["avg_seen_ade"][-1] - reference
        cells[-1] += f" ± {r['avg_seen_ade_std'][-1]:.3f} ({change:+.3f})"
        point = f"{r['avg_seen_ade_k1'][-1]:.3f}" if "avg_seen_ade_k1" in r else "-"
        lines.append(
            f"| {r['variant']} | "
            + " | ".join(cells)
            + f" | {r['forgetting_final_ade']:+.3f} | {paired_text(r, rows[0])} | {point} | "
            f"{paired_text(r, rows[0], 'final_ade_k1_per_seed')} |"
        )
    return lines


class PaperStudy(Study):
    """One of the paper's studies: its preset's sweep of C2INet-online, summarised per variant
    or per task order."""

    methods = C2INET
    sweeps = True
    scenarios = True
    scenario_required = False
    report = "study"

    markdown = staticmethod(study_markdown)

    def figure(self, report, path):
        study_figures.study_figure(report, path)

    def __init__(self, name: str, preset: Preset):
        self.name, self.preset, self.title = name, preset, preset.title
        self.examples = (
            "--seeds 3 --jobs 2",
            f"--quick --scenario crowd_radius_0.1,0.2 --out /tmp/{name}",
        )

    def scenario_of(self, args) -> str:
        return (args.scenario or self.preset.scenarios)[0]

    def run(self, args, config, execution, out, argv):
        if config.methods != (C2INET,):
            raise InputError(f"--methods: the paper's studies are of {C2INET} alone")
        scenarios = tuple(args.scenario) if args.scenario else None
        sweep = study_sweep(self.preset, config, scenarios)
        entries = sweeping.run_sweep(sweep, out, execution, args.resume, args.overwrite, argv)
        return {**summarise_study(self.preset, entries), "by": self.preset.by}


for _name, _preset in PRESETS.items():
    register(PaperStudy(_name, _preset))
