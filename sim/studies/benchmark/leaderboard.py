"""The fair benchmark's leaderboard: the ranked methods with intervals and Holm-adjusted paired
tests (the t-test's and the sign-flip test's) against fine-tuning, the marks of settings chosen
at a bound, the references apart, the decisive pair, and what ran, as a dict
(``leaderboard.json``; ``board_markdown.py`` writes it as Markdown)."""

from __future__ import annotations

from typing import Any

from c2inet.report import COMPARED, REFERENCE, compare
from c2inet.significance import ALPHA, holm, interval, interval_width, paired, sign_flip
from sim.experiment.design import near_bound
from sim.experiment.tuning import search_space


def adjust(comparison: dict[str, dict[str, Any]]) -> None:
    """Holm's correction over the board, in place: each compared metric's final-average p-values
    of every method against the reference form one family; ``p_raw`` keeps the test's own,
    ``p_value`` and ``significant`` become the adjusted."""
    tested = [name for name in comparison if name != REFERENCE]
    for metric in COMPARED:
        cells = [comparison[name][f"final_{metric}"] for name in tested]
        for cell, p in zip(cells, holm([c["p_value"] for c in cells]), strict=True):
            cell["p_raw"], cell["p_value"] = cell["p_value"], None if p is None else round(p, 6)
            cell["significant"] = p is not None and p < ALPHA


def add_sign_flips(
    comparison: dict[str, dict[str, Any]], summaries: dict[str, dict], metric: str = "ade_k1"
) -> None:
    """Beside each t-test on the ranked final ADE (``metric``), the sign-flip permutation test's
    p (``p_signflip_raw``) and its Holm-adjusted value over the board (``p_signflip``): a verdict
    that needs the t-test's normality shows as a star the permutation test does not give."""
    tested = [name for name in comparison if name != REFERENCE]
    reference = summaries[REFERENCE][f"final_{metric}_per_seed"]
    raw = []
    for name in tested:  # a test-time rule's row (``METHOD, RULE``) is not a board's method
        values = None if "," in name else summaries[name][f"final_{metric}_per_seed"]
        differences = [a - b for a, b in zip(values or [], reference, strict=False)]
        raw.append(sign_flip(differences) if values else None)
    for name, p, adjusted in zip(tested, raw, holm(raw), strict=True):
        cell = comparison[name][f"final_{metric}"]
        cell["p_signflip_raw"] = None if p is None else round(p, 6)
        cell["p_signflip"] = None if adjusted is None else round(adjusted, 6)


def bounds_of(method: str, settings: dict[str, dict[str, Any]]) -> dict[str, str]:
    """The chosen settings of ``method`` within 5 % of a bound of its search space: knob ->
    ``low`` or ``high`` (a mark on the board, and a range to widen)."""
    space, marks = search_space(method), {}
    for scope, values in settings.items():
        for key, value in values.items():
            name = key if scope == method else f"{scope}.{key}"
            side = near_bound(space[name], value) if name in space else None
            if side:
                marks[name] = side
    return marks


def reference_rows(summaries: dict[str, dict[str, Any]], names: tuple[str, ...]) -> list[dict]:
    """What the references block shows: final averages with their intervals, never tested."""
    rows = []
    for name in names:
        s = summaries[name]
        row: dict[str, Any] = {"method": name, "seeds": s["seeds"]}
        for metric in COMPARED:
            values = s[f"final_{metric}_per_seed"]
            bounds = interval(values)
            row[f"final_{metric}"] = {
                "mean": round(sum(values) / len(values), 6),
                "interval": None if bounds is None else [round(b, 6) for b in bounds],
            }
        row["memory_floats"] = s.get("memory_floats", [0])[-1]
        row["cpu_seconds"] = round(s["cpu_seconds"], 1)
        rows.append(row)
    return rows


