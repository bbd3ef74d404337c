"""The project's own fuzzing: generated inputs for every way a user hands the project something,
each answered with a result or the project's one error (``InputError``, exit code 2), never
another exception and never a hang.

Each target pairs a Hypothesis strategy of inputs with a function that feeds one input to the
project: the scenario parser, ``--set`` options, the ``sim.run`` and ``sim.generate`` command
lines (in-process, stopped before anything is generated), ETH-UCY, SDD and TrajNet++ data files,
family files, ``--config`` files (TOML and a run's ``config.json``) and a benchmark's tuning
storage.
``tests/sim/test_fuzz.py`` runs every target in CI; ``benchmarks/fuzz.py`` runs 10,000 cases
and counts the outcomes. Test machinery: it lives beside the tests, out of the package, and
needs ``hypothesis`` (the ``test`` extra).
"""

from __future__ import annotations

import atexit
import contextlib
import io
import re
import shutil
import signal
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fuzz_inputs import (
    argvs,
    config_files,
    data_files,
    family_files,
    run_damages,
    scenarios,
    sdd_files,
    settings,
    trajnet_files,
    tuning_storages,
)
from hypothesis import strategies as st

from c2inet.errors import InputError

SECONDS = 10  # CPU seconds: a case computing longer counts as a hang
WALL_SECONDS = 180  # a case blocked this long (a FIFO read, say) counts as one: generous, since
# a loaded machine (another test suite beside this one) stretches wall time many times


class Stop(Exception):
    """Raised by the stubs where the real command would start generating or training."""


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


# a progress bar's line in a log, or a domain's line as the curriculum is prepared: not a message
PROGRESS = re.compile(r"^([\w ]+:\s+\d+%\||domain \d+/\d+ )")


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


def _read_as(text: str, name: str, read: Callable[[Path], Any]) -> Any:
    """``read`` a file called ``name`` holding ``text`` (undecodable bytes kept as written)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / name
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        return read(path)


def data_file_target(text: str) -> Any:
    from sim.generators.files import read_trajectory_file

    return _read_as(text, "scene.txt", read_trajectory_file)


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

    def read(path: Path) -> Any:
        return read_trajectory_file(path, format="sdd", scale=0.03, every=12)

    return _read_as(text, "annotations.txt", read)


def trajnet_file_target(text: str) -> Any:
    from sim.generators.formats import trajnet_scenes

    return _read_as(text, "scenes.ndjson", trajnet_scenes)


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


_RUNS: dict[str, Path] = {}  # finished quick runs, made once a process: the cases copy them


def _finished_run(name: str, scenario: str) -> Path:
    """A finished quick run of fine-tuning on ``scenario`` (made on first use)."""
    if name not in _RUNS:
        from sim.run import main

        root = Path(tempfile.mkdtemp(prefix="c2i-fuzz-"))
        atexit.register(shutil.rmtree, root, True)  # the process's own runs, gone with it
        argv = ["--scenario", scenario, "--methods", "finetune", "--quick", "--no-record"]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            if main([*argv, "--out", str(root / name), "--cache", str(root / "cache")]) != 0:
                raise RuntimeError(f"the fuzz suite's own run {scenario} failed")
        _RUNS[name] = root / name
    return _RUNS[name]


def _damage(path: Path, how: str, other: Path) -> None:

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
    """A case ran past :data:`SECONDS` of CPU time or :data:`WALL_SECONDS` of wall time."""


def outcome(target: Target, case: Any) -> str:
    """``ok``, ``input error``, or raises: any other exception, or :class:`Hang`."""

    def alarm(*_):
        raise Hang(
            f"{target.name}: no answer in {SECONDS} CPU s or {WALL_SECONDS} s for {case!r:.200}"
        )

    previous = {sig: signal.signal(sig, alarm) for sig in (signal.SIGALRM, signal.SIGPROF)}
    signal.setitimer(signal.ITIMER_PROF, SECONDS)  # the process's CPU time, not the wall's
    signal.alarm(WALL_SECONDS)
    try:
        target.run(case)
        return "ok"
    except InputError:
        return "input error"
    finally:
        signal.alarm(0)
        signal.setitimer(signal.ITIMER_PROF, 0)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
