"""The fidelity report passes a faithful family, fails an unfaithful one, and trains for real."""

import json
from dataclasses import replace

import numpy as np
import pytest

from c2inet.data import Windows
from sim.domains import build_domain
from sim.experiment import Execution, ExperimentConfig
from sim.experiment.curriculum import learner_tasks
from sim.scenario import parse_scenario
from sim.stats import realised_summary, relative_difference, scene_profiles
from sim.studies.fidelity import Fidelity, compare_statistics, fidelity_report, transfer_cell
from sim.study import main


def domains(scenario: str, data=None):
    return [build_domain(spec, root_seed=0) for spec in parse_scenario(scenario, overrides=data)]


def test_relative_difference():
    assert relative_difference(1.1, 1.0) == pytest.approx(0.1)
    assert relative_difference(0.9, -1.0) == pytest.approx(1.9)
    assert relative_difference(0.0, 0.0) == 0.0
    assert relative_difference(1.0, 0.0) == float("inf")


def test_scene_profiles_measure_each_scene():
    (domain,) = domains("orca_radius_0.3")
    scenes = domain.scenes["test"]
    profiles = scene_profiles(scenes, domain.dt)
    assert all(len(v) == len(scenes) for v in profiles.values())
    first = scenes[0].positions
    closest = np.linalg.norm(first[:, 0] - first[:, 1], axis=1).min()
    assert profiles["closest"][0] == pytest.approx(closest)
    assert np.nanmin(profiles["closest"]) >= 0.6 - 1e-3  # RVO2 keeps 2r
    assert realised_summary(scenes, domain.dt)["first_speed"] == pytest.approx(1.0, abs=1e-3)


def test_statistics_pass_the_orca_stand_in_and_fail_the_old_crowd():
    generated, reference = domains("crowd_radius_0.4+orca_radius_0.4")
    faithful = compare_statistics(generated, reference)
    assert faithful["matched"], faithful["relative"]
    (old,) = domains("crowd_radius_0.4", {"controller": "ttc", "start": "rest"})
    unfaithful = compare_statistics(old, reference)
    assert not unfaithful["matched"]
    assert unfaithful["relative"]["first_speed"] < -0.3  # it starts from rest
    for name, distance in unfaithful["wasserstein"].items():  # every distribution moves away
        assert distance > faithful["wasserstein"][name], name
    histogram = faithful["histograms"]["speed"]
    assert sum(histogram["generated"]) == sum(len(s) for s in generated.scenes.values())


