"""Extension points from outside the package, as a user's own package would ship them through
entry points (``tests/sim/test_registry.py``): a generator that breaks its contract, a study, a
benchmark preset, and objects that are not what their group wants."""

import numpy as np

from sim.generators.crowd import CrowdGenerator
from sim.studies.base import Study
from sim.studies.benchmark.presets import Preset
from viz.loggers import Logger


class SeedlessCrowd(CrowdGenerator):
    """Crowds that ignore their seed: a plugin the generator checker must fail."""

    name = "seedless-crowd"

    def generate(self, name, family, knobs, splits, seed, workers=1):
        return super().generate(name, family, knobs, splits, np.random.SeedSequence(7), workers)


class Echo(Study):
    """A study of another package."""

    name = "echo"
    title = "a study from a plugin"


ECHO = Echo()
NOT_A_STUDY = object()
PLAZA = Preset(
    "plaza", "crowd_noise_0.1..0.3", "crowd_noise_0.15..0.35:0.1", "a preset from a plugin"
)


class EventCount(Logger):
    """A logger of another package: how many events a job sent."""

    name = "count"
    title = "the number of events in count.txt"

    def __init__(self, folder, epochs, tasks, **options):
        self.path, self.events = folder / "count.txt", 0

    def __call__(self, event, data):
        self.events += 1

    def close(self):
        self.path.write_text(str(self.events))


class Silent(EventCount):
    """A logger that writes nothing: the checker must fail it."""

    name = "silent"
    title = "logs nothing"

    def close(self):
        pass
