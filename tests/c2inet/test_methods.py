"""Every registered method against the library's checker (as Gymnasium's env checker), and the
checker itself against methods broken on purpose: each check must be able to fail.

The broken methods here override ``before_backward`` and one more hook left unnamed on purpose.
Example: ``pytest tests/c2inet/test_methods.py``
"""

import importlib.metadata
import random
from importlib.metadata import EntryPoint

import pytest
import torch

from c2inet.checker import MethodCheckError, check_method
from c2inet.methods import base
from c2inet.methods.base import PLUGINS, discover, get_method
from c2inet.methods.ewc import EWC
from c2inet.methods.finetune import Finetune
from c2inet.methods.lwf import LwF
from c2inet.methods.si import SI
from c2inet.options import Tunable
from c2inet.trainer import ContinualTrainer

METHODS = discover()


@pytest.mark.parametrize("name", sorted(METHODS))
def test_every_method_passes_the_checker(name):
    """Contract, metrics, determinism, resume after any task, no peeking, live mechanism."""
    check_method(METHODS[name])


def test_the_paper_baselines_and_the_staples_are_registered():
    paper = {"mog", "counterfactual", "invariant", "adaptive", "pecnet", "gcrl", "ewc", "coresets"}
    staples = {"lwf", "si", "agem", "derpp"}
    assert paper | staples | {"finetune", "joint", "cv", "c2inet-online"} <= set(METHODS)


class InertLwF(LwF):
    """LwF whose distillation never runs."""

    name = "test-inert-lwf"

    def before_backward(self, ctx):
        pass


class Forgetful(SI):
    """SI that saves nothing between tasks: a resumed run loses its importance."""

    name = "test-forgetful-si"

    def state_dict(self, model):
        return {}

    def load_state_dict(self, state, model):
        pass


class Noisy(Finetune):
    """Fine-tuning with a term drawn from the operating system's randomness."""

    name = "test-noisy"

    def before_backward(self, ctx):
        ctx.add_loss("noise", 1e-3 * random.SystemRandom().random() * ctx.loss)


class DeviceBound(Finetune):
    """Fine-tuning with a penalty made on the default device, not the model's: on a GPU it fails
    (a CPU tensor added to a GPU loss), so the checker must catch it on the CPU too."""

    name = "test-device-bound"

    def before_backward(self, ctx):
        ctx.add_loss("penalty", torch.zeros(()))


class Undocumented(EWC):
    """EWC with an extra hook its module's docstring does not name."""

    name = "test-undocumented"

    def after_step(self, ctx):
        pass


class MisTuned(EWC):
    """EWC whose searched range leaves out its default, and names an option it lacks."""

    name = "test-mistuned"
    search_space = {"strength": Tunable(1e5, 1e6, log=True)}


class Misspelt(EWC):
    """EWC that searches a model option no model has."""

    name = "test-misspelt"
    search_space = {"model.beta_q": Tunable(0.1, 1.0)}


@pytest.mark.parametrize(
    "cls, message",
    [
        (MisTuned, "outside its searched range"),
        (Misspelt, "no option of it"),
        (InertLwF, "inert"),
        (Forgetful, "resumed after task"),
        (Noisy, "same seed"),
        (DeviceBound, r"without naming a device at .*test_methods.py:\d+"),
        (Undocumented, "after_step"),
    ],
)
def test_the_checker_catches_broken_methods(cls, message):
    with pytest.raises(MethodCheckError, match=message):
        check_method(cls)
    assert cls.name not in METHODS


def test_the_checker_fails_a_c2inet_whose_queue_prior_cannot_act(monkeypatch):
    """With 8 free nats (the earlier default) KL_C has no gradient on the checker's scenes, so
    switching Eq 17 off changes nothing: C2INet's declared mechanism is inert, and it fails."""
    import dataclasses

    from c2inet import checker
    from c2inet.model_config import ModelConfig

    @dataclasses.dataclass
    class EightFreeNats(ModelConfig):
        free_bits_c: float = 8.0

    monkeypatch.setattr(checker, "ModelConfig", EightFreeNats)
    cls, tasks = METHODS["c2inet-online"], checker.turning_tasks(turns=(0.1, 0.2, 0.3))
    whole, _ = checker._run(cls, tasks)
    with pytest.raises(MethodCheckError, match=r"options \{'eq17': False\} change nothing"):
        checker.check_live(cls, tasks, whole)


