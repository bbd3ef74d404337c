"""Readers of the trajectory formats the field exchanges, beside ETH-UCY's ``frame agent x y``.

- ``sdd``: the raw Stanford Drone annotations (``track xmin ymin xmax ymax frame lost occluded
  generated "label"``, pixels at 30 fps): each box's centre, the chosen labels, lost boxes
  dropped. The files generator then samples the frames and scales pixels to metres.
- ``trajnetpp``: TrajNet++ ndjson (``{"scene": {"id", "p", "s", "e"}}`` and ``{"track": {"f",
  "p", "x", "y"}}`` lines): one scene per scene record, its primary agent in the first column.

The converted SDD text that SocialVAE-style repositories share is ETH-UCY's four columns in
metres, read by the ETH-UCY reader itself. SDD's metres per pixel, one per video, come from a
YAML file as OpenTraj ships it (``estimated_scales.yaml``: ``LOCATION: {videoN: {scale: s}}``).
JSON and YAML are parsed (YAML's safe subset), never unpickled.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml

from c2inet.errors import InputError, quote
from sim.data import Scene

MAX_COORDINATE = 1e6  # metres: beyond it a coordinate is a unit error, and statistics overflow
MAX_CELLS = 2_000_000  # frames x agents of one dense scene (32 MB)
MAX_SCALES_BYTES = 1_000_000  # OpenTraj's scales file is 3 kB

SDD_COLUMNS = "track xmin ymin xmax ymax frame lost occluded generated label"


def sdd_rows(path: Path, start: int, lines: list[str], labels: tuple[str, ...]) -> np.ndarray:
    """(rows, 5): frame, track, box centre x and y (pixels), line number, of the kept boxes of
    lines ``start``, ``start + 1``, ...: those whose label is in ``labels`` and not lost."""
    rows = []
    for number, line in enumerate(lines, start):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 10:
            raise InputError(
                f"{path}:{number}: expected 10 columns ({SDD_COLUMNS}), got {len(fields)}"
            )
        if fields[9].strip('"') not in labels or fields[6] != "0":
            continue
        try:
            track, x0, y0, x1, y1, frame = (float(f) for f in fields[:6])
        except ValueError:
            text = quote(line.strip())
            raise InputError(f"{path}:{number}: non-numeric value in {text}") from None
        if not track.is_integer():  # 1.5 and 1.7 would both be agent 1
            raise InputError(f"{path}:{number}: track id {fields[0]} is not a whole number")
        rows.append((frame, track, (x0 + x1) / 2, (y0 + y1) / 2, number))
    out = np.array(rows, dtype=float).reshape(-1, 5)
    bad = ~np.isfinite(out[:, :4]).all(1)
    if bad.any():
        raise InputError(f"{path}:{int(out[np.argmax(bad), 4])}: non-finite value")
    return out


def video_scales(path: Path, files: list[str]) -> dict[str, float]:
    """Each SDD annotation file's metres per pixel: the scale of its video (its folder) at its
    location (the folder above) in the YAML file ``path``; one error line for anything missing."""
    try:
        if path.stat().st_size > MAX_SCALES_BYTES:
            raise InputError(f"{path}: over {MAX_SCALES_BYTES // 1000} kB; no scales file is")
        table = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError, RecursionError) as error:
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise InputError(f"{path}: cannot read the videos' scales: {reason}") from None
    scales = {}
    for file in files:
        location, video = Path(file).parent.parent.name, Path(file).parent.name
        videos = table.get(location) if isinstance(table, dict) else None
        entry = videos.get(video) if isinstance(videos, dict) else None
        if isinstance(entry, dict):
            entry = entry.get("scale")
        if isinstance(entry, bool) or not isinstance(entry, int | float) or not 0 < entry < 1e3:
            raise InputError(f"{path}: no scale in (0, 1000) for {location} {video} ({file})")
        scales[file] = float(entry)
    return scales


def trajnet_scenes(path: Path, scale: float = 1.0, every: int = 1) -> list[Scene]:
    """The scenes of one TrajNet++ ndjson file: each scene record's frames ``s`` to ``e`` on the
    file's frame grid (of the frames whose id is a multiple of ``every``), every track present
    in them, the primary agent ``p`` first."""
    records, tracks = [], []
    try:
        with path.open(encoding="utf-8") as file:
            for number, line in enumerate(file, 1):
                if line.strip():
                    _record(path, number, line, records, tracks)
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: cannot read: {error}") from None
    if not records or not tracks:
        raise InputError(f"{path}: needs scene and track records (TrajNet++ ndjson)")
    rows = np.array(tracks, dtype=float)
    _check_tracks(path, rows, scale)
    rows = rows[rows[:, 0] % every == 0] if every > 1 else rows
    if not len(rows):
        raise InputError(f"{path}: no track rows on frames that are multiples of {every}")
    rows = rows[np.lexsort((rows[:, 1], rows[:, 0]))]  # by frame, then agent
    frames = np.unique(rows[:, 0])
    step = float(np.diff(frames).min()) if len(frames) > 1 else 1.0
    scenes = []
    for scene_id, primary, first, last, number in records:
        cells = ((last - first) / step + 1) * len(np.unique(rows[:, 1]))
        if cells > MAX_CELLS:  # bounded by the rows' agents before any allocation
            raise InputError(
                f"{path}:{number}: scene {scene_id:g} spans frames {first:g} to {last:g}: "
                f"{(last - first) / step + 1:.3g} frames, beyond what a scene may hold"
            )
        lo = np.searchsorted(rows[:, 0], first, side="left")
        inside = rows[lo : np.searchsorted(rows[:, 0], last, side="right")]
        index = (inside[:, 0] - first) / step
        if not np.allclose(index, np.round(index)):
            raise InputError(f"{path}:{number}: scene {scene_id:g} is off the frame grid")
        others = np.setdiff1d(inside[:, 1], [primary])
        if len(others) == len(np.unique(inside[:, 1])):
            raise InputError(f"{path}:{number}: scene {scene_id:g} lacks its agent {primary:g}")
        agents = np.concatenate([[primary], others])
        positions = np.full((int(round((last - first) / step)) + 1, len(agents), 2), np.nan)
        column = np.searchsorted(others, inside[:, 1]) + 1
        column[inside[:, 1] == primary] = 0
        positions[np.round(index).astype(int), column] = inside[:, 2:4] * scale
        scenes.append(Scene(positions, agents.astype(np.int64)))
    return scenes


def _check_tracks(path: Path, rows: np.ndarray, scale: float = 1.0) -> None:
    """Track rows as every reader checks them: integer frame and agent ids, coordinates within
    MAX_COORDINATE metres once scaled, one row per agent and frame."""
    if (rows[:, :2] != np.round(rows[:, :2])).any():
        raise InputError(f"{path}: a track's frame or agent id is not an integer")
    if (np.abs(rows[:, 2:4] * scale) > MAX_COORDINATE).any():
        raise InputError(f"{path}: a coordinate beyond {MAX_COORDINATE:g} m")
    keys = rows[:, :2]
    if len(np.unique(keys, axis=0)) < len(keys):
        raise InputError(f"{path}: an agent has two track rows at one frame")


def _record(path: Path, number: int, line: str, records: list, tracks: list) -> None:
    """Append one ndjson line's scene or track record, or raise naming the line."""
    where = f"{path}:{number}"
    try:
        record = json.loads(line)
        if "track" in record:
            t = record["track"]
            row = tuple(float(t[key]) for key in ("f", "p", "x", "y"))
            if not np.isfinite(row).all():
                raise InputError(f"{where}: non-finite value in a track")
            tracks.append(row)
        elif "scene" in record:
            s = record["scene"]
            scene = tuple(float(s[key]) for key in ("id", "p", "s", "e"))
            if not np.isfinite(scene).all() or scene != tuple(np.round(scene)):
                raise InputError(f"{where}: a scene's id, p, s and e must be finite integers")
            if scene[3] < scene[2]:
                raise InputError(f"{where}: scene ends (e) before it starts (s)")
            records.append((*scene, number))
        else:
            raise InputError(f"{where}: expected a 'scene' or a 'track' record")
    except InputError:
        raise
    except json.JSONDecodeError as error:
        raise InputError(f"{where}: not a JSON line ({error.msg})") from None
    except KeyError as error:
        raise InputError(f"{where}: record lacks the field {error}") from None
    except RecursionError:
        raise InputError(f"{where}: a record nested too deeply") from None
    except (TypeError, ValueError, AttributeError, OverflowError):
        raise InputError(f"{where}: malformed record {quote(line.strip())}") from None
