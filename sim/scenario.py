"""The scenario language: ``FAMILY_VALUES`` parts joined by ``+`` become an ordered curriculum.

VALUES is ``a..b`` (step from the decimals of ``a``), ``a..b:step`` or ``v1,v2,...``. FAMILY is
the stem of a TOML file in ``scenarios/`` or in an extra folder given by the user; name-valued
families (real data) take names instead of numbers.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path

from c2inet.errors import InputError
from sim.families import Family, available_families, load_family

MAX_DOMAINS = 64
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)"
_RANGE = re.compile(rf"^({_NUMBER})\.\.({_NUMBER})(?::({_NUMBER}))?$")
_NAME = re.compile(r"^[a-z0-9][a-z0-9_-]*$")


@dataclass(frozen=True)
class DomainSpec:
    """One task of a curriculum: a family and the value its knob takes."""

    family: Family
    value: float | str
    label: str  # the value as written in the domain name ("0.1", "univ")

    @property
    def name(self) -> str:
        return f"{self.family.name}_{self.label}"

    def knobs(self) -> dict:
        """The generator knobs of this domain: the family defaults with the value applied."""
        return self.family.knobs_for(self.value)


def _decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0


def _number(text: str, part: str) -> Decimal:
    try:
        value = Decimal(text)
    except InvalidOperation:
        raise InputError(f"scenario part {part!r}: {text!r} is not a number") from None
    if not value.is_finite():
        raise InputError(f"scenario part {part!r}: {text!r} is not a finite number")
    return value


def _numeric_values(values: str, part: str) -> list[tuple[float, str]]:
    match = _RANGE.match(values)
    if match:
        start_text, stop_text, step_text = match.groups()
        start, stop = _number(start_text, part), _number(stop_text, part)
        step = _number(step_text, part) if step_text else Decimal(1).scaleb(-_decimals(start_text))
        if step <= 0:
            raise InputError(f"scenario part {part!r}: the step {step} must be positive")
        if stop < start:
            raise InputError(f"scenario part {part!r}: the range {start}..{stop} is reversed")
        count = int((stop - start) / step) + 1
        if count > MAX_DOMAINS:
            raise InputError(f"scenario part {part!r}: {count} domains, more than {MAX_DOMAINS}")
        places = max(_decimals(start_text), _decimals(step_text or start_text))
        items = [start + i * step for i in range(count)]
        return [(float(v), f"{v:.{places}f}") for v in items]
    items = values.split(",")
    if any(not item for item in items):
        raise InputError(f"scenario part {part!r}: empty value in {values!r}")
    out = []
    for item in items:
        if not re.fullmatch(_NUMBER, item):
            raise InputError(f"scenario part {part!r}: {item!r} is not a number")
        out.append((float(_number(item, part)), item))
    return out


def _split_family(part: str, families: dict[str, Path]) -> tuple[str, str]:
    """The longest known family name that prefixes ``part`` followed by ``_``."""
    for name in sorted(families, key=len, reverse=True):
        if part.startswith(name + "_") and len(part) > len(name) + 1:
            return name, part[len(name) + 1 :]
    known = ", ".join(sorted(families)) or "none"
    raise InputError(f"scenario part {part!r}: unknown family (known families: {known})")


def parse_scenario(scenario: str, extra_dirs: list[Path] | None = None) -> list[DomainSpec]:
    """Parse a scenario string into an ordered curriculum of domain specs.

    Raises :class:`InputError` for anything malformed; never anything else.
    """
    if not isinstance(scenario, str) or not scenario.strip():
        raise InputError("scenario: empty; expected FAMILY_VALUES, e.g. crowd_noise_0.1..0.6")
    families = available_families(extra_dirs or [])
    curriculum: list[DomainSpec] = []
    for part in scenario.strip().split("+"):
        if not part:
            raise InputError(f"scenario {scenario!r}: empty part between '+' signs")
        name, values = _split_family(part, families)
        family = load_family(families[name])
        if family.value_names:
            labels = values.split(",")
            for label in labels:
                if label not in family.value_names:
                    known = ",".join(family.value_names)
                    raise InputError(
                        f"scenario part {part!r}: {label!r} is not a value of family "
                        f"{name!r} (known: {known})"
                    )
            specs = [DomainSpec(family, label, label) for label in labels]
        else:
            specs = [DomainSpec(family, v, label) for v, label in _numeric_values(values, part)]
        for spec in specs:
            spec.knobs()  # validates the knob value against the generator's range
            if not _NAME.match(spec.label.replace(".", "")):
                raise InputError(f"scenario part {part!r}: bad value {spec.label!r}")
        curriculum.extend(specs)
    names = [spec.name for spec in curriculum]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise InputError(f"scenario {scenario!r}: domain {duplicates[0]!r} appears twice")
    if len(curriculum) > MAX_DOMAINS:
        raise InputError(f"scenario {scenario!r}: more than {MAX_DOMAINS} domains")
    return curriculum
