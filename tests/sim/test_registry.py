"""The registry kit: every extension point discovered in its package and in its entry-point
group, one wording for an unknown name, plugins held to their kind and to their checker."""

import importlib.metadata
from importlib.metadata import EntryPoint

import pytest

from c2inet.backbones.base import REGISTRY as BACKBONES
from c2inet.errors import InputError
from c2inet.methods.base import REGISTRY as METHODS
from c2inet.registry import UnknownName
from sim.cli import listing
from sim.generators.base import REGISTRY as GENERATORS
from sim.generators.checker import GeneratorCheckError, check_generator
from sim.studies.base import REGISTRY as STUDIES
from sim.studies.benchmark.presets import REGISTRY as PRESETS
from viz.loggers import REGISTRY as LOGGERS
from viz.loggers.checker import LoggerCheckError, check_logger

KINDS = {
    "method": METHODS,
    "backbone": BACKBONES,
    "generator": GENERATORS,
    "study": STUDIES,
    "logger": LOGGERS,
    "preset": PRESETS,
}
KIND_GROUPS = {registry.group for registry in KINDS.values()}


@pytest.fixture
def entry_points(monkeypatch):
    """Give each group the entry points a test names; every registry restored after it."""
    given: dict[str, list[EntryPoint]] = {}
    real = importlib.metadata.entry_points

    def entry_points(**selection):  # the registries' groups given; others (numba's) as they are
        group = selection.get("group")
        return given.get(group, []) if group in KIND_GROUPS else real(**selection)

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    with (
        METHODS.isolated(),
        BACKBONES.isolated(),
        GENERATORS.isolated(),
        STUDIES.isolated(),
        LOGGERS.isolated(),
        PRESETS.isolated(),
    ):
        for registry in KINDS.values():
            registry.skipped.clear()
        yield given


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_kind_answers_an_unknown_name_in_one_wording(kind):
    registry = KINDS[kind]
    known = registry.names()
    name = known[0][:-1]  # a near miss
    with pytest.raises(UnknownName) as error:
        registry.get(name)
    assert str(error.value).startswith(f"{kind} {name!r}: unknown; did you mean")
    assert isinstance(error.value, InputError) and isinstance(error.value, KeyError)
    assert f"(known: {', '.join(known)})" in str(error.value)


def test_a_plugin_generator_is_discovered_listed_and_failed_by_its_checker(entry_points):
    entry_points["sim.generators"] = [
        EntryPoint("seedless-crowd", "plugin_parts:SeedlessCrowd", "sim.generators"),
    ]
    generator = GENERATORS.get("seedless-crowd")
    lines = listing(["generators"], []).splitlines()
    assert any(
        line.split()[0] == "seedless-crowd" and "ignore their seed" in line for line in lines
    )
    with pytest.raises(GeneratorCheckError, match="another seed gave the same domain"):
        check_generator(generator, {"agents": 3, "frames": 24})


def test_a_plugin_study_is_discovered_and_a_wrong_object_is_one_warning(entry_points, capsys):
    entry_points["sim.studies"] = [
        EntryPoint("echo", "plugin_parts:ECHO", "sim.studies"),
        EntryPoint("nothing", "plugin_parts:NOT_A_STUDY", "sim.studies"),
    ]
    assert STUDIES.get("echo").title == "a study from a plugin"
    assert "echo" in listing(["studies"], []) and "nothing" not in STUDIES.names()
    assert "study plugin 'nothing' skipped: <object object" in capsys.readouterr().err
    STUDIES.discover()
    assert "skipped" not in capsys.readouterr().err  # once a process


def test_a_plugin_preset_is_listed_found_by_name_and_cannot_take_a_builtins(
    entry_points, capsys, monkeypatch
):
    """A benchmark preset of another package: in ``--list presets`` and ``sim.bench --help``,
    found by name; one named as a built-in is skipped with one warning."""
    from dataclasses import replace

    import plugin_parts

    from sim.studies.benchmark import presets

    monkeypatch.setattr(plugin_parts, "RADIUS", replace(plugin_parts.PLAZA, name="radius"), False)
    entry_points["sim.presets"] = [
        EntryPoint("plaza", "plugin_parts:PLAZA", "sim.presets"),
        EntryPoint("radius-too", "plugin_parts:RADIUS", "sim.presets"),
    ]
    assert PRESETS.get("plaza").tune_scenario == "crowd_noise_0.15..0.35:0.1"
    assert "a preset from a plugin" in listing(["presets"], []) and "plaza" in presets()
    assert PRESETS.get("radius").scenario == "crowd_radius_0.1..0.6"  # the built-in stays
    assert (
        "preset plugin 'radius-too' skipped: its name 'radius' is a built-in"
        in capsys.readouterr().err
    )


def test_a_plugin_logger_is_discovered_listed_used_and_held_to_the_checker(entry_points, tmp_path):
    """A logger is one file (or an entry point): found, listed, accepted by ``--logger``, made
    for a job; one that writes nothing fails the checker."""
    from sim.experiment.config import Execution
    from viz.loggers import make_loggers

    entry_points["viz.loggers"] = [
        EntryPoint("count", "plugin_parts:EventCount", "viz.loggers"),
        EntryPoint("silent", "plugin_parts:Silent", "viz.loggers"),
    ]
    lines = listing(["loggers"], []).splitlines()
    assert any(line.split()[0] == "count" and "number of events" in line for line in lines)
    assert Execution(loggers=("count",)).loggers == ("count",)  # --logger count is accepted
    (logger,) = make_loggers(("count",), tmp_path / "job", 2, ["a"])
    (tmp_path / "job").mkdir()
    logger("epoch_end", {"task": 0, "epoch": 0})
    logger.close()
    assert (tmp_path / "job" / "count.txt").read_text() == "1"
    assert check_logger(LOGGERS.get("count"), tmp_path / "a")
    with pytest.raises(LoggerCheckError, match="'silent': logged a job and wrote nothing"):
        check_logger(LOGGERS.get("silent"), tmp_path / "b")
