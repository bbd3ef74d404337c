"""Domain families: one TOML file each, naming a generator, the knob its values set, defaults.

A family file looks like:

    description = "Pymunk crowds whose behavioural noise grows"
    generator = "crowd"
    knob = "noise"            # which generator knob the scenario values set
    seed_offset = 1           # decorrelates families that share knob values
    [knobs]                   # defaults for every knob of the generator
    layout = "circle_crossing"
    [splits]                  # scenes per split
    train = 300
    val = 50
    test = 100

Name-valued families (real data) have ``[values.NAME]`` tables instead of ``knob``. A family of
a dataset that cannot ship (SDD, TrajNet++) says ``data_root = "sdd"``: its file patterns are
relative to that folder of the data root (``--data-root DIR`` or ``$C2I_DATA_ROOT``), and
``download`` says what to put there.
"""

from __future__ import annotations

import dataclasses
import glob
import os
import re
import sys
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from c2inet.errors import InputError, did_you_mean
from c2inet.files import check_path_length
from c2inet.options import build
from sim.generators import get_generator

# the built-in families (and the real data they read) ship inside the package
SCENARIOS_DIR = Path(str(resources.files("sim").joinpath("scenarios")))
_FAMILY_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
DATA_ROOT_ENV = "C2I_DATA_ROOT"  # the folder that holds the datasets no family can ship


@dataclass(frozen=True)
class Splits:
    """How many scenes each split holds (simulated families)."""

    train: int = 300
    val: int = 50
    test: int = 100

    def __post_init__(self):
        for name in ("train", "val", "test"):
            if not 0 <= getattr(self, name) <= 1_000_000:
                raise InputError(f"splits.{name}={getattr(self, name)} is out of range")
        if self.train < 1 or self.test < 1:
            raise InputError("splits: train and test need at least one scene each")


@dataclass(frozen=True)
class Windowing:
    """How a family's scenes become learner windows (its ``[windows]`` table).

    ``stride``: frames between the starts of two training windows (1 to 100). ``share``: the
    first share of the training windows, in the recording's order, in (0, 1] (the first tenth is
    0.1). ``min_agents``: windows with fewer agents present throughout are dropped, in every
    split (2 is sgan's protocol, which drops lone agents). ``val_share``: for a family without
    validation files, the last share of the training windows, in the recording's order, held out
    as the validation split (the windows overlapping it dropped from training), in [0, 0.5];
    ``val_stride``: frames between two of those held-out windows (1: every frame, as test files
    are scored; more makes a validation-selected epoch cheaper to find).
    """

    stride: int = 1
    share: float = 1.0
    min_agents: int = 1
    val_share: float = 0.0
    val_stride: int = 1

    def __post_init__(self):
        bounds = {
            "stride": (1, 100),
            "share": (0, 1),
            "min_agents": (1, 100),
            "val_share": (0, 0.5),
            "val_stride": (1, 100),
        }
        for key, (low, high) in bounds.items():
            value = getattr(self, key)
            if not (low < value <= high if key == "share" else low <= value <= high):
                raise InputError(f"windows.{key}={value!r}: expected {WINDOW_RANGES[key]}")


WINDOW_RANGES = {
    "stride": "an integer in [1, 100]",
    "share": "a number in (0, 1]",
    "min_agents": "an integer in [1, 100]",
    "val_share": "a number in [0, 0.5]",
    "val_stride": "an integer in [1, 100]",
}


