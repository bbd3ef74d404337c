"""The project's own fuzzing: generated inputs for every way a user hands the project something,
each answered with a result or the project's one error (``InputError``, exit code 2), never
another exception and never a hang.

Each target pairs a Hypothesis strategy of inputs with a function that feeds one input to the
project: the scenario parser, ``--set`` options, the ``sim.run`` and ``sim.generate`` command
lines (in-process, stopped before anything is generated), ETH-UCY, SDD and TrajNet++ data files,
family files, ``--config`` files (TOML and a run's ``config.json``) and a benchmark's tuning
storage.
``tests/sim/test_fuzz.py`` runs every target in CI; ``benchmarks/fuzz.py`` runs 10,000 cases
and counts the outcomes. Needs ``hypothesis`` (the ``test`` extra).
"""

from __future__ import annotations

import contextlib
import io
import re
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


sdd_rows = st.builds(  # raw SDD annotations: track, box, frame, lost, occluded, generated, label
    lambda track, box, frame, flags, label: (
        f"{track} {box[0]} {box[1]} {box[0] + box[2]} {box[1] + box[3]} {frame} "
        f'{flags[0]} {flags[1]} {flags[2]} "{label}"'
    ),
    st.integers(0, 3),
    st.tuples(*[st.integers(0, 2000)] * 4),
    st.integers(0, 60).map(lambda f: f * 12),
    st.tuples(*[st.integers(0, 1)] * 3),
    st.sampled_from(["Pedestrian", "Biker", "Car", "x"]),
)
sdd_files = st.one_of(
    st.lists(sdd_rows, max_size=60).map("\n".join),
    st.lists(st.one_of(sdd_rows, st.lists(token, max_size=10).map(" ".join)), max_size=12).map(
        "\n".join
    ),
    st.binary(max_size=64).map(lambda b: b.decode("latin-1")),
)
json_numbers = st.one_of(
    st.integers(-5, 60),
    st.floats(-50, 50, allow_nan=False),
    st.sampled_from(["Infinity", "NaN", "1e309", "1" * 320, "0.5", '"3"', "null", "1e8"]),
)
trajnet_lines = st.one_of(
    st.builds(
        lambda i, p, s, e: f'{{"scene": {{"id": {i}, "p": {p}, "s": {s}, "e": {e}, "fps": 2.5}}}}',
        json_numbers,
        json_numbers,
        json_numbers,
        json_numbers,
    ),
    st.builds(
        lambda f, p, x, y: f'{{"track": {{"f": {f}, "p": {p}, "x": {x}, "y": {y}}}}}',
        json_numbers,
        json_numbers,
        json_numbers,
        json_numbers,
    ),
    st.text(max_size=20),
)
trajnet_scene = st.builds(  # a well-formed file: one scene, its agents on every frame
    lambda agents, frames, dx: "\n".join(
        [f'{{"scene": {{"id": 0, "p": 1, "s": 0, "e": {frames - 1}, "fps": 2.5}}}}']
        + [
            f'{{"track": {{"f": {f}, "p": {a}, "x": {a + f * dx}, "y": {a}}}}}'
            for f in range(frames)
            for a in range(1, agents + 1)
        ]
    ),
    st.integers(1, 4),
    st.integers(1, 30),
    st.floats(-1, 1, allow_nan=False),
)
trajnet_files = st.one_of(
    trajnet_scene,
    st.builds(lambda good, bad: good + "\n" + bad, trajnet_scene, trajnet_lines),
    st.lists(trajnet_lines, max_size=40).map("\n".join),
    st.binary(max_size=64).map(lambda b: b.decode("latin-1")),
)
config_keys = st.sampled_from(
    [
        "scenario", "methods", "seed", "seeds", "epochs", "k", "backbone", "quick", "record",
        "jobs", "threads", "workers", "cache", "loggers", "device", "memory_budget", "nope",
    ]
)  # fmt: skip
config_values = st.one_of(
    toml_values,
    st.sampled_from(['"crowd_noise_0.1,0.2"', '"finetune,cv"', '["finetune"]', "2", '"2"', "0"]),
)
tuning_storages = st.one_of(
    st.binary(max_size=200),
    st.just(b"SQLite format 3\x00"),  # a header and nothing behind it
    st.binary(max_size=100).map(lambda b: b"SQLite format 3\x00" + b),
)
config_files = st.one_of(
    st.builds(  # TOML: options, then --set tables
        lambda pairs, sets: (
            "".join(f"{k} = {v}\n" for k, v in pairs)
            + "".join(f"[settings.{scope}]\n{key} = {value}\n" for scope, key, value in sets)
        ),
        st.lists(st.tuples(config_keys, config_values), max_size=5, unique_by=lambda kv: kv[0]),
        st.lists(
            st.tuples(
                st.sampled_from(["train", "model", "data", "finetune", "x"]),
                st.sampled_from(["lr", "batch_scenes", "z_dim", "splits", "agents", "y"]),
                config_values,
            ),
            max_size=2,
            unique_by=lambda t: t[0],
        ),
    ),
    st.builds(  # a run's config.json, its tables drawn
        lambda experiment, execution: f'{{"experiment": {experiment}, "execution": {execution}}}',
        st.sampled_from(['{"scenario": "crowd_noise_0.1"}', "[]", "{}", "1", '{"seeds": "x"}']),
        st.sampled_from(['{"jobs": 2}', '{"cache": "/"}', "null", "[]", '{"loggers": ["csv"]}']),
    ).map(lambda text: "JSON:" + text),
    st.text(max_size=60),
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
    return _exit(code, err.getvalue())


PROGRESS = re.compile(r"^[\w ]+:\s+\d+%\|")  # a progress bar's line in a log, not a message


def _exit(code: int, stderr: str) -> int:
    """A command's exit code, bad input required to say exactly one ``error:`` line (progress
    lines aside): raised as the :class:`InputError` it stands for."""
    lines = [line for line in stderr.strip().split("\n") if not PROGRESS.match(line)]
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


def sdd_file_target(text: str) -> Any:
    from sim.generators.files import read_trajectory_file

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "annotations.txt"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        return read_trajectory_file(path, format="sdd", scale=0.03, every=12)


def trajnet_file_target(text: str) -> Any:
    from sim.generators.formats import trajnet_scenes

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scenes.ndjson"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        return trajnet_scenes(path)


def config_file_target(text: str) -> int:
    """``sim.run --config FILE`` (TOML, or JSON for a text marked ``JSON:``), stopped before it
    would run: the file's options reach the parser as strictly as flags."""
    suffix, text = (".json", text[5:]) if text.startswith("JSON:") else (".toml", text)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"config{suffix}"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        return run_command_target(["--config", str(path)])


def tuning_storage_target(data: bytes) -> Any:
    """A benchmark's own ``tuning.db`` replaced by these bytes, then its tuning resumed: it
    reaches its first trial, or refuses the store in one line."""
    from unittest import mock

    from sim.experiment import ExperimentConfig
    from sim.experiment.tuning import TuneConfig, run_tuning

    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("finetune",), quick=True, record=False)
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "tuning.db").write_bytes(data)
        with mock.patch("sim.experiment.tuning.plan", side_effect=Stop):
            try:
                return run_tuning(TuneConfig(base, trials=1), Path(tmp))
            except Stop:
                return None


