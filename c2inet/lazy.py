"""Imports paid on first use, declared at the top of the module that needs them.

A command that stops at bad input or answers ``--help`` must not pay for torch, scikit-learn or
the engine, yet a module's dependencies belong at its top, where a reader looks for them. Two
tools do both: :func:`lazy_module` (a module-level ``x = lazy_module("pkg.x")`` for
``import pkg.x as x``; the shape of PEP 810's ``lazy import``, which replaces it line for line
once the project requires Python 3.15) and :func:`lazy_exports` (a package's exported names,
PEP 562).
"""

from collections.abc import Callable
from importlib import import_module
from types import ModuleType
from typing import Any


class _LazyModule(ModuleType):
    """Stands for the module of its name until an attribute is read, then imports it.

    ``importlib.util.LazyLoader`` (and ``lazy_loader``, built on it) would import the parent
    package at once to find a submodule's spec: ``sklearn.linear_model`` would cost all of
    scikit-learn's import where it is declared. This finds nothing before the first read.
    """

    def __getattr__(self, name: str) -> Any:
        return getattr(import_module(self.__name__), name)

    def __dir__(self) -> list[str]:
        return dir(import_module(self.__name__))


def lazy_module(name: str) -> ModuleType:
    """The module ``name``, imported when one of its attributes is first read."""
    return _LazyModule(name)


def lazy_exports(package: str, homes: dict[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package`` that imports ``homes[name]`` (a module's name)
    when ``name`` is first asked for."""

    def __getattr__(name: str) -> Any:
        if name in homes:
            return getattr(import_module(homes[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
