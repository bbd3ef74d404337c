"""The independent pieces of a study that trains in its own loop (one method and seed through a
stream, one model trained on one domain), run as the engine's jobs.

A cell is a name (a file stem) and the arguments of one call. :func:`run_cells` runs the cells
at once on the execution's backend; each one's result is kept in ``cells/NAME.json`` the moment
it ends, with the identity of everything it depends on, so ``--resume`` reruns only what is
missing and never mixes in a cell of other options or data.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from c2inet.errors import InputError
from c2inet.files import write_text_atomic
from sim.experiment.backends import run_jobs
from sim.experiment.config import Execution
from sim.progress import progress_bar

CELLS = "cells"


def cell_identity(*parts: Any, arrays: Sequence[Any] = ()) -> str:
    """The SHA-256 of ``parts`` (as JSON) and the bytes of ``arrays`` (the data a cell reads)."""
    digest = hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode())
    for array in arrays:
        digest.update(array.tobytes())
    return digest.hexdigest()


def _load(path: Path, identity: str) -> Any:
    """A kept cell's result; an :class:`InputError` for a damaged one or another study's."""
    try:
        kept = json.loads(path.read_text())
        kept_identity, result = kept["identity"], kept["result"]
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        raise InputError(f"--resume: {path} is damaged; remove it to compute it again") from None
    if kept_identity != identity:
        raise InputError(
            f"--resume: {path} is the result of other options or other data; resume with the "
            "options of the first run, or remove the file"
        )
    return result


def _run_cell(
    job: tuple[str, tuple],
    fn: Callable,
    folder: str | None,
    identity: str,
    threads: int,
    *shared: Any,
    on_event: Callable | None = None,
) -> Any:
    """One cell in a worker (or this process): compute, keep, return."""
    import torch

    torch.set_num_threads(threads)
    name, args = job
    result = fn(*args, *shared)
    if folder is not None:
        text = json.dumps({"identity": identity, "result": result})
        write_text_atomic(Path(folder) / CELLS / f"{name}.json", text + "\n")
    if on_event is not None:
        on_event("job_end", {"tasks": 1})
    return result


def run_cells(
    fn: Callable[..., Any],
    cells: dict[str, tuple],
    shared: tuple,
    execution: Execution,
    folder: Path | None = None,
    identity: str = "",
    resume: bool = False,
) -> dict[str, Any]:
    """``{name: fn(*args, *shared) for name, args in cells.items()}``, the cells run at once on
    ``execution``'s backend and each kept in ``folder/cells`` (None: not kept); with
    ``resume``, kept cells of the same ``identity`` are read back instead of run. ``fn`` must
    be a module's function returning JSON data; ``shared`` reaches each worker once."""
    done = {}
    for name in cells:
        path = folder / CELLS / f"{name}.json" if folder is not None else None
        if resume and path is not None and path.is_file():
            done[name] = _load(path, identity)
    todo = [(name, args) for name, args in cells.items() if name not in done]
    with progress_bar(total=len(cells), initial=len(done), desc="runs") as bar:
        results = run_jobs(
            _run_cell,
            todo,
            (fn, None if folder is None else str(folder), identity, execution.threads, *shared),
            execution.backend,
            execution.jobs,
            execution.ray_address,
            progress=lambda event, _data: bar.update() if event == "job_end" else None,
        )
    done.update({name: result for (name, _), result in zip(todo, results, strict=True)})
    return {name: done[name] for name in cells}
