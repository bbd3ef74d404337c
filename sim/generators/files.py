"""Real trajectories from text files in the ETH-UCY format (``frame agent x y`` per line).

Each value of a files family maps to train, optional val, and test file patterns (globs relative
to the family TOML, or absolute). Every file becomes one scene: its frames on a uniform grid,
agents absent from a frame marked NaN. Nothing is simulated; knobs describe the recording.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError, quote
from c2inet.options import check_range
from sim.data import SPLITS, Domain, Scene
from sim.generators import Generator
from sim.stats import motion_stats, proximity_stats

MAX_COORDINATE = 1e6  # metres: beyond it a coordinate is a unit error, and statistics overflow


@dataclass(frozen=True)
class FilesKnobs:
    """Where the files are and how to read them."""

    train: tuple[str, ...] = ()
    val: tuple[str, ...] = ()
    test: tuple[str, ...] = ()
    dt: float = 0.4  # s per frame step of the files

    def __post_init__(self):
        if not self.train or not self.test:
            raise InputError("a files domain needs 'train' and 'test' file patterns")
        check_range("dt", self.dt, 0, 10, open_low=True)


def read_trajectory_file(path: Path) -> Scene:
    """Parse and validate one ETH-UCY text file; errors name the file and line."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: cannot read: {error}") from None
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):  # tolerates CRLF
        fields = line.split()
        if not fields:
            continue
        where = f"{path}:{number}"
        if len(fields) != 4:
            raise InputError(f"{where}: expected 4 columns (frame agent x y), got {len(fields)}")
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise InputError(f"{where}: non-numeric value in {quote(line.strip())}") from None
        if not all(np.isfinite(values)):
            raise InputError(f"{where}: non-finite value in {quote(line.strip())}")
        if max(abs(values[2]), abs(values[3])) > MAX_COORDINATE:
            raise InputError(f"{where}: coordinate beyond {MAX_COORDINATE:g} m")
        if not values[1].is_integer() or abs(values[1]) > 2**53:
            raise InputError(f"{where}: agent id {quote(fields[1], 20)} is not a whole number")
        rows.append([*values, number])
    if not rows:
        raise InputError(f"{path}: no trajectory rows")
    data = np.array(rows)
    data = data[np.lexsort((data[:, 0], data[:, 1]))]  # by agent, then frame
    frame, agent, line = data[:, 0], data[:, 1], data[:, 4].astype(int)
    same_agent = agent[1:] == agent[:-1]
    steps = np.diff(frame)
    first_step = {}  # agent -> its frame step
    for k in np.nonzero(same_agent)[0]:
        expected = first_step.setdefault(agent[k], steps[k])
        if steps[k] <= 0 or not np.isclose(steps[k], expected):
            raise InputError(
                f"{path}:{line[k + 1]}: agent {agent[k]:g} breaks its uniform frame step "
                f"{expected:g} (frame {frame[k]:g} then {frame[k + 1]:g})"
            )
    step = float(min(first_step.values())) if first_step else 1.0
    index = (frame - frame.min()) / step
    if not np.allclose(index, np.round(index)):
        raise InputError(f"{path}: frame ids are not on a uniform grid of step {step:g}")
    index = np.round(index).astype(np.int64)
    ids, column = np.unique(agent, return_inverse=True)
    positions = np.full((index.max() + 1, len(ids), 2), np.nan)
    positions[index, column] = data[:, 2:4]
    return Scene(positions, ids.astype(np.int64))


class FilesGenerator(Generator):
    """Recorded trajectories read from ETH-UCY-format text files."""

    name = "files"
    version = 2  # 2: no overlap count (it needed a made-up body radius)
    Knobs = FilesKnobs

    @classmethod
    def resolve(cls, knobs: FilesKnobs, base_dir: Path) -> dict[str, Any]:
        out: dict[str, Any] = {"dt": knobs.dt}
        for split in SPLITS:
            paths: list[str] = []
            for pattern in getattr(knobs, split):
                full = pattern if Path(pattern).is_absolute() else str(base_dir / pattern)
                matches = sorted(Path(full).parent.glob(Path(full).name))
                if not matches:
                    raise InputError(f"{split} pattern {pattern!r}: no file matches {full}")
                for match in matches:  # a folder, a device or a FIFO would hang or never end
                    if not match.is_file():
                        raise InputError(f"{split} pattern {pattern!r}: {match} is no regular file")
                paths.extend(str(m.resolve()) for m in matches)
            out[split] = paths
        return out

    @classmethod
    def content_key(cls, knobs: dict[str, Any]) -> dict[str, Any]:
        return {
            path: hashlib.sha256(Path(path).read_bytes()).hexdigest()
            for split in SPLITS
            for path in knobs[split]
        }

    def rollout(self, knobs: dict[str, Any], seed, frames: int) -> Scene:
        scene = read_trajectory_file(Path(knobs["test"][0]))
        return Scene(scene.positions[:frames], scene.agent_ids)

    def generate(self, name, family, knobs: dict[str, Any], splits, seed, workers=1) -> Domain:
        scenes = {split: [read_trajectory_file(Path(p)) for p in knobs[split]] for split in SPLITS}
        everything = [s for split in SPLITS for s in scenes[split]]
        stats = motion_stats(everything, knobs["dt"])
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
