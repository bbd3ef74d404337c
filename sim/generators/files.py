"""Real trajectories from recordings: ETH-UCY text (``frame agent x y`` per line, also the
converted SDD text of SocialVAE-style repositories), raw Stanford Drone annotations, TrajNet++
ndjson (readers of the last two in :mod:`sim.generators.formats`).

Each value of a files family maps to train, optional val, and test file patterns (globs relative
to the family TOML, or absolute). Tracks stay sparse: each group of tracks whose frame ranges
overlap becomes one scene on a uniform frame grid (agents absent from a frame marked NaN), so a
file of thousands of separate recordings, or of agents a million frames apart, costs memory in
proportion to its rows. Nothing is simulated; knobs describe the recording.
"""

from __future__ import annotations

import glob
import itertools
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.data import OBS_LEN, PRED_LEN
from c2inet.errors import InputError, quote
from c2inet.files import file_digest
from c2inet.options import check_range
from sim.data import SPLITS, Domain, Scene
from sim.generators.base import Generator
from sim.generators.formats import (
    MAX_CELLS,
    MAX_COORDINATE,
    sdd_rows,
    trajnet_scenes,
    video_scales,
)
from sim.stats import motion_stats, proximity_stats

WINDOW = OBS_LEN + PRED_LEN
CHUNK_LINES = 1 << 17  # lines parsed at a time (about 4 MB of text)
FORMATS = ("ethucy", "sdd", "trajnetpp")
UNUSUAL_SPEED = 10.0  # units a second: above it, people in metres would be running a sprint


@dataclass(frozen=True)
class FilesKnobs:
    """Where the files are and how to read them."""

    train: tuple[str, ...] = ()
    val: tuple[str, ...] = ()
    test: tuple[str, ...] = ()
    dt: float = 0.4  # s per frame step of the files
    split_gaps: bool = False  # a track that skips frames continues as a new track
    format: str = "ethucy"  # ethucy (also SocialVAE's SDD text), sdd (raw annotations), trajnetpp
    scale: float = 1.0  # metres per unit of the file: each SDD video's own, for its pixels
    scales: str = ""  # sdd: a YAML of every video's metres per pixel (OpenTraj's), over scale
    every: int = 1  # keep the frames whose id is a multiple (12: SDD's 30 fps as 2.5 fps)
    labels: tuple[str, ...] = ("Pedestrian",)  # sdd: the classes kept (Biker, Cart, Car...)
    # refuse a recording whose mean speed is above this (units a second): a family in metres
    # given pixels (SDD's raw coordinates) reads 10 to 100 times faster than people walk
    # (0: no check)
    max_speed: float = 0.0

    def __post_init__(self):
        if not self.train or not self.test:
            raise InputError("a files domain needs 'train' and 'test' file patterns")
        check_range("dt", self.dt, 0, 10, open_low=True)
        check_range("scale", self.scale, 0, 1e3, open_low=True)
        check_range("every", self.every, 1, 1000)
        check_range("max_speed", self.max_speed, 0, 1e6)
        if self.format not in FORMATS:
            raise InputError(f"format {self.format!r}: expected one of {', '.join(FORMATS)}")
        if self.scales and self.format != "sdd":
            raise InputError(f"scales {self.scales!r}: only SDD's videos have their own scales")


def read_recording(path: Path, knobs: dict[str, Any]) -> list[Scene]:
    """The scenes of one file as a files domain's resolved ``knobs`` say to read it."""
    if knobs.get("format") == "trajnetpp":
        return trajnet_scenes(path, knobs.get("scale", 1.0), knobs.get("every", 1))
    reading = {key: knobs[key] for key in ("format", "scale", "every", "labels") if key in knobs}
    if "scales" in knobs:
        reading["scale"] = knobs["scales"][str(path)]
    return read_trajectory_file(path, knobs["split_gaps"], **reading)


