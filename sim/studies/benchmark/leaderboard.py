"""The fair benchmark's leaderboard: the ranked methods with intervals and Holm-adjusted paired
tests against fine-tuning, the references apart, the decisive pair, and what ran; as a dict
(``leaderboard.json``) and as Markdown (``leaderboard.md``)."""

from __future__ import annotations

from typing import Any

from c2inet.report import COMPARED, REFERENCE, compare, comparison_rows, markdown_table
from c2inet.significance import ALPHA, holm, interval, interval_width, paired


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


def decide(pair: tuple[str, str], summaries: dict[str, dict[str, Any]], width: float) -> dict:
    """The decisive pair over all the seeds it ran: the paired difference of final
    point-prediction ADE (first minus second), its interval, its width and what it says."""
    a, b = (summaries[m]["final_ade_k1_per_seed"] for m in pair)
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
        "data": base.settings.get("data", {}),
        "trials": bench.trials,
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
    """The ranked methods by final point-prediction ADE over the common seeds, each with its
    interval, the Holm-adjusted paired test against fine-tuning, forgetting, memory, CPU cost
    and the settings tuning chose; the references apart; the decisive pair; what ran."""
    comparison = compare({m: summaries[m] for m in bench.ranked})
    adjust(comparison)
    ranked = sorted(comparison, key=lambda name: comparison[name]["final_ade_k1"]["mean"])
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
                "pruned": sum(t["pruned"] for t in chosen[method]["trials"]),
                **({"race": chosen[method]["race"]} if "race" in chosen[method] else {}),
            }
        )
    return {
        **protocol(bench, run),
        "entries": entries,
        "references": reference_rows(summaries, bench.references),
        "decisive": decisive and decide(bench.compare, decisive, bench.width),
        "run": run,
    }


def _data_text(data: dict[str, Any]) -> str:
    """The data sizes a board ran at, where they are not the families' own."""
    if not data:
        return ""
    return "; data: " + ", ".join(f"`{key}={value}`" for key, value in sorted(data.items()))


def _settings_text(settings: dict[str, dict[str, Any]]) -> str:
    return "; ".join(
        f"{scope}.{k}={v:.3g}" if isinstance(v, float) else f"{scope}.{k}={v}"
        for scope, options in settings.items()
        for k, v in options.items()
    )


def _tuning_seed_text(board: dict[str, Any]) -> str:
    """`` (tuning seed N)`` where the tuning had a root seed of its own."""
    seed = board.get("tuning_seed")
    return "" if seed is None or seed == board.get("seed") else f" (tuning seed {seed})"


def _race_text(board: dict[str, Any]) -> str:
    """``; its best N raced over M more seeds`` where the choice is the best mean of a race."""
    if not board.get("race"):
        return ""
    race, seeds = board["race"], board["race_seeds"]
    return f"; the {race} best raced over {seeds} more seeds each, the best mean chosen"


def _sampler_text(board: dict[str, Any]) -> str:
    """``; then asked by a Gaussian process`` where the trials after the start-up draws were."""
    return "; then asked by a Gaussian process" if board.get("sampler") == "gp" else ""


def _interval_text(cell: dict[str, Any]) -> str:
    bounds = cell["interval"]
    text = f"{cell['mean']:.3f}"
    return text if bounds is None else f"{text} [{bounds[0]:.3f}, {bounds[1]:.3f}]"


