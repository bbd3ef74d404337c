"""The project's own fuzzing: generated inputs for every way a user hands the project something,
each answered with a result or the project's one error (``InputError``, exit code 2), never
another exception and never a hang.

Each target pairs a Hypothesis strategy of inputs with a function that feeds one input to the
project: the scenario parser, ``--set`` options, the ``sim.run`` and ``sim.generate`` command
lines (in-process, stopped before anything is generated), ETH-UCY data files and family files.
``tests/sim/test_fuzz.py`` runs every target in CI; ``benchmarks/fuzz.py`` runs 10,000 cases
and counts the outcomes. Needs ``hypothesis`` (the ``test`` extra).
"""

from __future__ import annotations

import contextlib
import io
import signal
import string
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

from c2inet.errors import InputError

FAMILIES = ["crowd_noise", "crowd_radius", "crowd_density", "highway_density", "eth_ucy", "nope"]
SECONDS = 10  # a case taking longer counts as a hang


class Stop(Exception):
    """Raised by the stubs where the real command would start generating or training."""


# --- strategies ------------------------------------------------------------------------------
plain = st.one_of(
    st.decimals(0, 1, places=1).map(str),
    st.decimals(0, 1, places=2).map(str),
    st.sampled_from(["0.1", "0.2", "0.3", "0.6", "1", "2", "10"]),
)
numbers = st.one_of(
    plain,
    st.integers(-(10**6), 10**6).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.decimals(allow_nan=False, allow_infinity=False, places=3).map(str),
    st.sampled_from(["0.1", "0.6", "1e400", "-0", "1e-3000", "0." + "0" * 80 + "1", "nan"]),
    st.text(string.digits + ".-e", max_size=12),
)
values = st.one_of(
    plain,
    st.builds(lambda a, b: f"{a}..{b}", plain, plain),
    numbers,
    st.builds(lambda a, b: f"{a}..{b}", numbers, numbers),
    st.builds(lambda a, b, c: f"{a}..{b}:{c}", numbers, numbers, numbers),
    st.lists(numbers, min_size=1, max_size=4).map(",".join),
    st.sampled_from(["univ", "eth,hotel", "zara9", "", "0.1-0.6"]),
)
parts = st.builds(lambda f, v: f"{f}_{v}", st.sampled_from(FAMILIES), values)
scenarios = st.one_of(
    st.lists(
        st.builds(lambda f, v: f"{f}_{v}", st.sampled_from(["crowd_noise", "crowd_radius"]), plain),
        min_size=1,
        max_size=3,
    ).map("+".join),
    st.lists(parts, min_size=1, max_size=3).map("+".join),
    st.lists(parts, min_size=1, max_size=3).map(" + ".join),
    st.text(max_size=40),
)
option_keys = st.sampled_from(
    [
        "train.lr", "train.batch_scenes", "train.k_train", "train.epochs", "model.z_dim",
        "model.likelihood_std", "model.c_source", "model.backbone", "finetune.x", "ewc.strength",
        "ewc.gamma", "data.agents", "data.noise", "data.splits.train", "data.radius", "lr", "x.y",
    ]
)  # fmt: skip
option_values = st.one_of(numbers, st.sampled_from(["true", "false", "abc", "", "1.5", "-1"]))
settings = st.lists(
    st.one_of(
        st.builds(lambda k, v: f"{k}={v}", option_keys, option_values),
        st.text(max_size=20),
    ),
    max_size=3,
)
flags = st.sampled_from(
    [
        "--methods", "--epochs", "--seeds", "--k", "--seed", "--threads", "--jobs", "--workers",
        "--backend", "--logger", "--rerun", "--memory-budget", "--backbone", "--list",
    ]
)  # fmt: skip
flag_values = st.one_of(
    plain,
    st.builds(lambda a, b: f"{a}..{b}", plain, plain),
    numbers,
    st.sampled_from(
        ["finetune,cv", "all", "sgd", "ray", "csv", "spawnx", "connect=x", "methods", "knobs"]
    ),
)
argvs = st.builds(
    lambda scenario, pairs, sets: [
        *(["--scenario", scenario] if scenario is not None else []),
        *[x for pair in pairs for x in pair],
        *[x for s in sets for x in ("--set", s)],
    ],
    st.one_of(st.none(), scenarios),
    st.lists(st.tuples(flags, flag_values), max_size=3),
    settings,
)
token = st.one_of(numbers, st.text(string.printable, max_size=6))
rows = st.builds(
    lambda frame, agent, x, y: f"{frame * 10} {agent} {x} {y}",
    st.integers(0, 40),
    st.integers(1, 4),
    st.floats(-50, 50, allow_nan=False),
    st.floats(-50, 50, allow_nan=False),
)
data_files = st.one_of(
    st.lists(rows, max_size=60).map("\n".join),  # well-formed rows, frames in any order
    st.lists(st.one_of(rows, st.lists(token, max_size=6).map(" ".join)), max_size=12).map(
        "\n".join
    ),
    st.binary(max_size=64).map(lambda b: b.decode("latin-1")),
)
toml_values = st.one_of(
    plain,
    st.builds(lambda a, b: f"{a}..{b}", plain, plain),
    numbers,
    st.sampled_from(['"crowd"', '"files"', "true", "[1, 2]", "{a = 1}", '"x"', "[[[]]]"]),
)
knob_lines = st.lists(
    st.tuples(
        st.sampled_from(["agents", "radius", "noise", "frames", "layout", "speed", "density"]),
        st.one_of(plain, st.sampled_from(["2", "6", "20", '"corridor"', '"x"']), numbers),
    ),
    max_size=3,
    unique_by=lambda kv: kv[0],
)
family_files = st.one_of(
    st.builds(  # a crowd family, its knobs and splits drawn
        lambda knob, pairs, splits: (
            f'generator = "crowd"\nknob = "{knob}"\n[knobs]\n'
            + "".join(f"{k} = {v}\n" for k, v in pairs)
            + f"[splits]\ntrain = {splits[0]}\nval = {splits[1]}\ntest = {splits[2]}\n"
        ),
        st.sampled_from(["noise", "radius", "agents", "speed", "x"]),
        knob_lines,
        st.tuples(*[st.integers(-1, 12)] * 3),
    ),
    st.builds(
        lambda gen, knob, pairs, table: (
            f"generator = {gen}\nknob = {knob}\n"
            + "".join(f"{k} = {v}\n" for k, v in pairs)
            + f"[{table}]\n"
            + "".join(f"{k} = {v}\n" for k, v in pairs)
        ),
        toml_values,
        toml_values,
        st.lists(
            st.tuples(
                st.sampled_from(["agents", "radius", "noise", "train", "test", "frames", "zz"]),
                toml_values,
            ),
            max_size=3,
        ),
        st.sampled_from(["knobs", "splits", "values.a", "values", "other"]),
    ),
    st.text(max_size=60),
    st.integers(1, 400).map(lambda n: 'generator = "crowd"\nx = ' + "[" * n + "]" * n),
)


