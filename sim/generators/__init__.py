"""The generators: one module each (crowd, traffic, recorded files), registered by defining
their class (``sim.generators.base``) and checked by ``sim.generators.checker``."""

from sim.generators.base import GENERATORS, Generator, child_seed, discover, get_generator

__all__ = ["GENERATORS", "Generator", "child_seed", "discover", "get_generator"]