def _protocol_text(board: dict[str, Any]) -> str:
    """The paragraph under the title: the sizes and what every number means."""
    sizes = {
        "quick": "**quick sizes: a smoke test, not a result**",
        "reduced": "**reduced sizes (below the protocol's): read as a first look**",
        "protocol": "the protocol's sizes",
    }[board["sizes"]]
    given = _settings_text(board["run"]["settings"]) or "none"
    pruned = ", those worse than the median so far stopped early" if board.get("prune") else ""
    replay = board.get("replay_budget")
    if board.get("tuned_from"):
        tuning = (
            f"**no tuning here**: every method's settings as another benchmark chose them "
            f"(`{board['tuned_from']['file']}`, tuned on `{board['tune_scenario']}`)"
        )
    else:
        tuning = (
            f"{board['trials']} Optuna trials a method (its defaults first{pruned}"
            f"{_sampler_text(board)}) on `{board['tune_scenario']}`{_tuning_seed_text(board)} "
            f"scored on validation data only{_race_text(board)}"
        )
    return (
        f"{sizes}: {board['epochs']} epochs a task at batch {board['batch_scenes']}, K = "
        f"{board['k']}, {tuning}, "
        f"then {board['seeds']} seeds a method, seed s drawing its own data for every method"
        f"{_data_text(board.get('data', {}))}. `--set`: {given}. "
        f"Ranked by final average ADE of the point prediction (K = 1). Intervals are 95 %; p is "
        f"a paired t-test against {board['reference']} over the same seeds, Holm-adjusted over "
        f"the board, `*` below {board['alpha']}; a difference whose interval holds 0 is within "
        "the seed spread. Memory: floats a method keeps between tasks besides the model."
        + (f" Every replay method keeps {replay} scenes in all." if replay else "")
    )


def _rankings(board: dict[str, Any]) -> list[str]:
    """The ranking on the point prediction, then the board ordered by best of K."""
    comparison = {e["method"]: e for e in board["entries"]}
    ranked = comparison_rows(comparison, "ade_k1")  # the entries are in rank order
    ranks = ["rank", *(str(e["rank"]) for e in board["entries"])]
    by_best_of_k = dict(sorted(comparison.items(), key=lambda item: item[1]["final_ade"]["mean"]))
    return [
        "Point prediction (K = 1):",
        "",
        markdown_table([[rank, *row] for rank, row in zip(ranks, ranked, strict=True)]),
        "",
        "Best of K (ordered by its own final average):",
        "",
        markdown_table(comparison_rows(by_best_of_k, "ade")),
        "",
    ]


def _references(board: dict[str, Any]) -> list[str]:
    if not board["references"]:
        return []
    rows = [["reference", "seeds", "final avg K = 1 [95 % CI]", "final avg best of K"]]
    rows += [
        [
            r["method"],
            str(r["seeds"]),
            _interval_text(r["final_ade_k1"]),
            _interval_text(r["final_ade"]),
        ]
        for r in board["references"]
    ]
    return [
        f"References (not ranked, not tested; {board['reference']}'s tuned settings; "
        "joint-scratch trained once, on the union of every task):",
        "",
        markdown_table(rows),
        "",
    ]


def _decisive(board: dict[str, Any]) -> list[str]:
    d = board.get("decisive")
    if not d:
        return []
    bounds = d["interval"]
    return [
        f"Decisive pair, `{d['pair'][0]}` minus `{d['pair'][1]}` (final K = 1 ADE, paired, "
        f"{d['seeds']} seeds, added until the interval is narrower than {d['width']:g} m): "
        f"{d['difference']:+.4f} m"
        + ("" if bounds is None else f" [{bounds[0]:+.4f}, {bounds[1]:+.4f}]")
        + f". {d['verdict'][0].upper()}{d['verdict'][1:]}.",
        "",
    ]


