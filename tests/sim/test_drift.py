"""A knob drifting within one stream: the stream, the boundaries each mode gives, forgetting
without boundaries, and the report."""

import json

import numpy as np
import pytest

from sim.experiment import Execution, ExperimentConfig
from sim.studies import drift
from sim.study import main


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
    execution = Execution(cache=tmp_path / "cache")
    reports = {
        mode: drift.run_drift(config, drift.DriftOptions(boundaries=mode), execution)
        for mode in ("none", "chunks")
    }
    chunks = reports["none"]["chunks"]
    assert reports["none"]["methods"]["ewc"]["given"] == [0]
    assert reports["chunks"]["methods"]["ewc"]["given"] == list(range(chunks))
    assert reports["none"]["methods"]["ewc"]["needs_boundaries"]
    assert not reports["none"]["methods"]["finetune"]["needs_boundaries"]
    ewc = [np.asarray(reports[mode]["methods"]["ewc"]["ade"]) for mode in ("none", "chunks")]
    assert ewc[0].shape == (chunks, 6) and not np.array_equal(ewc[0], ewc[1])  # EWC woke up
    drift.Drift().write(reports["chunks"], tmp_path / "out")
    assert "needs boundaries" in (tmp_path / "out" / "drift.md").read_text()
    assert json.loads((tmp_path / "out" / "drift.json").read_text())["boundaries"] == "chunks"
    assert (tmp_path / "out" / "drift.png").read_bytes()[:4] == b"\x89PNG"


def test_forgetting_without_boundaries_counts_from_where_the_stream_reached_a_probe():
    errors = np.array([[0.5, 0.9], [0.2, 0.8], [0.4, 0.3]])
    lost = drift.forgetting(errors, np.array([0.1, 0.3, 0.5]), [0.1, 0.4])
    np.testing.assert_allclose(lost, [0.4 - 0.2, 0.0])


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--scenario", "eth_ucy_eth,hotel"], "give one numeric family"),
        (["--scenario", "crowd_noise_0.1..0.3", "--chunks", "0"], "--chunks"),
        (["--scenario", "crowd_noise_0.1..0.3", "--memory-budget", "0.001"], "memory budget"),
    ],
)
def test_bad_input_is_one_error_line(tmp_path, capsys, argv, message):
    assert main(["drift", *argv, "--out", str(tmp_path), "--cache", str(tmp_path / "cache")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