DAMAGES = ("truncated", "emptied", "garbage", "a folder", "another run's", "deleted")
run_damages = st.tuples(st.integers(0, 10**6), st.sampled_from(DAMAGES), st.booleans())
_RUNS: dict[str, Path] = {}  # finished quick runs, made once a process: the cases copy them


def _finished_run(name: str, scenario: str) -> Path:
    """A finished quick run of fine-tuning on ``scenario`` (made on first use)."""
    if name not in _RUNS:
        from sim.run import main

        root = Path(tempfile.mkdtemp(prefix="c2i-fuzz-"))
        argv = ["--scenario", scenario, "--methods", "finetune", "--quick", "--no-record"]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            if main([*argv, "--out", str(root / name), "--cache", str(root / "cache")]) != 0:
                raise RuntimeError(f"the fuzz suite's own run {scenario} failed")
        _RUNS[name] = root / name
    return _RUNS[name]


def _damage(path: Path, how: str, other: Path) -> None:
    import shutil

    data = path.read_bytes()
    if how == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif how == "emptied":
        path.write_bytes(b"")
    elif how == "garbage":
        path.write_bytes(bytes(range(256)) * 3)
    elif how == "a folder":
        path.unlink()
        path.mkdir()
    elif how == "another run's" and other.is_file():
        shutil.copyfile(other, path)
    else:
        path.unlink()


def run_folder_target(case: tuple[int, str, bool]) -> int:
    """A finished run (or, ``interrupted``, one killed after its first task) with one of its
    files damaged, then ``sim.run --resume``: it finishes, or refuses in one line."""
    import shutil

    from sim.run import main

    index, how, interrupted = case
    scenario = "crowd_noise_0.1,0.2"
    mine, theirs = _finished_run("a", scenario), _finished_run("b", "crowd_noise_0.1,0.3")
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        shutil.copytree(mine, run)
        if interrupted:  # killed during the second task: its result and checkpoint never written
            job = run / "jobs" / "finetune" / "seed_0"
            (job / "result.json").unlink()
            (job / "checkpoints" / "task_01.pt").unlink()
        files = sorted(p for p in run.rglob("*") if p.is_file())
        target = files[index % len(files)]
        _damage(target, how, theirs / target.relative_to(run))
        err = io.StringIO()
        argv = ["--scenario", scenario, "--methods", "finetune", "--quick", "--no-record"]
        argv += ["--resume", "--out", str(run), "--cache", str(mine.parent / "cache")]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            code = main(argv)
    if code not in (0, 2):
        raise AssertionError(f"exit {code}: {err.getvalue()[-300:]}")
    return _exit(code, err.getvalue())


@dataclass(frozen=True)
class Target:
    name: str
    strategy: st.SearchStrategy
    run: Callable[[Any], Any]
    examples: int = 150  # the cases CI draws (``benchmarks/fuzz.py`` draws its own number)


TARGETS = [
    Target("scenario", scenarios, scenario_target),
    Target("--set", settings, settings_target),
    Target("sim.run", argvs, run_command_target),
    Target("sim.generate", argvs, generate_command_target),
    Target("data file", data_files, data_file_target),
    Target("family file", family_files, family_file_target),
    Target("SDD file", sdd_files, sdd_file_target),
    Target("TrajNet++ file", trajnet_files, trajnet_file_target),
    Target("config file", config_files, config_file_target),
    Target("tuning storage", tuning_storages, tuning_storage_target, examples=50),
    Target("run folder", run_damages, run_folder_target, examples=12),  # a resume each: 1 s
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