@dataclass(frozen=True)
class Family:
    """A parsed family file."""

    name: str
    path: Path
    generator: str
    description: str = ""
    knob: str | None = None
    seed_offset: int = 0
    defaults: dict[str, Any] = field(default_factory=dict)
    splits: Splits = Splits()
    values: dict[str, dict[str, Any]] = field(default_factory=dict)
    unit: str = "m"  # of the positions: metres, or pixels (a recording not yet scaled)
    windowing: Windowing = Windowing()  # how its scenes become windows
    train: dict[str, Any] = field(default_factory=dict)  # the learner's defaults ([train])
    model: dict[str, Any] = field(default_factory=dict)  # and its network's ([model])
    data_root: str = ""  # the data root's folder its files are relative to ("": its own folder)
    download: str = ""  # what to put in that folder, and where to get it

    @property
    def stride(self) -> int:
        return self.windowing.stride

    @property
    def share(self) -> float:
        return self.windowing.share

    @property
    def value_names(self) -> tuple[str, ...]:
        return tuple(self.values)

    def knobs_for(self, value: float | str) -> dict[str, Any]:
        """Validated generator knobs for one value of this family, as a plain dict."""
        merged = dict(self.defaults)
        if self.values:
            merged.update(self.values[value])
        else:
            merged[self.knob] = value
        generator = get_generator(self.generator)
        knobs = build(generator.Knobs, merged, f"{self.path.name} value {value}")
        folder = self.files_dir()
        try:
            return generator.resolve(knobs, folder)
        except InputError as error:
            if not self.data_root:
                raise
            hint = self.other_format(folder)
            raise InputError(
                f"family {self.name}: {error} (expected {self.download}){hint}"
            ) from None

    def files_dir(self) -> Path:
        """The folder the family's file patterns are relative to: its TOML's, or its dataset's
        folder: ``DATA_ROOT/<data_root>``, or else the data root itself where it is that
        dataset's folder (its files are there). Else one line says what to put there, and which
        family reads a folder that holds another dataset's layout."""
        if not self.data_root:
            return self.path.parent
        root = os.environ.get(DATA_ROOT_ENV, "")
        given = check_path_length(Path(root).expanduser(), f"${DATA_ROOT_ENV} (--data-root)")
        if root and (given / self.data_root).is_dir():
            return given / self.data_root
        if root and given.is_dir() and self.holds_files(given):
            return given  # --data-root named the dataset's own folder
        where = f"{given / self.data_root}" if root else f"DATA_ROOT/{self.data_root}"
        hint = (
            self.other_format(given)
            if root
            else f" (give --data-root DATA_ROOT or set ${DATA_ROOT_ENV})"
        )
        raise InputError(f"family {self.name}: reads {self.download} from {where}{hint}")

    def other_format(self, folder: Path) -> str:
        """A hint where ``folder`` holds the files another dataset family reads ("" if none)."""
        for name, family in _dataset_families().items():
            held = (folder / family.data_root, folder)
            if name != self.name and any(family.holds_files(f) for f in held):
                return f"; {folder} holds what family {name} reads"
        return ""

    def holds_files(self, folder: Path) -> bool:
        """Whether ``folder`` holds a file of the first training pattern of any value."""
        patterns = [p for v in self.values.values() for p in v.get("train", [])[:1]]
        base = glob.escape(str(folder))  # a folder named with [ or * is a name, not a pattern
        return any(isinstance(p, str) and glob.glob(f"{base}/{p}") for p in patterns)


_noticed: set[Path] = set()  # built-in families replaced by a user's copy, said once


def _dataset_families() -> dict[str, Family]:
    """The built-in families that read a dataset from the data root."""
    families = {path.stem: load_family(path) for path in sorted(SCENARIOS_DIR.glob("*.toml"))}
    return {name: family for name, family in families.items() if family.data_root}


def available_families(extra_dirs: list[Path]) -> dict[str, Path]:
    """Family name -> TOML path. A user folder's family replaces a built-in one of the same
    name (a copy to tweak), with a notice; two user folders may not define the same family."""
    found: dict[str, Path] = {}
    for folder in [SCENARIOS_DIR, *extra_dirs]:
        folder = Path(folder)
        if not folder.is_dir():
            raise InputError(f"--scenarios-dir {folder}: not a folder")
        for path in sorted(folder.glob("*.toml")):
            if not _FAMILY_NAME.match(path.stem):
                raise InputError(f"{path}: family names use a-z, 0-9 and '_' only")
            before = found.get(path.stem)
            if before is not None and before != path:
                if before.parent.resolve() != SCENARIOS_DIR.resolve():
                    raise InputError(f"{path}: family {path.stem!r} is already defined in {before}")
                if path not in _noticed:
                    _noticed.add(path)
                    print(f"notice: {path} replaces the built-in {path.stem}", file=sys.stderr)
            found[path.stem] = path
    return found


MAX_FAMILY_BYTES = 1_000_000
VALUE_NAME = r"[a-z0-9][a-z0-9_-]*(\.[a-z0-9_-]+)*"  # e.g. "univ", "0.1": safe in file names
_FAMILY_KEYS = {"description", "generator", "knob", "seed_offset", "knobs", "splits", "values"}
_FAMILY_KEYS |= {"unit", "windows", "train", "model", "data_root", "download"}
UNITS = {"m": "metres", "px": "pixels"}  # what a family's positions are in


