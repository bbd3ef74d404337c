"""Every test, and every process a test starts, keeps its configuration and caches out of the
user's home folder (Rerun's analytics settings, matplotlib's cache; Ray's token: see its test),
and trains on one torch thread: with tests in parallel (``make test``), torch's default of one
thread per core made training several times slower (the project's rule for runs, too)."""

import os

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
