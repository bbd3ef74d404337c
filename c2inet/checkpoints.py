"""A job's task checkpoints on disk: one file a finished task, and a manifest of their SHA-256
and of the job's identity, so that ``--resume`` continues only from verified checkpoints of the
same job, options and data. Files are written atomically and read tensors-only."""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import torch

from c2inet.errors import InputError
from c2inet.files import file_digest, write_atomic, write_text_atomic

MANIFEST = "manifest.json"  # beside the checkpoints: the job's identity and their SHA-256
CHECKPOINT_KEYS = {"task", "model", "optimiser", "method", "torch_rng", "numpy_rng", "matrices"}


class CheckpointStore:
    """The checkpoints of ``tasks`` tasks in ``folder`` (None: none are kept), of ``identity``."""

    def __init__(self, folder: Path | None, identity: str, tasks: int):
        self.folder, self.identity, self.tasks = folder, identity, tasks

    def path(self, index: int) -> Path:
        return self.folder / f"task_{index:02d}.pt"

    def _present(self, path: Path) -> bool:
        if path.is_dir():  # a folder where a checkpoint was: nothing to read, one line
            raise InputError(
                f"--resume: {path} is a folder, not a checkpoint; remove it to retrain from the "
                "task before, or use --overwrite"
            )
        return path.exists()

    def verified(self) -> list[Path]:
        """The verified task checkpoints: task 0, 1, ... up to the first one the manifest does
        not list (a kill between the two writes), each checked against its SHA-256, and all of
        them against ``identity``."""
        if self.folder is None:
            return []
        paths = list(itertools.takewhile(self._present, map(self.path, range(self.tasks))))
        if not paths or not (self.folder / MANIFEST).exists():
            return []  # none, or killed before its first manifest, or an earlier version's
        manifest = self._manifest()
        if manifest.get("identity") != self.identity:
            raise InputError(
                f"--resume: {self.folder} holds checkpoints of another job, other options "
                "or other data; delete the folder to retrain that job, or use --overwrite"
            )
        listed = list(itertools.takewhile(lambda p: p.name in manifest["sha256"], paths))
        for path in listed:
            if file_digest(path) != manifest["sha256"][path.name]:
                raise InputError(
                    f"--resume: checkpoint {path} is damaged (its SHA-256 differs from the "
                    "manifest's); delete it to retrain from the task before, or use --overwrite"
                )
        return listed

    def _manifest(self) -> dict[str, Any]:
        path = self.folder / MANIFEST
        try:
            manifest = json.loads(path.read_text())
            if not isinstance(manifest, dict) or not isinstance(manifest.get("sha256"), dict):
                raise ValueError("no sha256 table")
        except (OSError, ValueError) as error:
            raise InputError(
                f"--resume: {path} is damaged ({type(error).__name__}); delete "
                f"{self.folder} to retrain that job, or use --overwrite"
            ) from None
        return manifest

    def save(self, index: int, state: dict[str, Any]) -> None:
        """Write task ``index``'s checkpoint, then the manifest that lists it (and the earlier
        ones, but none after it)."""
        path = self.path(index)
        write_atomic(path, lambda tmp: torch.save(state, tmp))
        fresh = index == 0 or not (self.folder / MANIFEST).exists()
        digests = {} if fresh else self._manifest()["sha256"]
        digests = {name: d for name, d in digests.items() if name < path.name}
        manifest = {"identity": self.identity, "sha256": {**digests, path.name: file_digest(path)}}
        write_text_atomic(self.folder / MANIFEST, json.dumps(manifest, indent=1) + "\n")


def load_checkpoint(path: Path, device: torch.device | str = "cpu") -> dict[str, Any]:
    """Read a task checkpoint safely (tensors and plain values only) onto ``device``; a damaged
    or foreign one is one :class:`InputError` naming it and the way out."""
    try:
        state = torch.load(path, weights_only=True, map_location=device)
        missing = CHECKPOINT_KEYS - set(state)
    except Exception as error:  # torch raises many kinds for a damaged file
        raise InputError(
            f"--resume: checkpoint {path} is damaged ({type(error).__name__}); delete it to "
            "retrain from the task before, or use --overwrite"
        ) from None
    if missing:
        raise InputError(f"--resume: {path} is no checkpoint of this project (no {min(missing)})")
    return state
