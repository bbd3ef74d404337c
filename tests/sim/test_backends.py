"""The local backend's workers never outlive their driver (issue 26, item 4)."""

import os
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest

DRIVER = textwrap.dedent(
    """
    import os, sys, time
    from pathlib import Path
    from sim.experiment.backends import run_jobs

    def sleeper(job, folder):
        written = Path(folder) / f"{job}.tmp"  # renamed when whole: the test reads it at once
        written.write_text(str(os.getpid()))
        written.rename(Path(folder) / f"{job}.pid")
        time.sleep(120)

    if __name__ == "__main__":
        run_jobs(sleeper, [0, 1], (sys.argv[1],), processes=2)
    """
)


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    state = (
        Path(f"/proc/{pid}/stat").read_text().split()[2] if Path(f"/proc/{pid}").exists() else ""
    )
    return state != "Z"  # a zombie has ended


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGKILL])
def test_workers_die_with_their_driver(tmp_path, signum):
    """Within 30 s of their driver's end; a driver that can catch the signal also removes its
    temporary folder (one killed by SIGKILL cannot: its folder goes with the test's own)."""
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    # the driver's temporary folders, short: its fork server's socket lies there (108 bytes)
    with tempfile.TemporaryDirectory(prefix="c2i-test-") as temporary:
        driver = subprocess.Popen(
            [sys.executable, str(script), str(tmp_path)],
            cwd=tmp_path,
            env={**os.environ, "TMPDIR": temporary},
        )
        deadline = time.monotonic() + 120
        while len(list(tmp_path.glob("*.pid"))) < 2:  # both workers are in their jobs
            assert time.monotonic() < deadline and driver.poll() is None
            time.sleep(0.2)
        workers = [int(p.read_text()) for p in tmp_path.glob("*.pid")]
        driver.send_signal(signum)
        driver.wait(timeout=60)
        deadline = time.monotonic() + 30
        while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not any(alive(pid) for pid in workers)
        if signum != signal.SIGKILL:
            assert not list(Path(temporary).glob("c2i-jobs-*"))


@pytest.mark.parametrize(
    ("address", "message"),
    [
        ("garbage", "expected HOST:PORT"),
        ("", "expected HOST:PORT"),
        ("127.0.0.1:0", "expected HOST:PORT"),
        ("127.0.0.1:1", "nothing answers there"),
    ],
)
def test_a_bad_ray_address_is_refused_before_any_work(address, message):
    """Issue 26, item 8: these gave tracebacks after 10 to 42 s, or retried for 600 s."""
    from c2inet.errors import InputError
    from sim.experiment import Execution

    start = time.monotonic()
    with pytest.raises(InputError, match=message):
        Execution(backend="ray", ray_address=address)
    assert time.monotonic() - start < 10


def test_a_listening_address_is_accepted():
    import socket

    from sim.experiment.backends import check_ray_address

    with socket.create_server(("127.0.0.1", 0)) as server:
        check_ray_address(f"127.0.0.1:{server.getsockname()[1]}")


UNGUARDED = textwrap.dedent(
    """
    from sim.experiment.backends import run_jobs

    def double(job):
        return 2 * job

    print(run_jobs(double, [1, 2], processes=2))  # no __main__ guard: every worker reruns this
    """
)


@pytest.mark.parametrize("how", ["stdin", "unguarded file"])
def test_a_driver_whose_workers_cannot_start_stops_with_one_line(tmp_path, how):
    """Issue 26, item 5: a script on standard input hung for over 10 minutes after its workers
    died, and a script without the ``__main__`` idiom printed multiprocessing's error and hung."""
    script = tmp_path / "driver.py"
    script.write_text(UNGUARDED)
    command = [sys.executable, "-"] if how == "stdin" else [sys.executable, str(script)]
    done = subprocess.run(
        command,
        input=UNGUARDED if how == "stdin" else None,
        capture_output=True,
        text=True,
        timeout=120,  # a hang fails here
        cwd=tmp_path,
    )
    assert done.returncode != 0
    expected = "is not a file" if how == "stdin" else "could not start"
    # the unguarded workers' own pools leak semaphores, which multiprocessing's resource tracker
    # (a process of its own) may report after the driver's last line: seen once in CI
    lines = [line for line in done.stderr.splitlines() if "resource_tracker" not in line]
    assert expected in lines[-1]


def note_start(job: int, folder: str) -> int:
    """A job that notes when it started, then takes a moment."""
    (Path(folder) / f"{job}.start").write_text(str(time.monotonic()))
    time.sleep(0.5)
    return 10 * job


def test_the_longest_jobs_start_first_and_results_keep_the_jobs_order(tmp_path):
    from sim.experiment.backends import run_jobs

    cost = {0: 1.0, 1: 5.0, 2: 2.0, 3: 9.0}  # seconds a job is expected to take
    results = run_jobs(
        note_start, [0, 1, 2, 3], (str(tmp_path),), "local", 2, cost_of=cost.__getitem__
    )
    assert results == [0, 10, 20, 30]
    started = sorted(cost, key=lambda job: float((tmp_path / f"{job}.start").read_text()))
    assert set(started[:2]) == {3, 1} and set(started[2:]) == {2, 0}


