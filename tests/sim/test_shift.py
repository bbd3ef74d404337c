"""Forgetting against the size of the shift: two-task curricula and both measures of a shift."""

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.experiment import Execution, ExperimentConfig
from sim.studies import shift


def quick(scenario: str, *methods: str) -> ExperimentConfig:
    return ExperimentConfig(scenario, methods=methods, quick=True, record=False)


def test_shift_runs_two_task_curricula_and_measures_both_shifts(tmp_path):
    base = quick("crowd_noise_0.1,0.3,0.6", "finetune")
    summary = shift.run_shift(["crowd_noise_0.1,0.3,0.6"], base, tmp_path, Execution(workers=1))
    shift.Shift().write(summary, tmp_path)
    (family,) = summary["families"]
    assert [r["domain"] for r in family["rows"]] == ["crowd_noise_0.3", "crowd_noise_0.6"]
    distance = [r["statistics_distance"] for r in family["rows"]]
    assert 0 < distance[0] < distance[1]  # a larger knob shift moves the statistics further
    cells = [r["methods"]["finetune"] for r in family["rows"]]
    assert all(np.isfinite(c["forgetting"]) and np.isfinite(c["gap"]) for c in cells)
    assert family["peaks"]["finetune"]["shift"] in (0.2, 0.5)
    assert (tmp_path / "shift.png").read_bytes()[:4] == b"\x89PNG"
    text = (tmp_path / "shift.md").read_text()
    assert "forgets most" in text  # two shifts rank perfectly whatever they measure: not shown
    assert np.isnan(family["peaks"]["finetune"]["rank_knob"]) and "No rank correlation" in text


def test_rank_correlation_needs_four_shifts():
    assert np.isnan(shift._spearman([1, 2, 3], [0.1, 0.3, 0.2]))
    assert shift._spearman([1, 2, 3, 4], [0.1, 0.2, 0.3, 0.4]) == pytest.approx(1.0)


def test_shift_needs_a_base_and_shifted_values():
    config = ExperimentConfig("crowd_noise_0.1")
    with pytest.raises(InputError, match="base value first"):
        shift.shift_grid("crowd_noise_0.1", config)
    with pytest.raises(InputError, match="base value first"):
        shift.shift_grid("eth_ucy_eth,hotel", config)


def test_the_shift_grid_holds_the_domains_the_sweep_trains():
    """``--set data.*`` reaches the domains whose statistics the study measures (it once parsed
    the scenario again without them: 10 agents measured where 6 were trained)."""
    config = ExperimentConfig("crowd_noise_0.1", settings={"data": {"agents": 6}})
    base, shifted = shift.shift_grid("crowd_noise_0.1..0.3", config)
    assert [s.knobs["agents"] for s in (base, *shifted)] == [6, 6, 6]
    default = shift.shift_grid("crowd_noise_0.1..0.3", ExperimentConfig("crowd_noise_0.1"))[0]
    assert default.knobs["agents"] != 6
