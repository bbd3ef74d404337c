"""The calibration study: knobs fitted to a reference's training windows, recovered where the
reference was made with known knobs, never reading its validation or test scenes."""

import json
from pathlib import Path

import pytest

from sim.studies import calibrate as calibrate_module
from sim.study import main

DATA = Path(__file__).parent / "data"  # planted.toml: crowd_noise at speed 1.5, 6 agents


def test_a_planted_reference_is_recovered_and_the_family_file_loads(tmp_path, capsys):
    out = tmp_path / "fit"
    argv = ["calibrate", "--scenario", "crowd_noise_0.1", "--reference", "planted_0.2"]
    argv += ["--scenarios-dir", str(DATA), "--trials", "15", "--scenes", "20", "--workers", "1"]
    assert main([*argv, "--out", str(out), "--cache", str(tmp_path / "cache")]) == 0
    assert "open calibrate.md" in capsys.readouterr().err
    report = json.loads((out / "calibrate.json").read_text())
    assert report["after"]["objective"] < 0.5 * report["before"]["objective"]
    assert report["before"]["knobs"]["speed"] == 1.0  # the family's own knobs come first
    assert abs(report["after"]["knobs"]["speed"] - 1.5) < 0.3  # the planted speed
    from sim.scenario import parse_scenario

    (spec,) = parse_scenario("calibrated_planted_0_2_0.2", [out])
    assert spec.knobs["speed"] == pytest.approx(report["after"]["knobs"]["speed"])
    assert (out / "calibrate.png").read_bytes()[:4] == b"\x89PNG"


def test_the_fit_reads_the_references_training_scenes_only(tmp_path, monkeypatch):
    real = calibrate_module.build_domain

    class Sealed(list):
        def __iter__(self):
            raise AssertionError("the fit read a validation or test scene")

        def __len__(self):
            raise AssertionError("the fit read a validation or test scene")

    def sealed(spec, *args, **kwargs):
        domain = real(spec, *args, **kwargs)
        if spec.family.name == "planted":
            domain.scenes = {"train": domain.scenes["train"], "val": Sealed(), "test": Sealed()}
        return domain

    monkeypatch.setattr(calibrate_module, "build_domain", sealed)
    from sim.experiment.config import Execution

    profiles, dt, digest = calibrate_module.reference_profiles(
        "planted_0.2", 0, Execution(workers=1, cache=tmp_path), [DATA]
    )
    assert dt == pytest.approx(0.4) and len(digest) == 16
    assert len(profiles["speed"]) == 30  # the 30 training scenes, one 20-frame span each


def test_long_recordings_are_measured_on_the_generators_span():
    import numpy as np

    from sim.data import Scene

    positions = np.zeros((50, 2, 2))
    positions[:, 1] = np.nan
    positions[25:, 1] = 1.0  # the second agent arrives at frame 25
    windows = calibrate_module.windows_of([Scene(positions, np.array([4, 9]))])
    assert [w.num_frames for w in windows] == [20, 20]  # 50 frames: two spans, the rest left
    assert [w.agent_ids.tolist() for w in windows] == [[4], [4, 9]]