def test_the_checker_catches_a_trainer_that_leaks_later_tasks(monkeypatch):
    """Were the joint reference handed every other task, not just the earlier ones."""

    def leaky(self, index):
        return [t.train for j, t in enumerate(self.tasks) if j != index]

    monkeypatch.setattr(ContinualTrainer, "earlier_training_data", leaky)
    with pytest.raises(MethodCheckError, match="the last task.s training data"):
        check_method(METHODS["joint"])


@pytest.fixture
def methods_registry():
    """The method registry restored after the test: the plugins it adds leave with it."""
    with base.REGISTRY.isolated() as registry:
        registry.skipped.clear()
        yield registry


def test_a_method_of_another_package_joins_through_its_entry_point(
    monkeypatch, capsys, methods_registry
):
    """A user's package declares ``shrinking = "plugin_method:Shrinking"`` in the entry-point
    group ``c2inet.methods``: the registry finds it, the checker passes it; a broken entry point
    is one warning and the rest still works."""
    entries = [
        EntryPoint("shrinking", "plugin_method:Shrinking", PLUGINS),
        EntryPoint("broken", "plugin_method:Nowhere", PLUGINS),
    ]
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: entries)
    methods = discover()
    assert "shrinking" in methods and "broken" not in methods
    assert "method plugin 'broken' skipped" in capsys.readouterr().err
    discover()
    get_method("shrinking")
    assert "skipped" not in capsys.readouterr().err  # said once a process, not at every look-up
    check_method(get_method("shrinking"))


@pytest.mark.parametrize(
    ("entry", "why"),
    [
        ("plugin_method:Impostor", "needs a name of its own"),  # would inherit 'finetune'
        ("plugin_method:Taker", "is a built-in method's"),
        ("plugin_method:Escaper", "needs a name of its own"),  # a path, not a name
    ],
)
def test_a_plugin_cannot_take_a_built_ins_name_or_a_name_that_is_a_path(
    monkeypatch, capsys, entry, why, methods_registry
):
    monkeypatch.setattr(
        importlib.metadata, "entry_points", lambda group: [EntryPoint("odd", entry, PLUGINS)]
    )
    methods = discover()
    assert methods["finetune"] is Finetune and "../../escaped" not in methods
    assert why in capsys.readouterr().err


def test_a_plugin_named_like_a_built_in_never_replaces_it_and_a_good_one_warns_nothing(
    monkeypatch, capsys, methods_registry, tmp_path
):
    """Issue 64's case: a plugin ``finetune`` (importing its module defines a class of that
    name) is one warning, and ``--methods finetune`` runs the built-in; a second plugin of a
    name already taken by a plugin is one warning too; a plugin written as the docs say loads
    and runs without a word (issue 65's false warning)."""
    from sim.run import main

    entries = [
        EntryPoint("shrinking", "plugin_method:Shrinking", PLUGINS),
        EntryPoint("finetune", "plugin_method:Taker", PLUGINS),
        EntryPoint("shrinking2", "plugin_method:Shrinking", PLUGINS),
        EntryPoint("twin", "plugin_method:ShrinkingTwin", PLUGINS),
    ]
    real = importlib.metadata.entry_points  # torch asks for its own groups while it trains

    def ours(group=None, **kwargs):
        return (
            entries if group == PLUGINS else real(**kwargs, **({"group": group} if group else {}))
        )

    monkeypatch.setattr(importlib.metadata, "entry_points", ours)
    argv = ["--scenario", "crowd_noise_0.1", "--methods", "finetune,shrinking", "--quick"]
    assert main([*argv, "--no-record", "--out", str(tmp_path / "run")]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "skipped" in line]
    assert len(err) == 2, err
    assert "'finetune' skipped: its name 'finetune' is a built-in method's" in err[0]
    assert "'twin' skipped: its name 'shrinking' is another plugin's method's" in err[1]
    assert get_method("finetune") is Finetune
    assert get_method("shrinking").__module__ == "plugin_method"


def test_a_plugin_that_exits_at_import_or_has_no_docstring_ends_no_command(
    monkeypatch, capsys, methods_registry
):
    from sim.cli import listing

    entries = [
        EntryPoint("exits", "plugin_method:exiting", PLUGINS),  # load() returns it; call below
        EntryPoint("undocumented", "plugin_method:Undocumented", PLUGINS),
    ]
    real_load = EntryPoint.load

    def load(entry):
        loaded = real_load(entry)
        return loaded() if entry.name == "exits" else loaded

    monkeypatch.setattr(EntryPoint, "load", load)
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: entries)
    assert "undocumented     (no description)" in listing(["methods"], [])
    assert "method plugin 'exits' skipped: it exited (3)" in capsys.readouterr().err
