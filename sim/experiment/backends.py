"""Where an experiment's jobs run: in this process, in local processes, or as Ray tasks.

Every backend calls the same ``fn(job, *shared, **options)`` once per job and returns the
results in the jobs' order, so the numbers never depend on the backend or the number of workers.
Ray is an optional extra (``pip install '.[ray]'``), imported only when asked for.
"""

from __future__ import annotations

import ast
import inspect
import multiprocessing
import os
import pickle
import select
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from c2inet.errors import InputError, WorkerDied, quote
from sim.experiment.netns import private_network

BACKENDS = ("local", "ray")

# a local worker's slot, read by c2inet.device.placed (named here too: importing that module
# loads torch, which a command's --help must not)
WORKER_SLOT = "C2I_WORKER_SLOT"
_shared: tuple[str, tuple] = ("", ())  # a local worker's shared inputs: their file, its contents
_pool: ProcessPoolExecutor | None = None  # this driver's local workers, between batches if kept
_kept = 0  # how many kept_workers() blocks are open


# Local workers fork from Python's fork server, which imports these once, rather than each
# starting a fresh Python that imports torch anew (4 to 5 CPU-s a worker). The server runs
# nothing, so it forks with no torch thread pool; Rerun is never among them, since its threads
# would not survive the fork.
PRELOAD = ["torch", "torch._dynamo", "c2inet.trainer"]


def _watch_driver(driver: int) -> None:
    """Kill this worker the moment the driver ends, however it ends (SIGKILL, out of memory): a
    thread waits on the driver's process file descriptor (Linux), else polls it each second
    (POSIX; on Windows, where ``os.kill`` terminates, nothing is watched)."""
    if os.name != "posix":
        return
    try:
        handle = os.pidfd_open(driver) if hasattr(os, "pidfd_open") else None
        os.kill(driver, 0)
    except ProcessLookupError:
        os._exit(1)  # the driver died before this worker started

    def watch() -> None:
        if handle is not None:
            select.select([handle], [], [])
        else:
            while _alive(driver):
                time.sleep(1.0)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="watch-driver", daemon=True).start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def _start_worker(driver: int, slots) -> None:
    """A local worker ignores Ctrl-C (the driver stops it), dies with the driver, and takes the
    next worker slot (which of several GPUs its jobs use: ``c2inet.device.placed``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _watch_driver(driver)
    with slots.get_lock():
        os.environ[WORKER_SLOT] = str(slots.value)
        slots.value += 1


def _exit_on(signum, _frame) -> None:
    raise SystemExit(128 + signum)


class _StopOnTermination:
    """While a pool runs, SIGTERM and SIGHUP end the driver through its ``finally`` (which stops
    the workers) instead of killing it on the spot."""

    SIGNALS = (signal.SIGTERM, signal.SIGHUP)

    def __enter__(self):
        self.previous = {}
        if threading.current_thread() is threading.main_thread():
            self.previous = {s: signal.signal(s, _exit_on) for s in self.SIGNALS}

    def __exit__(self, *_):
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)


def _call_in_worker(call: tuple[Callable, Any, dict, str]) -> Any:
    """One job in a local worker; the call's shared inputs are read from the driver's file
    ``shared`` by the first of its jobs that this worker runs."""
    global _shared
    fn, job, options, shared = call
    if _shared[0] != shared:
        with open(shared, "rb") as file:
            _shared = (shared, pickle.load(file))  # written by this run's driver a moment ago
    return fn(job, *_shared[1], **options)


def run_jobs(
    fn: Callable[..., Any],
    jobs: Sequence[Any],
    shared: tuple = (),
    backend: str = "local",
    processes: int = 1,
    ray_address: str | None = None,
    options: dict[str, Any] | None = None,
    progress: Callable[[str, dict], Any] | None = None,
    tasks_of: Callable[[Any], int] = lambda _job: 1,
    cost_of: Callable[[Any], float] = lambda _job: 0.0,
) -> list[Any]:
    """``[fn(job, *shared, **options) for job in jobs]`` on ``backend``.

    ``progress(event, data)`` follows the work: jobs run in this process pass it every trainer
    event (``fn`` receives it as ``on_event``); a job that finishes elsewhere sends
    ``("job_end", {"tasks": tasks_of(job)})``. Workers take the jobs longest first by
    ``cost_of(job)`` (ties in the given order), so no long job is left to run alone at the end;
    the results come back in the jobs' order.
    """
    options = options or {}
    progress = progress or (lambda _event, _data: None)
    order = sorted(range(len(jobs)), key=lambda i: -cost_of(jobs[i]))
    if backend == "ray":
        return _run_on_ray(
            fn, jobs, order, shared, processes, ray_address, options, progress, tasks_of
        )
    if processes <= 1 or len(jobs) <= 1:
        return [fn(job, *shared, **options, on_event=progress) for job in jobs]
    check_importable_main()
    with tempfile.TemporaryDirectory(prefix="c2i-jobs-") as folder, _StopOnTermination():
        # the shared inputs go through a file, not the workers' start-up pipe: a start-up
        # message larger than the pipe holds blocks the driver until that worker has imported
        # the project, so the workers would start one after another
        path = Path(folder) / "shared.pickle"
        path.write_bytes(pickle.dumps(shared, protocol=pickle.HIGHEST_PROTOCOL))
        calls = [(fn, job, options, str(path)) for job in jobs]
        try:
            results = _run_in_pool(_workers(processes), calls, order, progress, tasks_of, jobs)
        except BaseException:  # an error, Ctrl-C, SIGTERM: no worker outlives the batch
            _stop_workers()
            raise
        if not _kept:
            _stop_workers()
        return results


@contextmanager
def kept_workers() -> Iterator[None]:
    """Within this block the local workers serve every batch of jobs (a benchmark's tuning
    rounds and its evaluation start them, and import the project, once); they stop at its end,
    or with a batch that fails."""
    global _kept
    _kept += 1
    try:
        yield
    finally:
        _kept -= 1
        if not _kept:
            _stop_workers()


def _workers(processes: int) -> ProcessPoolExecutor:
    """The driver's pool of ``processes`` local workers: the kept one, else a new one."""
    global _pool
    if _pool is not None and _pool._max_workers != processes:  # no public way to ask
        _stop_workers()
    if _pool is None:
        # torch and a plain fork do not mix; Windows has no fork server, only spawn
        forkserver = "forkserver" in multiprocessing.get_all_start_methods()
        context = multiprocessing.get_context("forkserver" if forkserver else "spawn")
        if forkserver:
            context.set_forkserver_preload(PRELOAD)
        slots = context.Value("i", 0)
        _pool = ProcessPoolExecutor(processes, context, _start_worker, (os.getpid(), slots))
    return _pool