def read_trajectory_file(
    path: Path,
    split_gaps: bool = False,
    format: str = "ethucy",
    scale: float = 1.0,
    every: int = 1,
    labels: tuple[str, ...] = ("Pedestrian",),
) -> list[Scene]:
    """Parse and validate one ETH-UCY text file (or raw SDD annotations, ``format="sdd"``) into
    scenes, keeping the frames whose id is a multiple of ``every`` and multiplying coordinates
    by ``scale``; errors name the file and line.

    Tracks stay sparse: each agent keeps its own frame range, and agents whose ranges overlap
    (directly or through others) form one scene, so memory grows with the rows, not with the
    file's frames times its agents. A scene larger than ``MAX_CELLS`` is cut in time into pieces
    overlapping by one window less a frame: every 20-frame window lies in exactly one piece.
    With ``split_gaps`` a track that skips frames continues as a new track (a new id) instead of
    being an error.
    """
    data = _rows(path, format, tuple(labels))
    data = data[data[:, 0] % every == 0] if every > 1 else data
    if not len(data):
        raise InputError(f"{path}: no rows left on frames that are multiples of {every}")
    data[:, 2:4] *= scale
    far = np.abs(data[:, 2:4]).max(1) > MAX_COORDINATE
    if far.any():
        line = int(data[np.argmax(far), 4])
        raise InputError(f"{path}:{line}: coordinate beyond {MAX_COORDINATE:g} m")
    data = data[np.lexsort((data[:, 0], data[:, 1]))]  # by agent, then frame
    frame, agent, line = data[:, 0], data[:, 1], data[:, 4].astype(int)
    track = _tracks(path, frame, agent, line, split_gaps)
    index = _frame_index(path, frame, track, every)
    bounds = np.flatnonzero(np.diff(track, prepend=-1, append=track[-1] + 1))
    first, last = index[bounds[:-1]], index[bounds[1:] - 1]  # per track, in track order
    ids = _track_ids(agent[bounds[:-1]])
    scenes = []
    for members in _components(first, last):
        start, stop = first[members].min(), last[members].max() + 1
        length = max(MAX_CELLS // len(members), 4 * WINDOW)
        for piece in range(start, stop, length - WINDOW + 1):  # windows start in one piece only
            end = min(piece + length, stop)
            present = members[(first[members] < end) & (last[members] >= piece)]
            positions = np.full((end - piece, len(present), 2), np.nan)
            for column, t in enumerate(present):
                rows = slice(bounds[t], bounds[t + 1])
                keep = (index[rows] >= piece) & (index[rows] < end)
                positions[index[rows][keep] - piece, column] = data[rows, 2:4][keep]
            scenes.append(Scene(positions, ids[present]))
            if end == stop:
                break
    return scenes


def _frame_index(path: Path, frame: np.ndarray, track: np.ndarray, every: int) -> np.ndarray:
    """Each row's step from the file's first frame, on the grid of the smallest frame step
    within a track; a grid the frames are not on, or an ``every`` the step does not divide, is
    one line."""
    steps = np.diff(frame)[(track[1:] == track[:-1])]
    step = float(steps.min()) if len(steps) else 1.0
    if every > 1 and len(steps) and not np.isclose(step, every):
        raise InputError(
            f"{path}: every = {every} keeps frames {step:g} apart, not {every}: the file's own "
            f"frame step does not divide {every}, and a step of {step:g} frames read as one "
            "would multiply every speed; choose every as a multiple of the file's step"
        )
    index = (frame - frame.min()) / step
    if not np.allclose(index, np.round(index)):
        raise InputError(f"{path}: frame ids are not on a uniform grid of step {step:g}")
    return np.round(index).astype(np.int64)


def _rows(path: Path, format: str = "ethucy", labels: tuple[str, ...] = ()) -> np.ndarray:
    """(rows, 5): frame, agent, x, y and the line number of every row of the file, read in one
    pass of ``CHUNK_LINES`` lines at a time: the text is never held whole."""
    parts = []
    try:
        with path.open(encoding="utf-8") as file:  # universal newlines: CRLF is a line end
            for start in itertools.count(1, CHUNK_LINES):
                lines = list(itertools.islice(file, CHUNK_LINES))
                if not lines:
                    break
                if format == "sdd":
                    parts.append(sdd_rows(path, start, lines, labels))
                else:
                    parts.append(_chunk_rows(path, start, lines))
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: cannot read: {error}") from None
    rows = np.concatenate(parts) if parts else np.empty((0, 5))
    if not len(rows):
        raise InputError(f"{path}: no trajectory rows")
    return rows


def _chunk_rows(path: Path, start: int, lines: list[str]) -> np.ndarray:
    """The rows of lines ``start``, ``start + 1``, ... (blank ones skipped), validated."""
    with warnings.catch_warnings():  # a chunk of blank lines is no data, and no warning
        warnings.simplefilter("ignore", UserWarning)
        try:  # the fast path; a chunk it refuses is read line by line for the exact error
            values = np.loadtxt(lines, ndmin=2, comments=None)
        except ValueError:
            values = None
    numbers = np.arange(start, start + len(lines))
    if values is None or len(values) != len(lines):  # blank lines, or an error to place
        kept = [bool(line.strip()) for line in lines]
        numbers, lines = (
            numbers[kept],
            [line for line, keep in zip(lines, kept, strict=True) if keep],
        )
        if not lines:
            return np.empty((0, 5))
    if values is None or values.shape != (len(lines), 4):
        _first_bad_line(path, numbers, lines)

    def where(bad: np.ndarray) -> tuple[str, str]:
        """The first bad row's place (file:line) and its line's text."""
        first = int(np.argmax(bad))
        return f"{path}:{numbers[first]}", lines[first]

    finite = np.isfinite(values).all(1)
    if not finite.all():
        place, line = where(~finite)
        raise InputError(f"{place}: non-finite value in {quote(line.strip())}")
    whole = (values[:, 1] == np.round(values[:, 1])) & (np.abs(values[:, 1]) <= 2**53)
    if not whole.all():
        place, line = where(~whole)
        raise InputError(f"{place}: agent id {quote(line.split()[1], 20)} is not a whole number")
    return np.column_stack([values, numbers])


def _first_bad_line(path: Path, numbers: np.ndarray, lines: list[str]) -> None:
    """Raise the error of the first line that is not four numbers."""
    for number, line in zip(numbers.tolist(), lines, strict=True):
        fields = line.split()
        where = f"{path}:{number}"
        if len(fields) != 4:
            raise InputError(f"{where}: expected 4 columns (frame agent x y), got {len(fields)}")
        try:
            [float(f) for f in fields]
        except ValueError:
            raise InputError(f"{where}: non-numeric value in {quote(line.strip())}") from None
    raise InputError(f"{path}: cannot read its rows as numbers")


def _tracks(path, frame, agent, line, split_gaps: bool) -> np.ndarray:
    """The track number of every row (rows sorted by agent, then frame): an agent's rows are one
    track with a uniform frame step; with ``split_gaps`` a skip of whole steps starts another."""
    same = agent[1:] == agent[:-1]
    steps = np.diff(frame)
    agent_of_row = np.cumsum(np.concatenate([[True], ~same])) - 1
    pairs = np.flatnonzero(same)  # steps inside one agent's rows
    agents, first = np.unique(agent_of_row[pairs], return_index=True)
    first_step = np.full(agent_of_row[-1] + 1, np.nan)  # every agent's step is its first one
    first_step[agents] = steps[pairs[first]]
    expected = first_step[agent_of_row[:-1]]
    uniform = (steps > 0) & np.isclose(steps, expected)
    ratio = np.divide(steps, expected, out=np.zeros_like(steps), where=expected > 0)
    gap = split_gaps & (ratio > 1) & np.isclose(ratio, np.round(ratio))
    broken = same & ~uniform & ~gap
    if broken.any():
        k = int(np.argmax(broken))
        raise InputError(
            f"{path}:{line[k + 1]}: agent {agent[k]:g} breaks its uniform frame step "
            f"{expected[k]:g} (frame {frame[k]:g} then {frame[k + 1]:g})"
            + ("" if split_gaps else "; split_gaps = true splits tracks at gaps")
        )
    return np.concatenate([[0], np.cumsum(~same | gap)])


def _track_ids(agents: np.ndarray) -> np.ndarray:
    """An id per track: the agent's own for its first track, new ones above all for the rest."""
    ids = agents.astype(np.int64)
    later = np.flatnonzero(np.concatenate([[False], agents[1:] == agents[:-1]]))
    ids[later] = ids.max() + 1 + np.arange(len(later))
    return ids


def _components(first: np.ndarray, last: np.ndarray) -> list[np.ndarray]:
    """Tracks grouped into scenes: those whose frame ranges overlap, directly or in a chain."""
    order = np.argsort(first, kind="stable")
    groups, current, reach = [], [order[0]], last[order[0]]
    for t in order[1:]:
        if first[t] > reach:
            groups.append(np.sort(current))
            current, reach = [], first[t]
        current.append(t)
        reach = max(reach, last[t])
    groups.append(np.sort(current))
    return groups


class FilesGenerator(Generator):
    """Recorded trajectories read from ETH-UCY text, raw SDD annotations or TrajNet++ ndjson."""

    name = "files"
    seeded = False  # a recording is the same whatever the seed
    version = 3  # 2: no overlap count; 3: sparse tracks, a scene per group of overlapping tracks
    Knobs = FilesKnobs

    @classmethod
    def resolve(cls, knobs: FilesKnobs, base_dir: Path) -> dict[str, Any]:
        """The knobs with each pattern's files; the reading options only where they differ
        from ETH-UCY's, so an ETH-UCY domain keeps its cache key."""
        out: dict[str, Any] = {"dt": knobs.dt, "split_gaps": knobs.split_gaps}
        for key in ("format", "scale", "every", "labels", "max_speed"):
            if getattr(knobs, key) != getattr(FilesKnobs, key):
                out[key] = getattr(knobs, key)
        for split in SPLITS:
            paths: list[str] = []
            for pattern in getattr(knobs, split):
                full = pattern if Path(pattern).is_absolute() else str(base_dir / pattern)
                matches = sorted(map(Path, glob.glob(full)))  # wildcards in folders too
                if not matches:
                    raise InputError(f"{split} pattern {pattern!r}: no file matches {full}")
                for match in matches:  # a folder, a device or a FIFO would hang or never end
                    if not match.is_file():
                        raise InputError(f"{split} pattern {pattern!r}: {match} is no regular file")
                paths.extend(str(m.resolve()) for m in matches)
            out[split] = paths
        if knobs.scales:
            files = [path for split in SPLITS for path in out[split]]
            out["scales"] = video_scales(base_dir / knobs.scales, files)
        return out

    @classmethod
    def content_key(cls, knobs: dict[str, Any]) -> dict[str, Any]:
        return {path: file_digest(Path(path)) for split in SPLITS for path in knobs[split]}

    @classmethod
    def memory_bytes(cls, knobs: dict[str, Any], splits) -> int:
        """Six times the files' size: their rows as arrays (about 40 bytes a row of 25 to 40
        characters), sorted, and the scenes; 4.4 times measured on a 42 MB file."""
        return 6 * sum(Path(path).stat().st_size for split in SPLITS for path in knobs[split])

    def rollout(self, knobs: dict[str, Any], seed, frames: int) -> Scene:
        scenes = read_recording(Path(knobs["test"][0]), knobs)
        scene = max(scenes, key=lambda s: s.num_frames)
        return Scene(scene.positions[:frames], scene.agent_ids)

    def generate(self, name, family, knobs: dict[str, Any], splits, seed, workers=1) -> Domain:
        scenes = {
            split: [s for path in knobs[split] for s in read_recording(Path(path), knobs)]
            for split in SPLITS
        }
        everything = [s for split in SPLITS for s in scenes[split]]
        stats = motion_stats(everything, knobs["dt"])
        limit = knobs.get("max_speed", 0.0)
        pixels = knobs.get("format") == "sdd" and "scales" not in knobs and "scale" not in knobs
        if not limit and not pixels and stats["mean_speed"] > UNUSUAL_SPEED:  # a warning only
            print(
                f"warning: domain {name}: its agents move at {stats['mean_speed']:.3g} units/s on "
                "average; if they are people in metres, the coordinates are in another unit "
                "(pixels?)",
                file=sys.stderr,
            )
        if limit and stats["mean_speed"] > limit:
            raise InputError(
                f"domain {name}: its agents move at {stats['mean_speed']:.3g} units/s on average, "
                f"above the {limit:g} m/s a recording in metres can hold: are its coordinates "
                "pixels? (the family reads metres; sdd_px reads SDD's pixels)"
            )
        stats.update(proximity_stats(everything))  # no overlaps: recorded people have no radius
        stats["density"] = _density(everything)
        return Domain(name, family, self.name, knobs, knobs["dt"], scenes, stats)


def _density(scenes: list[Scene]) -> float:
    """Mean agents present per frame over the bounding-box area of each recording, per m^2."""
    values = []
    for scene in scenes:
        points = scene.positions.reshape(-1, 2)
        points = points[np.isfinite(points[:, 0])]
        area = max(float(np.prod(points.max(0) - points.min(0))), 1e-6)
        values.append(np.isfinite(scene.positions[..., 0]).sum(1).mean() / area)
    return float(np.mean(values))