def _settings_and_cost(board: dict[str, Any]) -> list[str]:
    """Each method's chosen settings and cost, then how and where the board ran."""
    settings = [["method", "chosen settings", "trials", "CPU s / job"]]
    for e in board["entries"]:
        trials = f"{e['trials']} ({e['pruned']} pruned)" if e.get("pruned") else str(e["trials"])
        text = _settings_text(e["settings"]) or "(nothing to tune)"
        settings.append([e["method"], text, trials, str(e["cpu_seconds"])])
    run = board["run"]
    cost = f"{run['wall_seconds'] / 60:.1f} min wall, {run['cpu_seconds']:.0f} CPU s of jobs"
    if run["decisive_seconds"]:
        cost += f", {run['decisive_seconds'] / 60:.1f} min of it the decisive pair's seeds"
    if run.get("estimate"):
        cost += (
            f" (estimated before it started: {run['estimate']['wall_seconds'] / 60:.1f} min, "
            f"{run['estimate']['cpu_seconds']:.0f} CPU s)"
        )
    return [
        "Chosen settings and cost:",
        "",
        markdown_table(settings),
        "",
        f"Ran: `{run['command']}` (the last of {run['calls']} calls) at commit "
        f"{', '.join(f'`{c}`' for c in run['commits'])} on {run['machine']}, "
        f"{_parallel_text(run)}: {cost}."
        + ("" if board.get("tuned_from") else f" Trials are kept in `{board['study_prefix']}`."),
        "",
    ]


def _parallel_text(run: dict[str, Any]) -> str:
    """How the jobs shared the machine: ``N jobs at a time``, or on which Ray cluster."""
    if run.get("backend") == "ray":
        address = run.get("ray_address")
        cpus = run["jobs"]
        return (
            f"on the Ray cluster at {address}"
            if address
            else f"on a local Ray cluster of {cpus} CPUs"
        )
    return f"{run['jobs']} job{'s' if run['jobs'] != 1 else ''} at a time"


def leaderboard_markdown(board: dict[str, Any]) -> str:
    """The leaderboard as Markdown: what ran, the ranking on the point prediction, best of K,
    the references, the decisive pair, the chosen settings and cost."""
    lines = [
        f"# Benchmark `{board['preset']}`: `{board['scenario']}`",
        "",
        _protocol_text(board),
        "",
        *_rankings(board),
        *_references(board),
        *_decisive(board),
        *_settings_and_cost(board),
    ]
    return "\n".join(lines)


def boards_table(boards: dict[str, dict[str, Any]]) -> str:
    """The tuned Table 2: one column per committed board (``leaderboard.json``, by name), each
    ranked method's final K = 1 ADE with its rank and ``*`` where it differs from fine-tuning
    after Holm's correction, methods ordered by their mean rank; then the decisive pairs and the
    references. Made from the boards alone, so REPRODUCTION can never disagree with them."""
    names = list(boards)
    cells: dict[str, dict[str, str]] = {}
    ranks: dict[str, list[int]] = {}
    for name, board in boards.items():
        for entry in board["entries"]:
            cell = entry["final_ade_k1"]
            mark = " *" if cell.get("significant") else ""
            cells.setdefault(entry["method"], {})[name] = (
                f"{cell['mean']:.3f} ({entry['rank']}){mark}"
            )
            ranks.setdefault(entry["method"], []).append(entry["rank"])
    order = sorted(cells, key=lambda m: (sum(ranks[m]) / len(ranks[m]), m))
    header = "| method | " + " | ".join(f"`{n}`" for n in names) + " |"
    lines = [header, "|---|" + "---|" * len(names)]
    lines += [f"| {m} | " + " | ".join(cells[m].get(n, "-") for n in names) + " |" for m in order]
    pairs = []
    for name, board in boards.items():
        pair = board.get("decisive") or {}
        if pair:
            low, high = pair["interval"]
            pairs.append(
                f"- `{name}`: {pair['pair'][0]} minus {pair['pair'][1]}, {pair['seeds']} paired "
                f"seeds: {pair['difference']:+.4f} m [{low:+.4f}, {high:+.4f}]; {pair['verdict']}"
            )
    references = [
        f"- `{name}`: "
        + ", ".join(f"{r['method']} {r['final_ade_k1']['mean']:.3f}" for r in board["references"])
        for name, board in boards.items()
        if board.get("references")
    ]
    return (
        "\n".join(
            [
                *lines,
                "",
                "Decisive pairs:",
                "",
                *(pairs or ["- none run"]),
                "",
                "References (not ranked):",
                "",
                *references,
            ]
        )
        + "\n"
    )
