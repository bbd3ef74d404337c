"""The one builder of typed option dataclasses, from TOML or command-line mappings: family knobs,
``--set`` overrides, and the learner's model, train and method options all pass through
:func:`build`, so no path is looser than another. Unknown keys and wrong types fail here (1.5 is
no integer); each dataclass checks its own ranges in ``__post_init__`` with :func:`check_range`,
so a configuration built in Python is held to the same ranges."""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from typing import Any, TypeVar

from c2inet.errors import InputError, did_you_mean

T = TypeVar("T")


def _coerce(value: Any, kind: Any, where: str, key: str) -> Any:
    origin = typing.get_origin(kind)
    if origin in (types.UnionType, typing.Union):
        options = typing.get_args(kind)
        if value is None and type(None) in options:
            return None
        kind = next(k for k in options if k is not type(None))
        origin = typing.get_origin(kind)
    if origin in (list, tuple):
        if not isinstance(value, list | tuple):
            raise InputError(f"{where}: {key!r} must be a list, got {value!r}")
        (item,) = typing.get_args(kind)[:1]
        return tuple(_coerce(v, item, where, key) for v in value)
    if kind is bool:
        if not isinstance(value, bool):
            raise InputError(f"{where}: {key!r} must be true or false, got {value!r}")
        return value
    if kind is int:
        whole = isinstance(value, int) or (
            isinstance(value, float) and math.isfinite(value) and value.is_integer()
        )
        if isinstance(value, bool) or not whole:
            raise InputError(f"{where}: {key!r} must be an integer, got {value!r}")
        return int(value)
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputError(f"{where}: {key!r} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise InputError(f"{where}: {key!r} must be finite, got {value!r}")
        return float(value)
    if kind is str:
        if not isinstance(value, str):
            raise InputError(f"{where}: {key!r} must be a string, got {value!r}")
        return value
    return value


def build(cls: type[T], mapping: dict[str, Any], where: str) -> T:
    """Build dataclass ``cls`` from ``mapping``: unknown keys and wrong types are errors.

    ``where`` names the input (a file, a scenario part) in the error message. The dataclass's own
    ``__post_init__`` checks value ranges and raises :class:`InputError` itself.
    """
    hints = typing.get_type_hints(cls)
    fields = {f.name for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(mapping) - fields)
    if unknown:
        raise InputError(
            f"{where}: unknown key {unknown[0]!r}{did_you_mean(unknown[0], fields)} "
            f"(allowed: {', '.join(sorted(fields))})"
        )
    values = {key: _coerce(value, hints[key], where, key) for key, value in mapping.items()}
    try:
        return cls(**values)
    except InputError as error:
        raise InputError(f"{where}: {error}") from None
    except TypeError as error:
        raise InputError(f"{where}: {error}") from None


def check_range(name: str, value: float, low: float, high: float, *, open_low=False) -> None:
    """Raise InputError unless low <= value <= high (or low < value when ``open_low``)."""
    ok = (value > low if open_low else value >= low) and value <= high
    if not ok:
        bracket = "(" if open_low else "["
        raise InputError(f"{name}={value:g} is out of range {bracket}{low:g}, {high:g}]")


def require(options: Any, low: float, *names: str, high: float = math.inf, open_low=False) -> None:
    """:func:`check_range` for each named field of ``options``: ``low <= value <= high``."""
    for name in names:
        check_range(name, getattr(options, name), low, high, open_low=open_low)


def choose(options: Any, name: str, allowed: tuple[str, ...]) -> None:
    """Raise InputError unless the field ``name`` of ``options`` is one of ``allowed``."""
    value = getattr(options, name)
    if value not in allowed:
        raise InputError(f"{name} {value!r}: expected one of {', '.join(allowed)}")


@dataclass(frozen=True)
class Tunable:
    """A range a tuner may search for one option: [low, high], on a log scale if ``log``,
    whole numbers if ``integer``. Declared beside the options it tunes (``Method.search_space``)
    so that every method is tuned over its own key knobs with the same budget."""

    low: float
    high: float
    log: bool = False
    integer: bool = False

    def __post_init__(self):
        if not self.low < self.high or (self.log and self.low <= 0):
            raise ValueError(f"bad range [{self.low}, {self.high}] (log={self.log})")

    def holds(self, value: Any) -> bool:
        return self.low <= value <= self.high


@dataclass(frozen=True)
class Choice:
    """A set of values a tuner may choose one of for an option (a switch, a named design)."""

    values: tuple[Any, ...]

    def __post_init__(self):
        if len(self.values) < 2 or len(set(self.values)) != len(self.values):
            raise ValueError(f"a choice needs two distinct values or more, got {self.values}")

    def holds(self, value: Any) -> bool:
        return value in self.values