def _stop_workers() -> None:
    global _pool
    if _pool is not None:
        for process in list(_pool._processes.values()):  # the executor offers no public way
            process.terminate()
        _pool.shutdown(wait=True, cancel_futures=True)
        _pool = None


def check_importable_main() -> None:
    """Local workers start by importing the driver's main module again; one read from standard
    input (``python - < script.py``) cannot be, and its workers would die at start-up."""
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    if path is not None and not Path(path).is_file():
        raise InputError(
            f"jobs > 1: the main program {path!r} is not a file, so worker processes cannot "
            "start; save it to a file and run that, or use one job"
        )


def check_guarded_main(jobs: int) -> None:
    """Refuse, before any folder or worker, parallel jobs started by a script's top level
    outside ``if __name__ == "__main__":``: every worker process imports the script again, so
    each would start the whole experiment anew (stray run folders, dying workers)."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if jobs <= 1 or path is None or not Path(path).is_file():
        return
    lines = [f.lineno for f in inspect.stack(0) if f.filename == path and f.function == "<module>"]
    if not lines:
        return
    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError):
        return
    guarded = [
        (node.lineno, node.end_lineno)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and "__main__" in ast.unparse(node.test)
    ]
    line = lines[-1]
    if not any(first <= line <= last for first, last in guarded):
        raise InputError(
            f"{Path(path).name}:{line}: jobs > 1 starts worker processes that import this script "
            'again; put the call under if __name__ == "__main__": (or run one job)'
        )


def _run_in_pool(pool, calls, order, progress, tasks_of, jobs) -> list[Any]:
    """The calls on the local pool, submitted in ``order``; results in the calls' order."""
    futures = {pool.submit(_call_in_worker, calls[i]): i for i in order}
    results: dict[int, Any] = {}
    for future in as_completed(futures):
        index = futures[future]
        try:
            results[index] = future.result()
        except BrokenProcessPool:
            raise WorkerDied(
                "a job process died: killed, out of memory, or it could not start (a script "
                "that runs jobs > 1 must be a file whose work sits under "
                '`if __name__ == "__main__":`, since each worker imports it again); '
                "finished jobs are kept: add --resume to continue"
            ) from None
        progress("job_end", {"tasks": tasks_of(jobs[index])})
    return [results[i] for i in range(len(calls))]