def decide(
    pair: tuple[str, str], summaries: dict[str, dict[str, Any]], width: float, metric: str
) -> dict:
    """The decisive pair over all the seeds it ran: the paired difference of the ranked final
    ADE (``metric``; first minus second), its interval, its width and what it says."""
    a, b = (summaries[m][f"final_{metric}_per_seed"] for m in pair)
    test = paired(a, b)
    low, high = test.interval or (float("-inf"), float("inf"))
    narrow = interval_width([x - y for x, y in zip(a, b, strict=True)]) < width
    if low > 0 or high < 0:
        better, worse = (pair[1], pair[0]) if low > 0 else pair
        verdict = f"{better} is better than {worse} by {abs(test.difference):.3f} m"
    elif narrow:
        verdict = f"no difference: the interval holds 0 and is narrower than {width:g} m"
    else:
        verdict = f"undecided: the interval holds 0 and is still wider than {width:g} m"
    return {
        "pair": list(pair),
        "seeds": len(a),
        "difference": round(test.difference, 6),
        "interval": None if test.interval is None else [round(v, 6) for v in test.interval],
        "width": width,
        "p_value": test.p_value,
        "verdict": verdict,
    }


def protocol(bench, run: dict[str, Any]) -> dict[str, Any]:
    """What a board was run with: curricula, sizes, tuning (or whose settings it took) and
    statistics."""
    base = bench.base
    train = base.train_config()
    return {
        "preset": bench.name,
        "scenario": base.scenario,
        "tune_scenario": (
            bench.borrowed[1].get("tune_scenario", "unknown")
            if bench.borrowed
            else bench.tuning().base.scenario
        ),
        **({"tuned_from": bench.borrowed[1]} if bench.borrowed else {}),
        "study_prefix": bench.key(),
        "sizes": run["sizes"],
        "epochs": base.epochs,
        "batch_scenes": train.batch_scenes,
        "k": base.k,
        "metric": bench.metric,
        "data": base.settings.get("data", {}),
        "trials": bench.trials,
        **({"design": bench.design.to_json()} if bench.design and not bench.borrowed else {}),
        "seed": base.seed,
        "tuning_seed": bench.tuning().base.seed,
        "prune": bench.prune,
        "race": bench.race,
        "race_seeds": bench.race_seeds,
        "sampler": bench.sampler,
        "replay_budget": bench.replay_budget,
        "seeds": base.seeds,
        "reference_seeds": bench.reference_seeds,
        "quick": base.quick,
        "reference": REFERENCE,
        "alpha": ALPHA,
        "correction": "holm",
    }


def leaderboard(
    bench,
    summaries: dict[str, dict[str, Any]],
    chosen: dict[str, dict[str, Any]],
    decisive: dict[str, dict[str, Any]] | None,
    run: dict[str, Any],
) -> dict[str, Any]:
    """The ranked methods by their final ADE (the point prediction's, or the best of K where
    the preset ranks that) over the common seeds, each with its interval, the Holm-adjusted
    paired test against fine-tuning, forgetting, memory, CPU cost and the settings tuning chose;
    the references apart; the decisive pair; what ran."""
    comparison = compare({m: summaries[m] for m in bench.ranked})
    adjust(comparison)
    add_sign_flips(comparison, summaries, bench.metric)
    ranked = sorted(comparison, key=lambda name: comparison[name][f"final_{bench.metric}"]["mean"])
    entries = []
    for rank, name in enumerate(ranked, 1):
        method = name.split(",")[0]
        entries.append(
            {
                "rank": rank,
                "method": name,
                **comparison[name],
                "cpu_seconds": round(summaries[method]["cpu_seconds"], 1),
                "settings": chosen[method]["settings"],
                "trials": len(chosen[method]["trials"]),
                "pruned": sum(t.get("pruned", False) for t in chosen[method]["trials"]),
                "at_bound": bounds_of(method, chosen[method]["settings"]),
                **({"kept": "defaults"} if chosen[method].get("kept") == "defaults" else {}),
                **({"race": chosen[method]["race"]} if "race" in chosen[method] else {}),
            }
        )
    return {
        **protocol(bench, run),
        "entries": entries,
        "references": reference_rows(summaries, bench.references),
        "decisive": decisive and decide(bench.compare, decisive, bench.width, bench.metric),
        "run": run,
    }
