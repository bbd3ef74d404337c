"""Every test, and every process a test starts, keeps its configuration and caches out of the
user's home folder (Rerun's analytics settings, matplotlib's cache; Ray's token: see its test),
and trains on one torch thread: with tests in parallel (``make test``), torch's default of one
thread per core made training several times slower (the project's rule for runs, too)."""

import fcntl
import importlib.util
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest
import torch

os.environ.setdefault("OMP_NUM_THREADS", "1")  # the processes tests start
torch.set_num_threads(1)


@pytest.fixture(scope="session", autouse=True)
def private_home(tmp_path_factory):
    home = tmp_path_factory.mktemp("home")
    before = {k: os.environ.get(k) for k in ("XDG_CONFIG_HOME", "MPLCONFIGDIR")}
    os.environ["XDG_CONFIG_HOME"] = str(home / "config")
    os.environ["MPLCONFIGDIR"] = str(home / "matplotlib")
    yield home
    for key, value in before.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope="session")
def made_once(tmp_path_factory) -> Callable[[str, Callable[[Path], None]], Path]:
    """``made_once(name, make)``: a folder that ``make`` fills once per test session, however
    many test workers ask for it; the first builds it under a lock, the others wait for it. (A
    module fixture is set up again each time work stealing brings its module back to a
    worker: three times, seen.)"""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base  # this session's

    def folder_made_once(name: str, make: Callable[[Path], None]) -> Path:
        folder, done = root / name, root / f"{name}.done"
        with open(root / f"{name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not done.exists():
                shutil.rmtree(folder, ignore_errors=True)  # a worker that failed half-way
                folder.mkdir()
                make(folder)
                done.touch()
        return folder

    return folder_made_once


ROOT = Path(__file__).resolve().parents[1]


def load_script(relative: str) -> ModuleType:
    """A script of the repository (``benchmarks/``, ``scripts/``: not a package) as a module."""
    path = ROOT / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def script() -> Callable[[str], ModuleType]:
    """``script("benchmarks/tuning_noise.py")``: that script as a module."""
    return load_script