# --- targets -----------------------------------------------------------------------------------
def scenario_target(text: str) -> Any:
    from sim.scenario import parse_scenario

    return parse_scenario(text)


def settings_target(items: list[str]) -> Any:
    from sim.experiment import ExperimentConfig, parse_settings

    return ExperimentConfig("crowd_noise_0.1,0.2", quick=True, settings=parse_settings(items))


def _command(module: str, stubbed: str, argv: list[str]) -> int:
    """``module.main(argv)`` with ``stubbed`` (its work) replaced by a :class:`Stop`, in a fresh
    folder; its exit code, with bad input required to give one ``error:`` line."""
    import importlib
    from unittest import mock

    main = importlib.import_module(module).main
    err = io.StringIO()
    with (
        tempfile.TemporaryDirectory() as tmp,
        contextlib.chdir(tmp),
        mock.patch(stubbed, side_effect=Stop),
        contextlib.redirect_stdout(io.StringIO()),
        contextlib.redirect_stderr(err),
    ):
        try:
            code = main(argv)
        except SystemExit as exit_:  # argparse
            code = exit_.code
        except Stop:
            return 0
    lines = err.getvalue().strip().split("\n")
    if code == 2 and (len(lines) != 1 or not lines[0].startswith("error:")):
        raise AssertionError(f"exit 2 without exactly one error line: {lines}")
    if code == 2:
        raise InputError(lines[0])
    return code


def run_command_target(argv: list[str]) -> int:
    return _command("sim.run", "sim.experiment.runner.run_experiment", argv)


def generate_command_target(argv: list[str]) -> int:
    return _command("sim.generate", "sim.domains.build_domain", [*argv, "--out", "out"])


def data_file_target(text: str) -> Any:
    from sim.generators.files import read_trajectory_file

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scene.txt"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        return read_trajectory_file(path)


def family_file_target(text: str) -> Any:
    """The family file, loaded, and a scenario of its first value parsed (knobs checked)."""
    from sim.families import load_family
    from sim.scenario import parse_scenario

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzzed.toml"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        family = load_family(path)
        value = family.value_names[0] if family.value_names else "0.1"
        return parse_scenario(f"fuzzed_{value}", [Path(tmp)])


@dataclass(frozen=True)
class Target:
    name: str
    strategy: st.SearchStrategy
    run: Callable[[Any], Any]


TARGETS = [
    Target("scenario", scenarios, scenario_target),
    Target("--set", settings, settings_target),
    Target("sim.run", argvs, run_command_target),
    Target("sim.generate", argvs, generate_command_target),
    Target("data file", data_files, data_file_target),
    Target("family file", family_files, family_file_target),
]


class Hang(Exception):
    """A case ran past :data:`SECONDS`."""


def outcome(target: Target, case: Any) -> str:
    """``ok``, ``input error``, or raises: any other exception, or :class:`Hang`."""

    def alarm(*_):
        raise Hang(f"{target.name}: no answer in {SECONDS} s for {case!r:.200}")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(SECONDS)
    try:
        target.run(case)
        return "ok"
    except InputError:
        return "input error"
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
