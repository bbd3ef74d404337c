"""Backbones by name: an encoder of observed displacements and a decoder of future ones."""

from c2inet.backbones.stgat import STGAT

BACKBONES = {"stgat": STGAT}