def worker_pid(job: int) -> int:
    time.sleep(0.5)  # long enough that both workers take a job
    return os.getpid()


def failing(job: int) -> None:
    raise ValueError(f"job {job} failed")


def test_kept_workers_serve_every_batch_until_one_fails():
    """Inside ``kept_workers`` the workers start once (a benchmark's tuning rounds would each
    pay their imports) and stop with a batch that fails; outside it, each batch has its own."""
    from sim.experiment.backends import kept_workers, run_jobs

    with kept_workers():
        first = set(run_jobs(worker_pid, [0, 1, 2, 3], processes=2))
        again = set(run_jobs(worker_pid, [0, 1, 2, 3], processes=2))
        assert len(first) == 2 and again == first
        with pytest.raises(ValueError, match="failed"):
            run_jobs(failing, [0, 1], processes=2)
        assert not any(alive(pid) for pid in first)
        kept = set(run_jobs(worker_pid, [0, 1], processes=2))
        assert not kept & first
    assert not any(alive(pid) for pid in kept)  # stopped at the block's end
    alone = set(run_jobs(worker_pid, [0, 1], processes=2))
    assert not any(alive(pid) for pid in alone) and not alone & kept


def preloaded(job: int) -> tuple[bool, int]:
    """Whether this worker had torch._dynamo before its job (nothing the job's own imports
    bring: only the optimiser imports it), and the worker's parent."""
    return "torch._dynamo" in sys.modules, os.getppid()


def test_workers_fork_from_a_server_that_imported_torch_once():
    """Workers do not each import torch and torch._dynamo (4 to 5 CPU-s a worker): they fork
    from Python's fork server, which imported them, so their parent is not the driver."""
    from sim.experiment.backends import run_jobs

    results = run_jobs(preloaded, [0, 1], processes=2)
    assert all(loaded for loaded, _ in results)
    assert all(parent != os.getpid() for _, parent in results)


def placement(job: int) -> tuple[int, str]:
    """This worker's pid and the CUDA device a job of it on `cuda` takes on a 2-GPU machine."""
    import time

    import torch

    from c2inet.device import placed

    time.sleep(0.3)  # both workers take a job
    return os.getpid(), str(placed(torch.device("cuda"), count=2))


def test_jobs_on_cuda_spread_over_the_devices_by_worker_slot():
    """Each local worker takes its own slot, so `--jobs 2 --device cuda` on two GPUs puts one
    worker's jobs on cuda:0 and the other's on cuda:1; a named index is kept; one GPU is
    `cuda`."""
    import torch

    from c2inet.device import placed
    from sim.experiment.backends import run_jobs

    results = run_jobs(placement, [0, 1, 2, 3], processes=2)
    by_worker = {pid: {device for p, device in results if p == pid} for pid, _ in results}
    assert sorted(set().union(*by_worker.values())) == ["cuda:0", "cuda:1"]
    assert all(len(devices) == 1 for devices in by_worker.values())  # a worker keeps its GPU
    assert placed(torch.device("cuda", 1), count=4) == torch.device("cuda", 1)
    assert placed(torch.device("cuda"), count=1) == torch.device("cuda")
    assert placed(torch.device("cpu"), count=4) == torch.device("cpu")


def namespace() -> int:
    return os.stat("/proc/thread-self/ns/net").st_ino


@pytest.mark.skipif(os.geteuid() != 0, reason="a network namespace needs root here")
def test_a_local_ray_cluster_starts_in_a_network_namespace_holding_only_the_loopback():
    """Issue 64: what starts inside ``private_network`` (Ray's servers, which bind every
    interface) sees one interface, the loopback, up; the thread returns to its own namespace;
    work that needs the machine's network runs outside it, with one warning."""
    from sim.experiment import netns

    before = namespace()
    with netns.private_network() as private:
        inside = namespace()
        child = subprocess.run(
            [sys.executable, "-c", "import socket; print([n for _, n in socket.if_nameindex()])"],
            capture_output=True,
            text=True,
            check=True,
        )
        with socket.create_server(("127.0.0.1", 0)) as server:  # the loopback is up
            socket.create_connection(server.getsockname(), timeout=2).close()
    assert private and inside != before and namespace() == before
    assert child.stdout.strip() == "['lo']"
    with netns.private_network("its jobs stream to a viewer") as private:
        assert not private and namespace() == before
    from sim.experiment.backends import _needs_network

    assert _needs_network({"loggers": ("csv", "mlflow")}) is None  # files: the namespace is fine
    assert "http://127.0.0.1:5000" in _needs_network({"loggers": ("mlflow=http://127.0.0.1:5000",)})
    assert _needs_network({"loggers": ("wandb=online",)}) and _needs_network({"live": "connect"})
