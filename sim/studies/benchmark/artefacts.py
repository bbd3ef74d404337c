"""Tuning as a shipped artefact: one JSON file a preset under ``tunings/``, holding every
method's chosen settings with everything that produced them (the curricula, the design, the
budget, every run's draws and scores, the commit, the machine). A board evaluates with its
preset's artefact unless told to ``--retune``; ``sim.run --tuned-from PRESET`` runs a method as
the board ran it, without the benchmark (as Mammoth ships its best arguments).

An artefact is ``{"format": 1, "preset", "scenario", "tune_scenario", "design", "seed",
"provenance", "methods": {METHOD: {"settings", "objective", ..., "trials"}}}``; a board's own
``tuning/tuning.json`` (methods at the top) reads the same way, so either may be given."""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path
from typing import Any

from c2inet.errors import InputError, one_line
from c2inet.files import file_digest, write_text_atomic
from c2inet.methods.base import get_method
from sim.experiment.folders import MAX_CONFIG_BYTES
from sim.experiment.tuning import search_space
from sim.studies.benchmark.presets import BATCH, PRESETS, REPLAY_BUDGET

FORMAT = 1
SHIPPED = Path(__file__).parent / "tunings"  # the package's artefacts, one a preset


def shown(path: Path) -> str:
    """``path`` as a board prints it: a shipped artefact by its place in the package
    (``sim/studies/benchmark/tunings/radius.json``), never the folder it is installed in;
    any other file as given."""
    if path.resolve().parent == SHIPPED.resolve():
        return f"sim/studies/benchmark/tunings/{path.name}"
    return str(path)


def shipped(preset: str) -> Path | None:
    """The artefact the package ships for ``preset`` (None where it ships none)."""
    path = SHIPPED / f"{preset}.json"
    return path if path.is_file() else None


def read_json(path: Path, option: str) -> Any:
    """A small JSON file of ours, or one line saying why it cannot be read."""
    try:
        if not path.is_file():  # a FIFO or a device would never end
            raise OSError("not a regular file")
        if path.stat().st_size > MAX_CONFIG_BYTES:
            raise OSError(f"larger than {MAX_CONFIG_BYTES} bytes")
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as error:
        why = "nested too deeply" if isinstance(error, RecursionError) else str(error)
        raise InputError(f"{option} {path}: cannot read it: {one_line(why)}") from None


def read_tuning(given: Path, option: str = "--tuned-from") -> tuple[Path, dict, dict]:
    """A tuning given as a file (an artefact or a board's ``tuning.json``), a board's folder
    (its ``tuning.json``, or the artefact a staged tuning wrote beside it) or a preset's name
    (its shipped artefact): the file found, the whole table and its methods; one line where
    there is none or it is not a table of methods."""
    named = len(given.parts) == 1 and not given.suffix and not given.exists()
    candidates = [shipped(str(given))] if named else []
    candidates += [given, given / "tuning.json", given / "tuning" / "tuning.json"]
    candidates += _beside_board(given, option)
    path = next((c for c in candidates if c is not None and c.is_file()), None)
    if path is None:
        raise InputError(
            f"{option} {given}: neither a preset that ships a tuning ({_names()}) nor a tuning "
            "file or a benchmark's folder"
        )
    table = read_json(path, option)
    if not isinstance(table, dict):
        raise InputError(f"{option} {path}: expected a table of methods")
    try:
        return path, table, methods_of(table)
    except InputError as error:
        raise InputError(f"{option} {path}: {error}") from None


def _beside_board(folder: Path, option: str) -> list[Path]:
    """The artefact a board tuned by the staged design keeps beside itself (``PRESET.json``,
    named by its ``leaderboard.json``)."""
    board = folder / "leaderboard.json"
    if not board.is_file():
        return []
    meta = read_json(board, option)
    preset = meta.get("preset") if isinstance(meta, dict) else None
    return [folder / f"{preset}.json"] if isinstance(preset, str) and "/" not in preset else []


def methods_of(table: dict[str, Any]) -> dict[str, Any]:
    """The method table of an artefact, or of a board's ``tuning.json`` (methods at the top)."""
    if table.get("format") is not None:
        if table["format"] != FORMAT or not isinstance(table.get("methods"), dict):
            raise InputError(f"a tuning artefact of format {table['format']!r}: expected {FORMAT}")
        return table["methods"]
    return table


def write_artefact(
    path: Path,
    preset: str,
    scenario: str,
    tune_scenario: str,
    design: dict[str, Any],
    seed: int,
    provenance: dict[str, Any],
    methods: dict[str, Any],
) -> dict[str, Any]:
    """Write an artefact (temporary file, then rename) and return it."""
    artefact = {
        "format": FORMAT,
        "preset": preset,
        "scenario": scenario,
        "tune_scenario": tune_scenario,
        "design": design,
        "seed": seed,
        "provenance": provenance,
        "methods": methods,
    }
    write_text_atomic(path, json.dumps(artefact, indent=1, sort_keys=False) + "\n")
    return artefact


