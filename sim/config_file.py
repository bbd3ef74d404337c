"""Options from a file (``--config FILE``: TOML, or a run's ``config.json``), checked as
strictly as the flags, and a run's resolved options written back as such a file
(``--print-config``)."""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path
from typing import Any

from c2inet.errors import InputError, did_you_mean, one_line
from sim.experiment.folders import MAX_CONFIG_BYTES

SAME_NAME = (
    *("scenario", "methods", "seed", "seeds", "epochs", "k", "backbone", "quick", "scenarios_dir"),
    *("jobs", "backend", "threads", "workers", "cache", "rerun", "memory_budget", "ray_address"),
    "device",
)
# a configuration file's key -> the option (argparse dest) that takes it
CONFIG_KEYS = {**{name: name for name in SAME_NAME}, "record": "no_record", "loggers": "logger"}
SWITCHES = ("quick", "record")  # true or false, not text
NUMBERS = ("seed", "seeds", "epochs", "k", "jobs", "threads", "workers", "memory_budget")
LISTS = ("methods", "loggers", "scenarios_dir")  # text, or a list of texts


def _typed(path: Path, key: str, value: Any) -> None:
    """Refuse a file's value of the wrong type, as strictly as the flag would: a number as
    text (``epochs = "3"``), a list, a table or a date where one value is meant."""
    if key in SWITCHES:
        ok, expected = isinstance(value, bool), "true or false"
    elif key in NUMBERS:
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        expected = "a number"
    elif key in LISTS:
        items = value if isinstance(value, list) else [value]
        ok, expected = all(isinstance(v, str) for v in items), "text or a list of texts"
    else:
        ok, expected = isinstance(value, str), "text"
    if not ok:
        raise InputError(f"--config {path}: {key} = {value!r}: expected {expected}")


# what a run's config.json may carry over from its execution table: how much of this machine
# to use. Where data goes (a cache folder, a tracking server, a viewer, a Ray cluster) is never
# taken from someone else's file
SAFE_EXECUTION = ("backend", "jobs", "threads", "workers", "memory_budget")


def read_config(path: Path, notes: list[str] | None = None) -> dict[str, Any]:
    """A configuration file as one flat table: TOML, or JSON such as a run's ``config.json``
    (its ``experiment`` table, and of its ``execution`` table the keys of
    :data:`SAFE_EXECUTION`, said on stderr, or appended to ``notes`` for the caller to say once
    the command line holds)."""
    try:
        if not path.is_file():  # a FIFO or a device would never end
            raise OSError("not a regular file")
        if path.stat().st_size > MAX_CONFIG_BYTES:
            raise OSError(f"larger than {MAX_CONFIG_BYTES} bytes")
        text = path.read_text(encoding="utf-8")
        data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as error:
        why = "nested too deeply" if isinstance(error, RecursionError) else str(error)
        raise InputError(f"--config {path}: cannot read it: {one_line(why)}") from None
    if not isinstance(data, dict):
        raise InputError(f"--config {path}: expected a table of options")
    if isinstance(data.get("experiment"), dict):
        execution = data.get("execution")
        execution = execution if isinstance(execution, dict) else {}
        taken = {k: v for k, v in execution.items() if k in SAFE_EXECUTION}
        left = sorted(
            k if k.isidentifier() else repr(k) for k, v in execution.items() if k not in taken and v
        )
        if taken or left:
            note = (
                f"--config {path}: of its execution, applies "
                f"{', '.join(f'{k}={v}' for k, v in sorted(taken.items())) or 'nothing'}"
                + (f"; not {', '.join(left)} (give them as flags)" if left else "")
            )
            if notes is None:
                print(note, file=sys.stderr)
            else:
                notes.append(note)
        data = {**taken, **data["experiment"]}
    return data


def config_defaults(
    path: Path, p: argparse.ArgumentParser, notes: list[str] | None = None
) -> tuple[dict, dict]:
    """The parser's defaults from ``path``, as if typed (so checked by the same types), and the
    file's ``--set`` settings (what it says of a run's execution: into ``notes``). A key this
    command has no option for is skipped; a key no command knows is an error."""
    data, dests = read_config(path, notes), {a.dest for a in p._actions}
    defaults = {}
    for key, value in data.items():
        if key == "settings":  # merged with --set apart
            continue
        if key not in CONFIG_KEYS:
            known = did_you_mean(key, CONFIG_KEYS)
            raise InputError(f"--config {path}: unknown option {key!r}{known}")
        dest = CONFIG_KEYS[key]
        if dest not in dests or value is None:
            continue
        _typed(path, key, value)
        if key == "record":
            value = not value
        elif key in ("methods", "loggers") and isinstance(value, list):
            value = ",".join(map(str, value))
        elif key == "scenarios_dir":
            value = [Path(v) for v in (value if isinstance(value, list) else [value])]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = str(value)  # argparse types a string default: the flag's own checks apply
        defaults[dest] = value
    settings = data.get("settings", {})
    if not isinstance(settings, dict) or not all(isinstance(v, dict) for v in settings.values()):
        raise InputError(f"--config {path}: settings must be tables of SCOPE.KEY = VALUE")
    return defaults, settings


def toml_value(value: Any) -> str:
    """One TOML value: text, a number, true/false, or a list of them."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return json.dumps(str(value))  # a JSON string is a TOML basic string


def resolved_config(config, execution) -> str:
    """The configuration a run of ``config`` on ``execution`` uses, as a ``--config`` file:
    every option, defaults included, then each settings scope as a table."""
    lines = [
        f"scenario = {toml_value(config.scenario)}",
        f"methods = {toml_value(config.methods)}",
        *(
            f"{key} = {toml_value(getattr(config, key))}"
            for key in ("seed", "seeds", "epochs", "k", "backbone", "quick", "record", "device")
        ),
        *(
            f"{key} = {toml_value(getattr(execution, key))}"
            for key in ("backend", "jobs", "threads", "workers")
        ),
    ]
    if config.scenarios_dir:
        lines.append(f"scenarios_dir = {toml_value([str(d) for d in config.scenarios_dir])}")
    for scope, values in sorted(config.settings.items()):
        lines += ["", f"[settings.{json.dumps(scope) if '-' in scope else scope}]"]
        lines += [
            f"{json.dumps(k) if '.' in k else k} = {toml_value(v)}" for k, v in values.items()
        ]
    return "\n".join(lines) + "\n"
