"""One registry kit for every extension point (methods, backbones, generators, studies,
loggers, benchmark presets).

A :class:`Registry` holds one kind's entries by name. :meth:`Registry.discover` imports every
module of the kind's package (a new file registers itself) and loads the entry points of the
kind's group (another package's additions, e.g. ``[project.entry-points."c2inet.methods"]``);
:meth:`Registry.get` answers an unknown name in one wording, with the did-you-mean. A plugin
whose name is not a plain name, is a built-in's, fails its kind's test or cannot even be
imported is skipped with one warning a process: it never ends a command, never replaces a
built-in and never names a folder outside ``--out``.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import pkgutil
import re
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, Generic, TypeVar

from c2inet.errors import InputError, did_you_mean

T = TypeVar("T")
PLUGIN_NAME = re.compile(r"[a-z][a-z0-9_-]{0,39}")  # a name that is also a safe folder name


class UnknownName(InputError, KeyError):
    """A name no entry of a registry has (an :class:`InputError`; a ``KeyError`` too, as a
    lookup by name)."""

    def __str__(self) -> str:
        return str(self.args[0])


def own_name(entry: Any) -> Any:
    """The name an entry declares itself: a class's own ``name`` (not one inherited from a
    built-in it subclasses), an instance's ``name``."""
    return entry.__dict__.get("name") if isinstance(entry, type) else getattr(entry, "name", None)


class Registry(Generic[T]):
    """The entries of one ``kind`` (``"method"``): those the modules of ``package`` register on
    import (``skip``: the package's modules that register none) and those of the entry-point
    ``group``; ``accepts(entry)`` says why a plugin is not one of the kind (None: it is)."""

    def __init__(
        self,
        kind: str,
        package: str,
        group: str,
        accepts: Callable[[Any], str | None] = lambda entry: None,
        skip: tuple[str, ...] = (),
    ):
        self.kind, self.package, self.group = kind, package, group
        self.accepts, self.skip = accepts, skip
        self.entries: dict[str, T] = {}
        self.skipped: set[str] = set()  # broken plugins, each said once a process
        self.loaded: set[str] = set()  # the entry points (their "module:attr") taken in

    def add(self, name: str, entry: T) -> T:
        """Register ``entry`` under ``name``; a name given to two entries is an error."""
        if not name or (name in self.entries and self.entries[name] is not entry):
            raise ValueError(f"{self.kind} name {name!r} is empty or registered twice")
        self.entries[name] = entry
        return entry

    def enrol(self, entry: T) -> T | None:
        """The front door of a class at its definition (a kind's ``__init_subclass__``): one
        defined in the kind's own package registers under its own name (a twin is an error);
        one defined anywhere else (a plugin, a test's variant, a user's script) never
        registers itself, so it can never replace an entry: a plugin comes in through its entry
        point, where a taken name is one warning."""
        name = own_name(entry)
        module = getattr(entry, "__module__", "")
        if name and (module == self.package or module.startswith(self.package + ".")):
            return self.add(name, entry)
        return None

    def discover(self) -> dict[str, T]:
        """Every entry: the package's modules, then the group's plugins."""
        package = importlib.import_module(self.package)  # or one module holding every entry
        for module in pkgutil.iter_modules(getattr(package, "__path__", ())):
            if module.name not in self.skip:
                importlib.import_module(f"{self.package}.{module.name}")
        for point in importlib.metadata.entry_points(group=self.group):
            if point.value not in self.loaded and point.name not in self.skipped:
                self._load(point)
        return self.entries

    def _load(self, point: importlib.metadata.EntryPoint) -> None:
        try:
            entry = point.load()
            why = self.accepts(entry)
            if why:
                raise TypeError(why)
            name = own_name(entry)
            if not isinstance(name, str) or not PLUGIN_NAME.fullmatch(name):
                raise TypeError(
                    f"{point.value} needs a name of its own: lower-case letters, digits, '-' "
                    f"and '_', at most 40 (got {name!r})"
                )
            if name in self.entries and self.entries[name] is not entry:
                taken = "a built-in" if self._built_in(name) else "another plugin's"
                raise TypeError(f"its name {name!r} is {taken} {self.kind}'s; choose another")
        except (Exception, SystemExit) as error:  # a third party's code: whatever it raises
            why = f"it exited ({error.code})" if isinstance(error, SystemExit) else error
            print(f"warning: {self.kind} plugin {point.name!r} skipped: {why}", file=sys.stderr)
            self.skipped.add(point.name)
            return
        self.entries[name] = entry
        self.loaded.add(point.value)

    def _built_in(self, name: str) -> bool:
        module = getattr(self.entries[name], "__module__", "") or ""
        return module == self.package or module.startswith(self.package + ".")

    def get(self, name: str) -> T:
        """The entry called ``name``; an :class:`UnknownName` naming the known ones."""
        entries = self.discover()
        if name not in entries:
            raise UnknownName(
                f"{self.kind} {name!r}: unknown{did_you_mean(name, entries)} "
                f"(known: {', '.join(sorted(entries))})"
            )
        return entries[name]

    def names(self) -> list[str]:
        return sorted(self.discover())

    def describe(self) -> str:
        """One line per entry: its name and the first line of its docstring."""
        return "\n".join(f"{name:16} {first_line(self.entries[name])}" for name in self.names())

    @contextmanager
    def isolated(self) -> Iterator[Registry[T]]:
        """The entries and skipped plugins restored as they were after the block (tests that
        add plugins)."""
        entries, skipped, loaded = dict(self.entries), set(self.skipped), set(self.loaded)
        try:
            yield self
        finally:
            for kept, now in (
                (entries, self.entries),
                (skipped, self.skipped),
                (loaded, self.loaded),
            ):
                now.clear()
                now.update(kept)


def first_line(entry: Any) -> str:
    """The first line of an entry's docstring; a plugin may have none."""
    doc = entry.__doc__ if isinstance(entry, type) else type(entry).__doc__
    doc = getattr(entry, "title", "") or doc  # a study's one-line title, where it has one
    return ((doc or "").strip().splitlines() or ["(no description)"])[0]
