"""Reading and writing domains: Parquet (the cache), ETH-UCY text and NPZ exports, atomically."""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from pathlib import Path

import numpy as np

from c2inet.errors import InputError
from c2inet.files import write_atomic, write_text_atomic
from c2inet.lazy import lazy_module
from sim.data import SPLITS, Domain, Scene

# Arrow loads where a domain is written or read: a command's --help needs none
pa = lazy_module("pyarrow")
pq = lazy_module("pyarrow.parquet")


def _table(domain: Domain) -> pa.Table:
    columns: dict[str, list[np.ndarray]] = {
        k: [] for k in ("split", "scene", "frame", "agent", "x", "y")
    }
    for split_id, split in enumerate(SPLITS):
        for index, scene in enumerate(domain.scenes[split]):
            frame, column = np.nonzero(np.isfinite(scene.positions[..., 0]))
            columns["split"].append(np.full(len(frame), split_id, np.int8))
            columns["scene"].append(np.full(len(frame), index, np.int32))
            columns["frame"].append(frame.astype(np.int32))
            columns["agent"].append(scene.agent_ids[column])
            columns["x"].append(scene.positions[frame, column, 0])
            columns["y"].append(scene.positions[frame, column, 1])
    arrays = {k: np.concatenate(v) if v else np.zeros(0) for k, v in columns.items()}
    meta: dict = {
        "name": domain.name,
        "family": domain.family,
        "generator": domain.generator,
        "knobs": domain.knobs,
        "dt": domain.dt,
        "stats": domain.stats,
        "hash": domain.hash,
        "scenes": {
            s: [[sc.num_frames, len(sc.agent_ids)] for sc in domain.scenes[s]] for s in SPLITS
        },
    }
    meta["checksum"] = _checksum(arrays, meta)
    return pa.table(arrays).replace_schema_metadata({"domain": json.dumps(meta, sort_keys=True)})


def _checksum(arrays: dict[str, np.ndarray], meta: dict) -> str:
    """SHA-256 of every column's bytes and of the metadata (without the checksum itself)."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape}".encode())
        digest.update(array.tobytes())
    rest = {k: v for k, v in meta.items() if k != "checksum"}
    digest.update(json.dumps(rest, sort_keys=True).encode())
    return digest.hexdigest()


def write_parquet(domain: Domain, path: Path) -> None:
    table = _table(domain)
    write_atomic(path, lambda tmp: pq.write_table(table, tmp, compression="zstd"))


def read_parquet(path: Path) -> Domain:
    """Read a domain written by :func:`write_parquet`."""
    try:
        table = pq.read_table(path)
        meta = json.loads(table.schema.metadata[b"domain"])
        data = {name: table.column(name).to_numpy() for name in table.column_names}
        intact = meta["checksum"] == _checksum(data, meta)
    except (OSError, KeyError, ValueError, TypeError, pa.ArrowException) as error:
        raise InputError(f"{path}: not a domain file: {error}") from None
    if not intact:
        raise InputError(f"{path}: damaged domain file (its content does not match its checksum)")
    scenes: dict[str, list[Scene]] = {}
    for split_id, split in enumerate(SPLITS):
        in_split = data["split"] == split_id
        out = []
        for index, (frames, agents) in enumerate(meta["scenes"][split]):
            rows = in_split & (data["scene"] == index)
            ids, column = np.unique(data["agent"][rows], return_inverse=True)
            positions = np.full((frames, agents, 2), np.nan)
            positions[data["frame"][rows], column, 0] = data["x"][rows]
            positions[data["frame"][rows], column, 1] = data["y"][rows]
            out.append(Scene(positions, ids.astype(np.int64)))
        scenes[split] = out
    return Domain(
        meta["name"],
        meta["family"],
        meta["generator"],
        meta["knobs"],
        meta["dt"],
        scenes,
        meta["stats"],
        meta["hash"],
    )


def write_ethucy(domain: Domain, folder: Path) -> None:
    """One ``frame agent x y`` text file per split; scenes follow each other in frame and id."""
    frame_step = 10
    for split in SPLITS:
        lines, frame_offset, agent_offset = [], 0, 0
        for scene in domain.scenes[split]:
            frame, column = np.nonzero(np.isfinite(scene.positions[..., 0]))
            order = np.lexsort((column, frame))
            for f, c in zip(frame[order], column[order], strict=True):
                x, y = scene.positions[f, c]
                lines.append(
                    f"{(frame_offset + f) * frame_step}\t{agent_offset + c}\t{x:.6f}\t{y:.6f}\n"
                )
            frame_offset += scene.num_frames + 1  # one empty frame keeps scenes apart
            agent_offset += len(scene.agent_ids)
        write_text_atomic(folder / f"{split}.txt", "".join(lines))


def write_npz(domain: Domain, folder: Path) -> None:
    """Key ``raw`` shaped (scenes, agents, frames, 2) per split, for fixed-size scenes only."""
    for split in SPLITS:
        scenes = domain.scenes[split]
        shapes = {s.positions.shape for s in scenes}
        if len(shapes) > 1 or any(np.isnan(s.positions).any() for s in scenes):
            raise InputError(
                f"domain {domain.name}: npz export needs fixed-size scenes with every agent present"
            )
        raw = (
            np.stack([s.positions.transpose(1, 0, 2) for s in scenes])
            if scenes
            else np.zeros((0, 0, 0, 2))
        )

        def write(tmp: Path, raw=raw) -> None:  # a fixed timestamp keeps the bytes reproducible
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, raw, allow_pickle=False)
            with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as archive:
                archive.writestr(
                    zipfile.ZipInfo("raw.npy", date_time=(1980, 1, 1, 0, 0, 0)), buffer.getvalue()
                )

        write_atomic(folder / f"{split}.npz", write)
