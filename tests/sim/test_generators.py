"""Every registered generator against the same contract (as Gymnasium's env checker), and the
checker catching generators broken on purpose."""

import dataclasses
import re

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.families import SCENARIOS_DIR, Splits, available_families, load_family
from sim.generators import discover
from sim.generators.checker import GeneratorCheckError, check_domain, check_generator
from sim.generators.crowd import CrowdGenerator, CrowdKnobs

GENERATORS = discover()
SMALL = {"agents": 3, "frames": 24}


def family_knobs(generator: str) -> dict:
    """Knobs of the first shipped family of ``generator``, small."""
    families = [load_family(p) for p in available_families([]).values()]
    family = next(f for f in families if f.generator == generator)
    value = family.value_names[0] if family.values else 0.3
    knobs = family.knobs_for(1.0 if family.knob == "vehicles_density" else value)
    return {**knobs, "seconds": 9.0, "vehicles": 5} if generator == "traffic" else knobs


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_every_registered_generator_passes_the_checker(name):
    assert set(GENERATORS) >= {"crowd", "traffic", "files"}
    check_generator(GENERATORS[name], family_knobs(name))


@dataclasses.dataclass(frozen=True)
class UncheckedKnobs(CrowdKnobs):
    def __post_init__(self):  # declares no range
        pass


class Unranged(CrowdGenerator):
    """Crowd knobs without their ranges."""

    Knobs = UncheckedKnobs


class Unseeded(CrowdGenerator):
    """Ignores its seed."""

    def generate(self, name, family, knobs, splits, seed, workers=1):
        return super().generate(name, family, knobs, splits, np.random.SeedSequence(7), workers)


class Unrepeatable(CrowdGenerator):
    """Draws from the global random state."""

    def generate(self, name, family, knobs, splits, seed, workers=1):
        noise = int(np.random.default_rng().integers(1 << 30))
        return super().generate(name, family, knobs, splits, np.random.SeedSequence(noise))


class Hungry(CrowdGenerator):
    """Allocates far beyond its memory estimate."""

    def generate(self, name, family, knobs, splits, seed, workers=1):
        scratch = np.ones(20_000_000)  # 160 MB
        domain = super().generate(name, family, knobs, splits, seed, workers)
        domain.stats["scratch"] = float(scratch[0])
        return domain


class Statless(CrowdGenerator):
    """Forgets a statistic the reports read."""

    def generate(self, name, family, knobs, splits, seed, workers=1):
        domain = super().generate(name, family, knobs, splits, seed, workers)
        del domain.stats["density"]
        return domain


class Short(CrowdGenerator):
    """Scenes too short for one learner window."""

    def generate(self, name, family, knobs, splits, seed, workers=1):
        return super().generate(name, family, {**knobs, "frames": 12}, splits, seed, workers)


@pytest.mark.parametrize(
    "broken,message",
    [
        (Unranged, "knob horizon=nan is accepted"),
        (Unseeded, "another seed gave the same domain"),
        (Unrepeatable, "the same seed gave another domain"),
        (Hungry, "memory estimate says"),
        (Statless, "statistics missing or not finite: density"),
        (Short, "no learner windows"),
    ],
)
def test_the_checker_catches_a_broken_generator(broken, message):
    with pytest.raises(GeneratorCheckError, match=message):
        check_generator(broken, SMALL, registered=False)
    assert broken.__name__ not in GENERATORS and GENERATORS["crowd"] is CrowdGenerator


@pytest.mark.parametrize("path", sorted(available_families([]).values()), ids=lambda p: p.stem)
def test_every_shipped_family_loads_and_generates_a_valid_domain(path, monkeypatch):
    """Every shipped family makes a valid domain; one of a dataset that cannot ship (its files
    in the data root, tests/sim/test_formats.py) says, without it, what to download."""
    family = load_family(path)
    assert family.description, f"{path.name} needs a description"
    if family.data_root:
        monkeypatch.setenv("C2I_DATA_ROOT", "")  # none given
        with pytest.raises(InputError, match=f"reads {re.escape(family.download)} from DATA_ROOT"):
            family.knobs_for(family.value_names[0])
        return
    if family.values:
        value = family.value_names[0]
    else:
        value = 1.0 if family.knob == "vehicles_density" else 0.3
    knobs = family.knobs_for(value)
    generator = GENERATORS[family.generator]
    if family.generator == "traffic":
        knobs = {**knobs, "seconds": 9.0, "vehicles": 5}
    splits = Splits(*generator.quick_splits) if family.generator != "crowd" else Splits(2, 1, 1)
    domain = generator().generate("d", family.name, knobs, splits, np.random.SeedSequence(0))
    check_domain(generator, domain)
    if family.generator != "files":  # recorded people have no radius to overlap by
        assert np.isfinite(domain.stats["overlaps"])


def test_shipped_families_live_in_the_scenarios_folder():
    names = {p.stem for p in SCENARIOS_DIR.glob("*.toml")}
    assert {
        "crowd_noise",
        "crowd_radius",
        "crowd_density",
        "eth_ucy",
        "highway_density",
        "highway_noise",
        "merge_density",
    } <= names


def test_a_domain_over_the_memory_budget_is_refused_before_generating(tmp_path):
    from sim.domains import build_domain
    from sim.scenario import parse_scenario

    spec = parse_scenario("crowd_noise_0.1", overrides={"agents": 40, "frames": 100_000})[0]
    with pytest.raises(InputError, match=r"needs about 1\d\d GB, more than the memory budget"):
        build_domain(spec, 0, tmp_path, memory_budget=12.0)
    assert not list(tmp_path.iterdir())


def test_a_crowd_domains_windows_carry_its_bodies_contact_distance(tmp_path):
    """The crowd's discs touch at twice their radius: its tasks' windows say so (and the
    evaluation scores collisions at it); traffic knows no such distance."""
    from sim.experiment.curriculum import make_tasks
    from sim.generators import get_generator
    from sim.scenario import parse_scenario

    assert CrowdGenerator.contact({"radius": 0.25}) == 0.5
    assert get_generator("traffic").contact({}) is None
    specs = parse_scenario("crowd_radius_0.3")
    tasks, _ = make_tasks(specs, 0, True, tmp_path, 1)
    assert {tasks[0].train.contact, tasks[0].test.contact} == {0.6}
