"""Every registered generator against the same contract (as Gymnasium's env checker)."""

import dataclasses

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.data import SPLITS, Domain
from sim.families import SCENARIOS_DIR, Splits, available_families, load_family
from sim.generators import GENERATORS, Generator, get_generator

get_generator("crowd")  # imports the built-in generators


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_generator_contract(name):
    cls = GENERATORS[name]
    assert issubclass(cls, Generator) and cls.name == name and cls.version >= 1
    assert dataclasses.is_dataclass(cls.Knobs) and cls.Knobs.__dataclass_params__.frozen
    assert cls.__doc__ and len(cls.quick_splits) == 3


@pytest.mark.parametrize("path", sorted(available_families([]).values()), ids=lambda p: p.stem)
def test_every_shipped_family_loads_and_generates_a_valid_domain(path):
    family = load_family(path)
    assert family.description, f"{path.name} needs a description"
    if family.values:
        value = family.value_names[0]
    else:
        value = 1.0 if family.knob == "vehicles_density" else 0.3
    knobs = family.knobs_for(value)
    generator = get_generator(family.generator)()
    if family.generator == "traffic":
        knobs = {**knobs, "seconds": 9.0, "vehicles": 5}
    splits = Splits(*generator.quick_splits) if family.generator != "crowd" else Splits(2, 1, 1)
    domain = generator.generate("d", family.name, knobs, splits, np.random.SeedSequence(0))
    assert isinstance(domain, Domain) and set(domain.scenes) == set(SPLITS)
    expected = {"mean_speed", "min_separation", "heading_change", "density"}
    if family.generator != "files":  # recorded people have no radius to overlap by
        expected.add("overlaps")
    assert expected <= set(domain.stats)
    assert all(np.isfinite(v) for v in domain.stats.values())
    for split in ("train", "test"):
        windows = domain.windows(split)
        assert windows is not None and np.isfinite(windows.positions).all()


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
