"""The scenario language: ``FAMILY_VALUES`` parts joined by ``+`` become an ordered curriculum.

VALUES is ``a..b`` (step from the decimals of ``a``), ``a..b:step`` or ``v1,v2,...``. FAMILY is
the stem of a TOML file in ``sim/scenarios/`` or in an extra folder given by the user; name-valued
families (real data) take names instead of numbers, or a range where the names are numbers.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Any

from c2inet.errors import InputError, did_you_mean, quote
from c2inet.options import build
from sim.families import Family, Splits, available_families, load_family, window_options

MAX_DOMAINS = 64
MAX_LABEL = 32  # characters of a value as written in a domain name
MAX_SCENARIO = 2000  # characters of a whole scenario string, checked before any parsing
_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)"  # unambiguous: no quadratic backtracking
_RANGE = re.compile(rf"^({_NUMBER})\.\.({_NUMBER})(?::({_NUMBER}))?$")
_NAME = re.compile(r"^[a-z0-9][a-z0-9_-]*$")


@dataclass(frozen=True)
class DomainSpec:
    """One task of a curriculum: a family, the value its knob takes and the generator knobs
    that result (the family defaults with the value applied), resolved and validated once."""

    family: Family
    value: float | str
    label: str  # the value as written in the domain name ("0.1", "univ")
    knobs: dict[str, Any] = field(init=False, compare=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "knobs", self.family.knobs_for(self.value))

    @property
    def name(self) -> str:
        return f"{self.family.name}_{self.label}"


def _decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0


def _check_length(text: str, part: str) -> None:
    """Refuse a value longer than ``MAX_LABEL`` before any parsing (constant time)."""
    if len(text) > MAX_LABEL:
        raise InputError(
            f"scenario part {quote(part)}: value {quote(text, 20)} is longer than "
            f"{MAX_LABEL} characters"
        )


def _number(text: str, part: str) -> Decimal:
    _check_length(text, part)
    try:
        value = Decimal(text)
    except InvalidOperation:
        raise InputError(
            f"scenario part {quote(part)}: {quote(text, 20)} is not a number"
        ) from None
    if not value.is_finite():
        raise InputError(f"scenario part {quote(part)}: {quote(text, 20)} is not a finite number")
    return value


def _numeric_values(values: str, part: str) -> list[tuple[float, str]]:
    match = _RANGE.match(values)
    if match:
        start_text, stop_text, step_text = match.groups()
        start, stop = _number(start_text, part), _number(stop_text, part)
        step = _number(step_text, part) if step_text else Decimal(1).scaleb(-_decimals(start_text))
        if step <= 0:
            raise InputError(f"scenario part {quote(part)}: the step {step} must be positive")
        if stop < start:
            raise InputError(f"scenario part {quote(part)}: the range {start}..{stop} is reversed")
        if (stop - start) / step >= MAX_DOMAINS:  # compared as decimals: the count may be huge
            raise InputError(f"scenario part {quote(part)}: more than {MAX_DOMAINS} domains")
        count = int((stop - start) / step) + 1
        places = max(_decimals(start_text), _decimals(step_text or start_text))
        items = [start + i * step for i in range(count)]
        return [(float(v), f"{v:.{places}f}") for v in items]
    items = values.split(",")
    if any(not item for item in items):
        raise InputError(f"scenario part {quote(part)}: empty value in {values!r}")
    out = []
    for item in items:
        _check_length(item, part)
        if not re.fullmatch(_NUMBER, item):
            hint = ""
            if re.fullmatch(rf"{_NUMBER}-{_NUMBER}", item):
                hint = f" (a range is written {item.replace('-', '..', 1)})"
            raise InputError(f"scenario part {quote(part)}: {item!r} is not a number{hint}")
        out.append((float(_number(item, part)), item))
    return out


def _split_family(part: str, families: dict[str, Path]) -> tuple[str, str]:
    """The longest known family name that prefixes ``part`` followed by ``_``."""
    for name in sorted(families, key=len, reverse=True):
        if part.startswith(name + "_") and len(part) > len(name) + 1:
            return name, part[len(name) + 1 :]
    if part.rstrip("_") in families:
        raise InputError(
            f"scenario part {quote(part)}: family {part.rstrip('_')!r} needs values, "
            f"e.g. {part.rstrip('_')}_0.1..0.3 (python -m sim.run --list knobs FAMILY)"
        )
    guess = part.rsplit("_", 1)[0] if "_" in part else part
    raise InputError(
        f"scenario part {quote(part)}: unknown family{did_you_mean(guess, families)} "
        f"(known families: {', '.join(sorted(families)) or 'none'})"
    )


def with_overrides(family: Family, overrides: dict[str, Any]) -> Family:
    """``family`` with knob defaults, split sizes (``splits.NAME`` keys) and how its scenes are
    cut into windows (``windows.stride``, ``.share``, ``.min_agents``, ``.val_share``,
    ``.val_stride``) replaced."""
    if not overrides:
        return family

    def scoped(prefix: str) -> dict[str, Any]:
        return {k.removeprefix(prefix): v for k, v in overrides.items() if k.startswith(prefix)}

    splits, windows = scoped("splits."), scoped("windows.")
    knobs = {k: v for k, v in overrides.items() if not k.startswith(("splits.", "windows."))}
    if family.knob in knobs:
        raise InputError(f"--set data.{family.knob}: that knob is what {family.name}'s values set")
    unknown = sorted(set(splits) - {"train", "val", "test"})
    if unknown:
        raise InputError(f"--set data.splits.{unknown[0]}: expected splits.train, .val or .test")
    sizes = build(Splits, {**vars(family.splits), **splits}, "--set data.splits")
    windowing = window_options(windows, "--set data", family.windowing)
    defaults = {**family.defaults, **knobs}
    return replace(family, defaults=defaults, splits=sizes, windowing=windowing)


def parse_scenario(
    scenario: str, extra_dirs: list[Path] | None = None, overrides: dict[str, Any] | None = None
) -> list[DomainSpec]:
    """Parse a scenario string into an ordered curriculum of domain specs.

    ``overrides`` change every family's knob defaults (``{"agents": 6}``) or scenes per split
    (``{"splits.train": 100}``), as ``--set data.KEY=VALUE`` gives them; they become part of
    each domain's knobs, so of its hash. Raises :class:`InputError` for anything malformed;
    never anything else.
    """
    if not isinstance(scenario, str) or not scenario.strip():
        raise InputError("scenario: empty; expected FAMILY_VALUES, e.g. crowd_noise_0.1..0.6")
    if len(scenario) > MAX_SCENARIO:
        raise InputError(f"scenario {quote(scenario)}: longer than {MAX_SCENARIO} characters")
    families = available_families(extra_dirs or [])
    curriculum: list[DomainSpec] = []
    for part in (p.strip() for p in scenario.strip().split("+")):
        if not part:
            raise InputError(f"scenario {quote(scenario)}: empty part between '+' signs")
        name, values = _split_family(part, families)
        family = with_overrides(load_family(families[name]), overrides or {})
        if family.value_names:
            ranged = _RANGE.match(values)  # numbered names (e.g. orca_radius) take ranges too
            labels = [t for _, t in _numeric_values(values, part)] if ranged else values.split(",")
            for label in labels:
                if label not in family.value_names:
                    known = ",".join(family.value_names)
                    raise InputError(
                        f"scenario part {quote(part)}: {quote(label)} is not a value of family "
                        f"{name!r} (known: {known})"
                    )
            specs = [DomainSpec(family, label, label) for label in labels]
        else:
            specs = [DomainSpec(family, v, label) for v, label in _numeric_values(values, part)]
        for spec in specs:
            if len(spec.label) > MAX_LABEL:  # the label names files: keep it short
                raise InputError(
                    f"scenario part {quote(part)}: value {quote(spec.label, 20)} is longer than "
                    f"{MAX_LABEL} characters"
                )
            if not _NAME.match(spec.label.replace(".", "")):
                raise InputError(f"scenario part {quote(part)}: bad value {spec.label!r}")
        curriculum.extend(specs)
    names = [spec.name for spec in curriculum]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise InputError(f"scenario {quote(scenario)}: domain {duplicates[0]!r} appears twice")
    seen: dict[tuple[str, Any], str] = {}  # one value under two spellings (0.1 and 00.1)
    for spec in curriculum:
        key = (spec.family.name, spec.value)
        if key in seen:
            raise InputError(
                f"scenario {quote(scenario)}: {spec.label!r} and {seen[key]!r} are one value of "
                f"family {spec.family.name!r}; name it once"
            )
        seen[key] = spec.label
    if len(curriculum) > MAX_DOMAINS:
        raise InputError(f"scenario {quote(scenario)}: more than {MAX_DOMAINS} domains")
    return curriculum