def check_ray_address(address: str, seconds: float = 5.0) -> None:
    """Refuse, in one line and before any work, a Ray address that is malformed or where
    nothing answers: ``HOST:PORT`` or ``ray://HOST:PORT`` (a TCP connection is tried), or
    ``auto`` (a cluster started on this machine by ``ray start``)."""
    where = f"--ray-address {quote(address, 40)}"
    if address == "auto":
        if not (os.environ.get("RAY_ADDRESS") or Path("/tmp/ray/ray_current_cluster").exists()):
            raise InputError(f"{where}: no Ray cluster runs on this machine (start one: ray start)")
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError(f"{where}: expected HOST:PORT, ray://HOST:PORT or auto")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=seconds).close()
    except OSError as error:
        raise InputError(f"{where}: nothing answers there ({error.strerror or error})") from None


def _run_on_ray(fn, jobs, order, shared, processes, address, options, progress, tasks_of):
    """One Ray task per job with one CPU; the shared inputs go to the object store once."""
    try:
        import ray
    except ImportError:
        raise InputError("--backend ray: Ray is not installed (pip install '.[ray]')") from None
    if address is not None:
        _join(ray, address)
        return _ray_jobs(ray, fn, jobs, order, shared, processes, options, progress, tasks_of)
    with private_network(_needs_network(options)) as private:
        ray.init(
            num_cpus=processes,
            include_dashboard=False,
            log_to_driver=False,
            _node_ip_address="127.0.0.1" if private else None,
        )
        return _ray_jobs(ray, fn, jobs, order, shared, processes, options, progress, tasks_of)


def _join(ray, address: str) -> None:
    """Connect to the cluster at ``address``; a refusal (a cluster with token authentication
    and no or another token here, or one that went away) is one line, and Ray's own retries
    say nothing (its C++ client writes each one to standard error, which is held meanwhile)."""
    held = os.dup(2)
    try:
        with open(os.devnull, "wb") as void:
            os.dup2(void.fileno(), 2)
            ray.init(address=address, log_to_driver=False)
    except ConnectionError:
        raise InputError(
            f"--ray-address {quote(address, 40)}: the cluster there refused this driver (with "
            "token authentication on, set RAY_AUTH_MODE=token and RAY_AUTH_TOKEN_PATH to the "
            "cluster's token file), or it stopped"
        ) from None
    finally:
        os.dup2(held, 2)
        os.close(held)


def _needs_network(options: dict[str, Any]) -> str | None:
    """Why a local cluster's jobs need this machine's network (a live viewer, a tracking
    server), or None."""
    if options.get("live"):
        return "its jobs stream to a viewer"
    for logger in options.get("loggers") or ():  # mlflow=URI, wandb=online (viz.loggers)
        target = logger.partition("=")[2]
        if target.startswith(("http:", "https:")) or target == "online":
            return f"its jobs log to {target}"
    return None


def _ray_jobs(ray, fn, jobs, order, shared, processes, options, progress, tasks_of):
    """The jobs as Ray tasks on the cluster ``ray`` is connected to; Ray shut down after."""
    try:
        refs = [ray.put(item) for item in shared]
        # where the cluster has GPUs, each job a share of them (all --jobs fit at once): Ray
        # shows a task only its own GPU, which a job on `cuda` then takes
        gpus = ray.cluster_resources().get("GPU", 0)
        remote = ray.remote(num_cpus=1, num_gpus=min(1.0, gpus / processes) if gpus else 0)(fn)
        pending = {remote.remote(jobs[i], *refs, **options): i for i in order}
        results: dict[int, Any] = {}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                index = pending.pop(ref)
                results[index] = ray.get(ref)
                progress("job_end", {"tasks": tasks_of(jobs[index])})
        return [results[i] for i in range(len(jobs))]
    finally:
        ray.shutdown()
