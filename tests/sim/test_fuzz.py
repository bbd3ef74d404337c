"""Fuzzing every input path (``sim.fuzz``): a result or the project's one error, nothing else.

Each test draws a few hundred inputs; ``benchmarks/fuzz.py`` runs 10,000 and counts outcomes.
"""

import pytest
from hypothesis import HealthCheck, given, settings

from sim.fuzz import TARGETS, Target, outcome

FUZZ = settings(
    max_examples=150, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True
)


@pytest.mark.parametrize("target", TARGETS, ids=lambda t: t.name)
def test_every_input_gets_a_result_or_one_clear_error(target: Target):
    @FUZZ
    @given(target.strategy)
    def check(case):
        assert outcome(target, case) in ("ok", "input error")

    check()


def test_the_fuzz_targets_reach_both_outcomes():
    """Inputs that pass and inputs that fail, so the strategies are not all rejected early."""
    from sim.fuzz import data_file_target, scenario_target

    assert outcome(TARGETS[0], "crowd_noise_0.1..0.3") == "ok"
    assert outcome(TARGETS[0], "crowd_noise_0.1-0.3") == "input error"
    assert scenario_target("crowd_noise_0.1+crowd_radius_0.2")
    assert data_file_target("0 1 0 0\n10 1 0.4 0\n")[0].agent_ids.tolist() == [1]
