"""The backbone registry: ``@register("name")`` on a class adds it; :data:`REGISTRY` finds every
module of ``c2inet.backbones`` (a new file is all a new backbone needs) and the entry points of
the group ``c2inet.backbones`` (another package's backbones)."""

from __future__ import annotations

from typing import Any

from c2inet.registry import Registry


def _is_backbone(entry: Any) -> str | None:
    needs = ("context_dim", "encode", "decode")
    if isinstance(entry, type) and all(hasattr(entry, attr) for attr in needs):
        return None
    return f"{entry!r} is not a backbone class (it needs context_dim, encode and decode)"


REGISTRY: Registry[type] = Registry(
    "backbone", "c2inet.backbones", "c2inet.backbones", _is_backbone, skip=("base", "checker")
)
BACKBONES = REGISTRY.entries  # name -> class


def register(name: str):
    """Class decorator: the backbone ``name`` (a name given twice is an error)."""

    def add(cls: type) -> type:
        cls.name = name
        return REGISTRY.add(name, cls)

    return add


def discover() -> dict[str, type]:
    """Every backbone: this package's modules and the plugins of ``c2inet.backbones``."""
    return REGISTRY.discover()
