"""The backbone registry: ``@register("name")`` on a class adds it; :func:`discover` imports
every module of ``c2inet.backbones`` so that a new file is all a new backbone needs."""

from __future__ import annotations

import importlib
import pkgutil

BACKBONES: dict[str, type] = {}
NOT_BACKBONES = {"base", "checker"}  # the package's own modules that define none


def register(name: str):
    """Class decorator: the backbone ``name`` (a name given twice is an error)."""

    def add(cls: type) -> type:
        if name in BACKBONES and BACKBONES[name] is not cls:
            raise ValueError(f"backbone name {name!r} registered twice")
        cls.name = name
        BACKBONES[name] = cls
        return cls

    return add


def discover() -> dict[str, type]:
    """Every backbone: the modules of ``c2inet.backbones`` register their classes on import."""
    package = importlib.import_module("c2inet.backbones")
    for module in pkgutil.iter_modules(package.__path__):
        if module.name not in NOT_BACKBONES:
            importlib.import_module(f"c2inet.backbones.{module.name}")
    return BACKBONES
