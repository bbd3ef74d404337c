"""Fuzzing every input path (``fuzzing.py``): a result or the project's one error, nothing
else.

Each test draws a few hundred inputs; ``benchmarks/fuzz.py`` runs 10,000 and counts outcomes.
"""

import pytest
from fuzzing import TARGETS, Target, outcome
from hypothesis import HealthCheck, given, settings

FUZZ = settings(
    max_examples=150, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True
)


@pytest.mark.parametrize("target", TARGETS, ids=lambda t: t.name)
def test_every_input_gets_a_result_or_one_clear_error(target: Target):
    @settings(FUZZ, max_examples=target.examples)
    @given(target.strategy)
    def check(case):
        assert outcome(target, case) in ("ok", "input error")

    check()


def test_the_fuzz_targets_reach_both_outcomes():
    """Inputs that pass and inputs that fail, so the strategies are not all rejected early."""
    from fuzzing import data_file_target, scenario_target

    assert outcome(TARGETS[0], "crowd_noise_0.1..0.3") == "ok"
    assert outcome(TARGETS[0], "crowd_noise_0.1-0.3") == "input error"
    assert scenario_target("crowd_noise_0.1+crowd_radius_0.2")
    assert data_file_target("0 1 0 0\n10 1 0.4 0\n")[0].agent_ids.tolist() == [1]


def test_what_the_fuzz_suite_found_stays_fixed(tmp_path):
    """Its first finds: a benchmark's own tuning store damaged on resume was a driver's
    traceback; a run marker or a report replaced by a folder was an ``IsADirectoryError``."""
    from fuzzing import tuning_storage_target

    from c2inet.errors import InputError
    from c2inet.files import write_text_atomic

    with pytest.raises(InputError, match=r"the tuning store .*\(delete it to tune again\)"):
        tuning_storage_target(b"SQLite format 3\x00")
    (tmp_path / "report.md").mkdir()
    with pytest.raises(InputError, match="a folder stands where the file goes"):
        write_text_atomic(tmp_path / "report.md", "# report\n")
    from sim.experiment import ExperimentConfig
    from sim.experiment.config import Execution
    from sim.experiment.folders import MARKER, claim

    run = tmp_path / "run"
    (run / MARKER).mkdir(parents=True)
    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True)
    with pytest.raises(InputError, match=f"its {MARKER} is not a file"):
        claim(run, config, Execution(), resume=True, overwrite=False)
    assert (run / MARKER).is_dir()  # nothing removed
