"""The studies no fixed dataset allows: drift without boundaries, forgetting against shift size,
an active curriculum. Each writes its table, JSON and figure, and its parts are live."""

import json

import numpy as np
import pytest

from c2inet.checker import CHECK_CONFIG, turning_tasks
from c2inet.errors import InputError
from c2inet.methods.base import get_method
from c2inet.model import ModelConfig
from c2inet.stream import StreamLearner
from sim import active, drift, shift
from sim.experiment import Execution, ExperimentConfig


def quick(scenario: str, *methods: str) -> ExperimentConfig:
    return ExperimentConfig(scenario, methods=methods, quick=True, record=False)


def test_the_drift_stream_drifts_and_does_not_depend_on_its_chunking():
    specs = drift.drift_specs(quick("crowd_noise_0.1,0.6", "finetune"))
    chunks, middles = drift.drift_stream(specs, drift.DriftOptions(scenes=12, chunks=3), 0)
    assert len(chunks) == 3 and sum(len(c) for c in chunks) == 12
    assert np.all(np.diff(middles) > 0) and 0.1 <= middles[0] < middles[-1] <= 0.6
    whole, _ = drift.drift_stream(specs, drift.DriftOptions(scenes=12, chunks=1), 0)
    np.testing.assert_array_equal(whole[0].positions, np.concatenate([c.positions for c in chunks]))
    turning = [np.abs(np.diff(np.diff(c.positions, axis=1), axis=1)).mean() for c in chunks]
    assert turning[-1] > turning[0]  # more behavioural noise later in the stream


def test_drift_report_gives_boundaries_by_mode_and_marks_who_needs_them(tmp_path):
    config = quick("crowd_noise_0.1..0.6", "finetune", "ewc")
    reports = {
        mode: drift.run_drift(config, drift.DriftOptions(boundaries=mode), tmp_path / "cache")
        for mode in ("none", "chunks")
    }
    chunks = reports["none"]["chunks"]
    assert reports["none"]["methods"]["ewc"]["given"] == [0]
    assert reports["chunks"]["methods"]["ewc"]["given"] == list(range(chunks))
    assert reports["none"]["methods"]["ewc"]["needs_boundaries"]
    assert not reports["none"]["methods"]["finetune"]["needs_boundaries"]
    ewc = [np.asarray(reports[mode]["methods"]["ewc"]["ade"]) for mode in ("none", "chunks")]
    assert ewc[0].shape == (chunks, 6) and not np.array_equal(ewc[0], ewc[1])  # EWC woke up
    drift.write_drift(reports["chunks"], tmp_path / "out")
    assert "needs boundaries" in (tmp_path / "out" / "drift.md").read_text()
    assert json.loads((tmp_path / "out" / "drift.json").read_text())["boundaries"] == "chunks"
    assert (tmp_path / "out" / "drift.png").read_bytes()[:4] == b"\x89PNG"


def test_forgetting_without_boundaries_counts_from_where_the_stream_reached_a_probe():
    errors = np.array([[0.5, 0.9], [0.2, 0.8], [0.4, 0.3]])
    lost = drift.forgetting(errors, np.array([0.1, 0.3, 0.5]), [0.1, 0.4])
    np.testing.assert_allclose(lost, [0.4 - 0.2, 0.0])


def test_shift_runs_two_task_curricula_and_measures_both_shifts(tmp_path):
    base = quick("crowd_noise_0.1,0.3,0.6", "finetune")
    summary = shift.run_shift(["crowd_noise_0.1,0.3,0.6"], base, tmp_path, Execution(workers=1))
    (family,) = summary["families"]
    assert [r["domain"] for r in family["rows"]] == ["crowd_noise_0.3", "crowd_noise_0.6"]
    distance = [r["statistics_distance"] for r in family["rows"]]
    assert 0 < distance[0] < distance[1]  # a larger knob shift moves the statistics further
    cells = [r["methods"]["finetune"] for r in family["rows"]]
    assert all(np.isfinite(c["forgetting"]) and np.isfinite(c["gap"]) for c in cells)
    assert family["peaks"]["finetune"]["shift"] in (0.2, 0.5)
    assert (tmp_path / "shift.png").read_bytes()[:4] == b"\x89PNG"
    assert "forgets most" in (tmp_path / "shift.md").read_text()


def test_shift_needs_a_base_and_shifted_values():
    with pytest.raises(InputError, match="base value first"):
        shift.shift_grid("crowd_noise_0.1", [])
    with pytest.raises(InputError, match="base value first"):
        shift.shift_grid("eth_ucy_eth,hotel", [])


def test_active_strategies_choose_differently_and_draw_the_same_scenes(tmp_path):
    config = quick("crowd_noise_0.1..0.6", "finetune")
    options = active.ActiveOptions(rounds=3, scenes=4, random_orders=2)
    report = active.run_active(config, options, tmp_path / "cache")
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
    active.write_active(report, tmp_path / "out")
    assert "final worst ADE" in (tmp_path / "out" / "active.md").read_text()


@pytest.mark.parametrize(
    "command,argv,message",
    [
        (drift.main, ["--scenario", "eth_ucy_eth,hotel"], "one simulated family"),
        (drift.main, ["--scenario", "crowd_noise_0.1..0.3", "--chunks", "0"], "--chunks"),
        (active.main, ["--scenario", "crowd_noise_0.1", "--quick"], "a grid"),
        (active.main, ["--scenario", "crowd_noise_0.1,0.2", "--strategies", "best"], "best"),
    ],
)
def test_bad_input_is_one_error_line(tmp_path, capsys, command, argv, message):
    assert command([*argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_needs_rank_grid_values_by_error_relative_error_and_spread():
    tasks = turning_tasks((0.05, 0.4))
    learner = StreamLearner(get_method("finetune")(ModelConfig()), CHECK_CONFIG)
    learner.learn(tasks[0].train)
    errors = active.need("error", learner, tasks, 0, [1.0, 1.0])
    assert errors[1] > errors[0]  # the unseen, sharper turn is worse
    relative = active.need("relative", learner, tasks, 0, [1.0, 4 * errors[1] / errors[0]])
    np.testing.assert_allclose(relative, [errors[0], errors[0] / 4])  # its ranking flips
    assert all(s > 0 for s in active.need("spread", learner, tasks, 0, [1.0, 1.0]))
