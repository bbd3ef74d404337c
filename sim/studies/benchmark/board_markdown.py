"""The fair benchmark's leaderboard as Markdown (``leaderboard.md``): what ran, the ranking on
its metric (the point prediction, or best of K) with both tests, the other metric, the
references, the decisive pair, the chosen settings and cost; and the tuned Table 2 over several
committed boards."""

from __future__ import annotations

from typing import Any

from c2inet.report import COMPARED, RANKABLE, comparison_rows, markdown_table


def ranked_metric(board: dict[str, Any]) -> str:
    """What ``board`` ranks by: ``ade_k1`` (the point prediction; every board before the metric
    was an option) or ``ade`` (best of K)."""
    return board.get("metric", "ade_k1")


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


def _design_text(design: dict[str, Any] | None) -> str:
    """How a shipped tuning was made, in words."""
    if not design:
        return "a board's own tuning"
    if design.get("kind") == "staged":
        return (
            f"the staged design: learning rates {design['lr_low']:g} to {design['lr_high']:g} "
            f"on {design['lr_points']} points (offset {design['offset']:g}), each knob in turn, "
            f"every setting on the same {design['draws']} data draws"
            + (
                ", the defaults kept over the walk's choice only where better on every draw"
                if design.get("keep_defaults") == "every-draw"
                else ", the defaults kept over the walk's choice where better on the mean"
            )
        )
    return f"{design['trials']} Optuna trials a method ({design['sampler']}), one data draw a trial"


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
        source = board["tuned_from"]
        tuning = (
            f"**no tuning here**: every method's settings from one tuning, `{source['file']}` "
            f"(SHA-256 `{source['sha256'][:12]}`; {_design_text(source.get('design'))}, "
            f"tuned on `{board['tune_scenario']}`); the board rests on that one tuning, so its "
            "intervals hold the seeds' spread, not a second tuning's"
        )
    elif board.get("design"):
        tuning = (
            f"tuned by {_design_text(board['design'])}, on `{board['tune_scenario']}`"
            f"{_tuning_seed_text(board)} scored on validation data only (one tuning: the "
            "intervals hold the seeds' spread, not a second tuning's)"
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
        f"Ranked by final average ADE of {RANKABLE[ranked_metric(board)]}. Intervals are 95 %; "
        "p is "
        f"a paired t-test against {board['reference']} over the same seeds and the sign-flip "
        f"permutation test's beside it (no normality assumed), each Holm-adjusted over the "
        f"board, `*` below {board['alpha']}; a difference whose interval holds 0 is within "
        "the seed spread. Memory: floats a method keeps between tasks besides the model."
        + (f" Every replay method keeps {replay} scenes in all." if replay else "")
    )


def _rankings(board: dict[str, Any]) -> list[str]:
    """The ranking on the board's metric, then the board ordered by the other one."""
    metric = ranked_metric(board)
    other = next(m for m in COMPARED if m != metric)
    comparison = {e["method"]: e for e in board["entries"]}
    ranked = comparison_rows(comparison, metric)  # the entries are in rank order
    ranked[0].insert(4, "sign-flip p")
    for row, e in zip(ranked[1:], board["entries"], strict=True):
        p = e[f"final_{metric}"].get("p_signflip")
        row.insert(4, "-" if p is None else f"{p:.3f}" + (" *" if p < board["alpha"] else ""))
        row[0] += " †" if e.get("at_bound") else ""
    ranks = ["rank", *(str(e["rank"]) for e in board["entries"])]
    by_other = dict(sorted(comparison.items(), key=lambda item: item[1][f"final_{other}"]["mean"]))
    return [
        f"{_capital(RANKABLE[metric])} (ranked):",
        "",
        markdown_table([[rank, *row] for rank, row in zip(ranks, ranked, strict=True)]),
        "",
        *_bound_note(board),
        f"{_capital(RANKABLE[other])} (ordered by its own final average):",
        "",
        markdown_table(comparison_rows(by_other, other)),
        "",
    ]


def _capital(text: str) -> str:
    return text[0].upper() + text[1:]


def _bound_note(board: dict[str, Any]) -> list[str]:
    """The methods marked † and the knobs their tuning chose at a bound of its range."""
    marked = [
        e["method"] + " (" + ", ".join(f"{k} at its {side} bound" for k, side in marks) + ")"
        for e in board["entries"]
        if (marks := list(e.get("at_bound", {}).items()))
    ]
    if not marked:
        return []
    return [
        "† chosen within 5 % (log) of its search range's bound, so the range may cut off the "
        "best setting: " + "; ".join(marked) + ".",
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
        f"Decisive pair, `{d['pair'][0]}` minus `{d['pair'][1]}` (final ADE of "
        f"{RANKABLE[ranked_metric(board)]}, paired, "
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
        if e.get("kept") == "defaults":  # the staged walk's choice scored worse in tuning
            text += " (its defaults, kept: they scored better than the tuning's choice)"
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
        f"{_parallel_text(run)}: {cost}." + _kept_text(board),
        "",
    ]


def _kept_text(board: dict[str, Any]) -> str:
    """Where the board's own tuning is kept (nothing where it took another's)."""
    if board.get("tuned_from"):
        return ""
    if board.get("design"):
        return f" Its tuning is kept as the artefact `{board['preset']}.json` beside the board."
    return f" Trials are kept in `{board['study_prefix']}`."


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


def _column(name: str, board: dict[str, Any]) -> str:
    """A board's column head: its name, and its metric where it ranks best of K (every table
    says its K)."""
    if ranked_metric(board) == "ade_k1":
        return f"`{name}`"
    return f"`{name}` (best of {board.get('k', 'K')})"


def boards_table(boards: dict[str, dict[str, Any]]) -> str:
    """The tuned Table 2: one column per committed board (``leaderboard.json``, by name), each
    ranked method's final ADE on its board's metric (K = 1 unless the board ranks best of K),
    its rank and ``*`` where it differs from fine-tuning
    after Holm's correction, methods ordered by their mean rank; then the decisive pairs and the
    references. Made from the boards alone, so REPRODUCTION can never disagree with them."""
    names = list(boards)
    cells: dict[str, dict[str, str]] = {}
    ranks: dict[str, list[int]] = {}
    for name, board in boards.items():
        for entry in board["entries"]:
            cell = entry[f"final_{ranked_metric(board)}"]
            mark = " *" if cell.get("significant") else ""
            cells.setdefault(entry["method"], {})[name] = (
                f"{cell['mean']:.3f} ({entry['rank']}){mark}"
            )
            ranks.setdefault(entry["method"], []).append(entry["rank"])
    order = sorted(cells, key=lambda m: (sum(ranks[m]) / len(ranks[m]), m))
    header = "| method | " + " | ".join(_column(n, boards[n]) for n in names) + " |"
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
        + ", ".join(
            f"{r['method']} {r[f'final_{ranked_metric(board)}']['mean']:.3f}"
            for r in board["references"]
        )
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