def test_transfer_report_trains_tests_and_writes(tmp_path):
    scenario, reference = "crowd_radius_0.2,0.5", "orca_radius_0.2,0.5"
    config = ExperimentConfig(scenario, methods=("finetune",), quick=True, record=False)
    report = fidelity_report(
        scenario, reference, config, execution=Execution(cache=tmp_path / "cache")
    )
    matrix = np.asarray(report["transfer"]["ade"])
    assert matrix.shape == (4, 4) and np.all(np.isfinite(matrix)) and np.all(matrix > 0)
    assert len(set(matrix.ravel().round(6))) > 4  # each model and test set its own number
    cv = report["transfer"]["cv_ade"]
    assert cv[1] > cv[0] and cv[3] > cv[2]  # larger radii: more avoidance, worse for CV
    pair = report["pairs"][1]
    assert pair["domains"] == ["crowd_radius_0.5", "orca_radius_0.5"]
    assert pair["transfer"]["ratio"] == pytest.approx(matrix[1, 3] / matrix[3, 3])
    Fidelity().write(report, tmp_path / "out")
    written = json.loads((tmp_path / "out" / "fidelity.json").read_text())
    assert written["transfer"]["ade"] == report["transfer"]["ade"]
    assert "Transfer ratio within the target" in (tmp_path / "out" / "fidelity.md").read_text()
    assert (tmp_path / "out" / "fidelity.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--scenario", "crowd_radius_0.1,0.2", "--reference", "orca_radius_0.1"], "pair by"),
        (["--scenario", "crowd_radius_0.1", "--reference", "orca_radius_0.9"], "not a value"),
    ],
)
def test_bad_input_is_one_error_line_and_exit_code_2(tmp_path, capsys, argv, message):
    assert main(["fidelity", *argv, "--out", str(tmp_path), "--no-transfer"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and err.count("\n") == 1


def test_the_reference_is_required(capsys):
    assert main(["fidelity", "--scenario", "crowd_radius_0.1"]) == 2
    assert "required: --reference" in capsys.readouterr().err


def test_the_sim_only_model_never_sees_a_real_training_window(tmp_path):
    """The transfer's model of the generated domain trains on that domain alone: poisoning the
    reference's training windows (NaN) leaves it finite on every test set, while the model
    trained on the reference is ruined by them, so the poison would show."""
    sim_task, real_task = learner_tasks(
        "crowd_radius_0.2+orca_radius_0.2", quick=True, cache=tmp_path
    )
    poisoned = Windows(np.full_like(real_task.train.positions, np.nan), real_task.train.scene_start)
    tasks = [sim_task, replace(real_task, train=poisoned)]
    config = ExperimentConfig("crowd_radius_0.2", methods=("finetune",), quick=True, epochs=1)
    from_sim = transfer_cell(0, 0, config, "finetune", tasks)
    assert np.all(np.isfinite(from_sim["ade"])) and np.all(np.isfinite(from_sim["fde"]))
    from_real = transfer_cell(0, 1, config, "finetune", tasks)
    assert not np.all(np.isfinite(from_real["ade"]))


def test_the_pretraining_script_runs_its_three_arms_and_its_committed_table_is_its_own(
    tmp_path, monkeypatch, script, capsys
):
    """``scripts/pretrain_transfer.py``: per scene, the tenth alone, the fitted crowd then the
    tenth, the fitted crowd then all (each a ``sim.run`` of fine-tuning), read back from each
    run's metrics beside the fidelity study's columns; the committed table is what its JSON
    prints, not edited by hand."""
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    pretrain = script("scripts/pretrain_transfer.py")
    commands = []

    def fake_run(command):  # a run that ends with its last task's ADE, by arm
        commands.append(command)
        out = Path(command[command.index("--out") + 1])
        out.mkdir(parents=True)
        ade = {"tenth": 0.4, "fitted+tenth": 0.5, "fitted+all": 0.3}[out.name]
        metrics = {"methods": {"finetune": {"ade": [[9.0, ade]], "ade_std": [[9.0, 0.01]]}}}
        (out / "metrics.json").write_text(json.dumps(metrics))
        return subprocess.CompletedProcess(command, 0)

    monkeypatch.chdir(root)
    monkeypatch.setattr(subprocess, "run", fake_run)
    row = pretrain.scene_row("zara1", tmp_path, 3, 2)
    scenarios = [c[c.index("--scenario") + 1] for c in commands]
    fitted = "calibrated_eth_ucy_zara1_0.110921"
    assert scenarios == [
        "eth_ucy_tenth_zara1",
        f"{fitted}+eth_ucy_tenth_zara1",
        f"{fitted}+eth_ucy_zara1",
    ]
    assert all(c[c.index("--methods") + 1] == "finetune" and "--resume" not in c for c in commands)
    assert (row["tenth"], row["fitted+tenth"], row["fitted+all"]) == (0.4, 0.5, 0.3)
    assert row["all real alone"] == pytest.approx(0.326, abs=5e-4)  # transfer_fitted.json
    assert pretrain.scene_row("zara1", tmp_path, 3, 2) == row and len(commands) == 3  # kept
    committed = root / "docs" / "calibration" / "pretrain"
    rows = json.loads((committed / "pretrain.json").read_text())
    assert pretrain.markdown(rows, 3) == (committed / "pretrain.md").read_text()
    # bad input is one line and exit 2, before any training (issue 64's seventh case)
    for argv, why in (
        (["--scenes", "mars"], "'mars' is no ETH-UCY scene"),
        (["--seeds", "0"], "--seeds 0: expected 1 to 64"),
        (["--out", "/proc/nowhere/x"], "--out /proc/nowhere/x: cannot create it"),
    ):
        assert pretrain.main(argv) == 2 and len(commands) == 3
        err = capsys.readouterr().err
        assert why in err and err.count("\n") == 1