def from_board(board: Path, preset: str, out: Path) -> dict[str, Any]:
    """An artefact made from a committed board's own tuning (its ``tuning.json`` and
    ``leaderboard.json``): the design it used (Optuna, one data draw a trial, the 3-task
    curriculum), said as such, with the file it came from and its SHA-256."""
    tuning, meta = board / "tuning.json", json.loads((board / "leaderboard.json").read_text())
    run = meta.get("run", {})
    design = {
        "kind": "optuna",
        "sampler": meta.get("sampler", "tpe"),
        "trials": meta["trials"],
        "race": meta.get("race", 0),
        "prune": meta.get("prune", False),
        "draws": 1,  # every trial on its own single data draw
        "tasks": None,  # the tuning curriculum's, below
    }
    provenance = {
        "made_by": run.get("command"),
        "from_board": str(board),
        "file": str(tuning),
        "sha256": file_digest(tuning),
        "study_prefix": meta.get("study_prefix"),
        "commits": run.get("commits", []),
        "machine": run.get("machine"),
        "epochs": meta.get("epochs"),
        "batch_scenes": meta.get("batch_scenes"),
        "data": meta.get("data", {}),
        "note": "a single tuning: one Optuna study a method on a 3-task curriculum, each trial "
        "scored on one data draw (the design issue 60 found unstable)",
    }
    return write_artefact(
        out,
        preset,
        meta["scenario"],
        meta["tune_scenario"],
        design,
        meta.get("tuning_seed", meta.get("seed", 0)),
        provenance,
        json.loads(tuning.read_text()),
    )


def tuned_settings(given: str, methods: tuple[str, ...], tasks: int) -> tuple[dict[str, dict], str]:
    """``sim.run --tuned-from PRESET|FILE``: the settings a tuning chose for ``methods`` (a
    preset's shipped artefact, an artefact file or a board's ``tuning.json``), as ``--set``
    settings by scope, and the file they came from; by a preset's name also what its board
    sets (batch, data sizes, the replay budget over ``tasks`` tasks), so the run is the board's
    job. The trainer's and the model's options are shared by every method of one run, so
    methods tuned to different ``train.*`` or ``model.*`` values are one line: run them one at
    a time (or the board)."""
    path, _, table = read_tuning(Path(given))  # the one reading of a name, file or folder
    by_name = path == shipped(given)  # a preset's own artefact: its board's settings too
    settings = _board_settings(given, methods, tasks) if by_name else {}
    for method in methods:
        entry = table.get(method)
        if not isinstance(entry, dict) or not isinstance(entry.get("settings"), dict):
            raise InputError(f"--tuned-from {path}: no chosen settings of {method!r}")
        tunable_only(f"--tuned-from {path}: {method}", method, entry["settings"])
        for scope, values in entry["settings"].items():
            for key, value in values.items():
                have = settings.setdefault(scope, {})
                if scope in ("train", "model") and have.get(key, value) != value:
                    raise InputError(
                        f"--tuned-from {path}: the methods were tuned to different {scope}.{key} "
                        "values; run one method at a time (or the board: python -m sim.bench)"
                    )
                have[key] = value
    return settings, str(path)


def _board_settings(preset: str, methods: tuple[str, ...], tasks: int) -> dict[str, dict]:
    """What a preset's board sets beside the tuning: batch, data sizes, replay budget."""
    settings = {"train": {"batch_scenes": BATCH}, "data": dict(PRESETS[preset].data)}
    for method in methods:
        options = get_method(method).replay_options(REPLAY_BUDGET, tasks)
        if options:
            settings[method] = dict(options)
    return settings


def _names() -> str:
    return ", ".join(sorted(p.stem for p in SHIPPED.glob("*.json"))) or "none"


def tunable_only(where: str, method: str, settings: dict[str, dict[str, Any]]) -> None:
    """Refuse a borrowed setting no tuning of ``method`` could have chosen: an unknown scope,
    the data (the board would be evaluated on other data than it says), or a key outside the
    method's search space (``sim.experiment.tuning.search_space``: ``train.lr`` and its own)."""
    space = search_space(method)
    for scope, values in settings.items():
        if scope not in ("train", "model", method):
            why = "the data are the board's own" if scope == "data" else "an unknown scope"
            raise InputError(
                f"{where}: settings of scope {scope!r}: {why}; a tuning chooses train.*, "
                f"model.* and {method}.* within its search space"
            )
        for key in values:
            name = key if scope == method else f"{scope}.{key}"
            if name not in space:
                known = ", ".join(sorted(space)) or "nothing (it is not tuned)"
                raise InputError(
                    f"{where}: {scope}.{key} is outside {method}'s search space ({known})"
                )


def reselected(given: Path, rule: str, out: Path) -> dict[str, Any]:
    """A staged artefact (a file, a board's folder or a preset's name) chosen anew from its own
    runs with ``rule`` keeping the defaults (``sim.experiment.staged.reselect``: no run), written
    to ``out`` with its design saying the rule and its provenance the file it came from."""
    from sim.experiment.design import Design
    from sim.experiment.staged import reselect

    path, artefact, _ = read_tuning(given, "reselect")
    named = artefact.get("design") or {}
    if artefact.get("format") is None or named.get("kind") != "staged":
        raise InputError(f"{path}: not a staged tuning's artefact; only its runs can be reselected")
    shape = {f.name: named[f.name] for f in fields(Design) if f.name in named}
    design = Design(**shape).keeping(rule)  # the design's other words (its metric) kept below
    provenance = {
        "reselected_from": shown(path),
        "sha256": file_digest(path),
        "keep_defaults": rule,
        "tuned": artefact["provenance"],
    }
    return write_artefact(
        out,
        artefact["preset"],
        artefact["scenario"],
        artefact["tune_scenario"],
        {**{k: v for k, v in named.items() if k != "keep_defaults"}, **design.to_json()},
        artefact["seed"],
        provenance,
        reselect(artefact, design),
    )
