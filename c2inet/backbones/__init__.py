"""Backbones by name: an encoder of observed displacements and a decoder of future ones.

A backbone has ``context_dim``, ``encode(obs_rel, batch) -> (N, context_dim)`` and
``decode(cond, last_rel) -> (12, S, N, 2)``; ``tests/c2inet/test_backbones.py`` checks every
registered one against that contract.
"""

from c2inet.backbones.stgat import STGAT
from c2inet.backbones.stgcnn import STGCNN

BACKBONES = {"stgat": STGAT, "stgcnn": STGCNN}