def toml_table(raw: dict, key: str, path: Path) -> dict:
    """``raw[key]`` when it is a TOML table (empty when absent), else an InputError."""
    value = raw.get(key, {})
    if not isinstance(value, dict):
        raise InputError(f"{path}: {key!r} must be a table")
    return value


def window_options(table: dict[str, Any], where: str, base: Windowing | None = None) -> Windowing:
    """The ``[windows]`` table (or ``--set data.windows.*``) over ``base``, checked."""
    for key, value in table.items():
        whole = key in ("stride", "min_agents")
        kind = int if whole else int | float
        if key in WINDOW_RANGES and (isinstance(value, bool) or not isinstance(value, kind)):
            raise InputError(f"{where}: windows.{key}={value!r}: expected {WINDOW_RANGES[key]}")
    return build(Windowing, {**vars(base or Windowing()), **table}, f"{where} [windows]")


def _read_toml(path: Path) -> dict[str, Any]:
    """A family file's table, or one line saying why it cannot be read."""
    if not path.is_file():  # a FIFO or a device named *.toml would block or never end
        raise InputError(f"{path}: a family file must be a regular file")
    if path.stat().st_size > MAX_FAMILY_BYTES:
        raise InputError(f"{path}: larger than {MAX_FAMILY_BYTES // 1000} kB; no family is")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
        raise InputError(f"{path}: cannot read family file: {error}") from None
    except RecursionError:
        raise InputError(f"{path}: cannot read family file: nested too deeply") from None


def load_family(path: Path) -> Family:
    """Read and check one family TOML file; every unknown key is an error."""
    raw = _read_toml(path)
    unknown = sorted(set(raw) - _FAMILY_KEYS)
    if unknown:
        raise InputError(
            f"{path}: unknown key {unknown[0]!r}{did_you_mean(unknown[0], _FAMILY_KEYS)} "
            f"(allowed: {', '.join(sorted(_FAMILY_KEYS))})"
        )
    if not isinstance(raw.get("generator"), str):
        raise InputError(f"{path}: 'generator' must be the name of a generator, e.g. \"crowd\"")
    generator = get_generator(raw["generator"], where=str(path))
    knob_names = {f.name for f in dataclasses.fields(generator.Knobs)}
    defaults = raw.get("knobs", {})
    values = raw.get("values", {})
    knob = raw.get("knob")
    if not isinstance(defaults, dict) or not isinstance(values, dict):
        raise InputError(f"{path}: 'knobs' and 'values' must be tables")
    if (knob is None) == (not values):
        raise InputError(f"{path}: give either 'knob' (numeric values) or [values.NAME] tables")
    if knob is not None and (not isinstance(knob, str) or knob not in knob_names):
        raise InputError(f"{path}: knob {knob!r} is not a knob of generator {raw['generator']!r}")
    for name, table in values.items():
        if not re.fullmatch(VALUE_NAME, name) or not isinstance(table, dict):
            raise InputError(f"{path}: bad value table {name!r}")
    windowing = window_options(toml_table(raw, "windows", path), str(path))
    unit = raw.get("unit", "m")
    if unit not in UNITS:
        raise InputError(f"{path}: unit {unit!r}: expected one of {', '.join(UNITS)}")
    data_root, download = raw.get("data_root", ""), raw.get("download", "")
    if not isinstance(data_root, str) or not re.fullmatch(r"[a-z0-9_]*", data_root):
        raise InputError(f"{path}: data_root {data_root!r}: a folder name of a-z, 0-9 and '_'")
    if data_root and not (isinstance(download, str) and download):
        raise InputError(f"{path}: a family with a data_root says what to download there")
    seed_offset = raw.get("seed_offset", 0)
    if isinstance(seed_offset, bool) or not isinstance(seed_offset, int) or seed_offset < 0:
        raise InputError(f"{path}: seed_offset must be a non-negative integer")
    family = Family(
        name=path.stem,
        path=path,
        generator=raw["generator"],
        description=str(raw.get("description", "")),
        knob=knob,
        seed_offset=seed_offset,
        defaults=defaults,
        splits=build(Splits, toml_table(raw, "splits", path), f"{path} [splits]"),
        values=values,
        unit=unit,
        windowing=windowing,
        train=toml_table(raw, "train", path),
        model=toml_table(raw, "model", path),
        data_root=data_root,
        download=str(download),
    )
    if not values:  # the defaults alone must already be a valid knob set
        build(generator.Knobs, defaults, f"{path} [knobs]")
    return family
