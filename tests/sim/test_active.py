"""The active curriculum: strategies that choose differently from the same scenes."""

import numpy as np
import pytest

from c2inet.checker import CHECK_CONFIG, turning_tasks
from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.stream import StreamLearner
from sim.experiment import Execution, ExperimentConfig
from sim.studies import active
from sim.study import main


def quick(scenario: str, *methods: str) -> ExperimentConfig:
    return ExperimentConfig(scenario, methods=methods, quick=True, record=False)


def test_active_strategies_choose_differently_and_draw_the_same_scenes(tmp_path):
    config = quick("crowd_noise_0.1..0.6", "finetune")
    options = active.ActiveOptions(rounds=3, scenes=4, random_orders=2)
    report = active.run_active(config, options, Execution(cache=tmp_path / "cache"))
    runs = report["strategies"]
    assert runs["fixed"]["chosen"] == [[0, 2, 5]] and set(runs) == set(active.STRATEGIES)
    assert all(chosen[0] == 0 for s in runs.values() for chosen in s["chosen"])
    assert runs["random"]["runs"] == 2
    assert runs["error"]["mean"][0] == runs["fixed"]["mean"][0]  # the same first round
    assert len({tuple(s["chosen"][0]) for s in runs.values()}) > 1
    specs = active.grid_specs(config)
    source = active.SceneSource(specs, 3, 0)
    np.testing.assert_array_equal(source.draw(1, 2).positions, source.draw(1, 2).positions)
    assert not np.array_equal(source.draw(1, 2).positions, source.draw(2, 2).positions)
    active.Active().write(report, tmp_path / "out")
    assert "final worst ADE" in (tmp_path / "out" / "active.md").read_text()


def test_needs_rank_grid_values_by_error_relative_error_and_spread():
    tasks = turning_tasks((0.05, 0.4))
    learner = StreamLearner(get_method("finetune")(ModelConfig()), CHECK_CONFIG)
    learner.learn(tasks[0].train)
    errors = active.need("error", learner, tasks, 0, [1.0, 1.0])
    assert errors[1] > errors[0]  # the unseen, sharper turn is worse
    relative = active.need("relative", learner, tasks, 0, [1.0, 4 * errors[1] / errors[0]])
    np.testing.assert_allclose(relative, [errors[0], errors[0] / 4])  # its ranking flips
    assert all(s > 0 for s in active.need("spread", learner, tasks, 0, [1.0, 1.0]))


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--scenario", "crowd_noise_0.1", "--quick"], "an active curriculum's grid"),
        (["--scenario", "eth_ucy_eth,hotel", "--quick"], "an active curriculum's grid"),
        (["--scenario", "crowd_noise_0.1,0.2", "--strategies", "best"], "best"),
    ],
)
def test_bad_input_is_one_error_line(tmp_path, capsys, argv, message):
    assert main(["active", *argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@pytest.mark.parametrize(
    ("strategies", "message"),
    [(("error", "error"), "named twice"), (("guess",), "not one of"), ((), "none given")],
)
def test_strategies_are_named_once_each_from_the_known_ones(strategies, message):
    """Issue 26, item 12: ``--strategies error,error`` ran the same strategy twice."""
    from c2inet.errors import InputError

    with pytest.raises(InputError, match=message):
        active.ActiveOptions(strategies=strategies)
