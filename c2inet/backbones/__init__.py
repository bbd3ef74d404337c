"""Backbones by name: an encoder of observed displacements and a decoder of future ones.

A backbone has ``context_dim``, ``encode(obs_rel, batch) -> (N, context_dim)`` and
``decode(cond, last_rel) -> (12, S, N, 2)``; one file each, registered with
``@register("name")`` (``c2inet.backbones.base``) and checked by ``c2inet.backbones.checker``
(a test runs it over every registered one).
"""

from c2inet.backbones.base import BACKBONES, discover, register

discover()

__all__ = ["BACKBONES", "discover", "register"]
