"""``python -m sim.sweep``: every combination runs, tidy results, a combined report, resume."""

import json

import pyarrow.parquet as pq
import pytest

from c2inet.errors import InputError
from sim.experiment import ExperimentConfig
from sim.experiment.outputs import COLUMNS
from sim.experiment.sweep import SweepConfig, parse_grid
from sim.sweep import main as sweep_main


def test_a_sweep_runs_the_cross_product_and_writes_tidy_results(tmp_path):
    out = tmp_path / "sweep"
    command = [
        "--scenario",
        "crowd_noise_0.1",  # one task each: the product is what is tested
        "--scenario",
        "crowd_radius_0.2,0.4",
        "--methods",
        "finetune,cv",
        "--seeds",
        "2",
        "--set",
        "train.lr=0.003,0.01",
        "--quick",
        "--jobs",
        "1",  # in this process: parallel jobs are test_parallel_jobs_give_the_same_metrics's
        "--cache",
        str(tmp_path / "cache"),
        "--out",
        str(out),
    ]
    assert sweep_main(command) == 0
    table = pq.read_table(out / "results.parquet").to_pydict()
    assert tuple(table) == COLUMNS
    metrics = {"ade", "fde", "ade_k1", "fde_k1", "ade_agent", "fde_agent"} & set(table["metric"])
    # 2 values x 2 methods x 2 seeds x (1 + 2 x 2 cells) per metric
    assert len(table["value"]) == 40 * len(set(table["metric"])) and "ade" in metrics
    assert set(table["setting"]) == {"train.lr=0.003", "train.lr=0.01"}
    assert set(table["seed"]) == {0, 1} and set(table["method"]) == {"finetune", "cv"}
    for scenario in ("crowd_noise_0.1", "crowd_radius_0.2,0.4"):
        for setting in ("train.lr_0.003", "train.lr_0.01"):
            folder = out / scenario / setting
            run = json.loads((folder / "metrics.json").read_text())
            assert run["methods"]["finetune"]["seeds"] == 2
            assert (folder / "recording.rrd").stat().st_size > 0
    # the learning rate is live: the two settings train differently, constant velocity does not
    ft = {s: [] for s in ("train.lr=0.003", "train.lr=0.01")}
    for method, setting, metric, value in zip(
        table["method"], table["setting"], table["metric"], table["value"], strict=True
    ):
        if method == "finetune" and metric == "ade":
            ft[setting].append(value)
    assert ft["train.lr=0.003"] != ft["train.lr=0.01"]
    report = (out / "report.md").read_text()
    assert report.count("| crowd_") == 8 and "± " in report
    assert sweep_main([*command, "--resume"]) == 0
    assert pq.read_table(out / "results.parquet").to_pydict() == table


def test_the_grid_is_a_product_of_typed_values():
    grid = parse_grid(["model.beta_c=0,1", "c2inet-online.pruning=true,false"])
    base = ExperimentConfig("crowd_noise_0.1", methods=("c2inet-online",), quick=True)
    sweep = SweepConfig(base, ("crowd_noise_0.1", "crowd_noise_0.2"), grid)
    labels = [label for label, _ in sweep.settings()]
    assert len(labels) == 4 and "c2inet-online.pruning=False,model.beta_c=1" in labels
    experiments = sweep.experiments()
    assert len(experiments) == 8 and experiments[-1][1].scenario == "crowd_noise_0.2"
    assert {e.settings["model"]["beta_c"] for _, e in experiments} == {0, 1}
    with pytest.raises(InputError, match="SCOPE.KEY=V1"):
        parse_grid(["model.beta_c"])
    with pytest.raises(InputError, match="given twice"):
        parse_grid(["model.beta_c=0", "model.beta_c=1"])
    with pytest.raises(InputError, match="listed twice"):
        parse_grid(["model.beta_c=0,1,0"])
    with pytest.raises(InputError, match="not data, model, train"):
        SweepConfig(base, ("crowd_noise_0.1",), parse_grid(["ewc.strength=1"])).experiments()


def test_a_variant_lays_its_settings_over_the_base_settings():
    """A study's ``--set`` (the base's settings) reaches every variant; a variant's own value
    wins where both name an option."""
    settings = {"model": {"beta_c": 0.5}, "train": {"lr": 0.01}}
    base = ExperimentConfig("crowd_noise_0.1", methods=("c2inet-online",), settings=settings)
    variants = (("off", {"model": {"beta_c": 0.0}}), ("full", {}))
    sweep = SweepConfig(base, ("crowd_noise_0.1",), variants=variants)
    (_, off), (_, full) = sweep.experiments()
    assert off.settings == {"model": {"beta_c": 0.0}, "train": {"lr": 0.01}}
    assert full.settings == settings


def test_a_sweep_stopped_before_claiming_every_folder_resumes(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["--scenario", "crowd_noise_0.1", "--quick", "--methods", "cv", "--no-record"]
    argv += ["--set", "train.lr=0.001,0.002", "--out", str(out), "--cache", str(tmp_path / "c")]
    assert sweep_main(argv) == 0
    second = out / "crowd_noise_0.1" / "train.lr_0.002"
    before = json.loads((second / "metrics.json").read_text())["methods"]
    for path in sorted(second.rglob("*"), reverse=True):  # as if killed before its claim
        path.rmdir() if path.is_dir() else path.unlink()
    assert sweep_main([*argv, "--resume"]) == 0
    assert json.loads((second / "metrics.json").read_text())["methods"] == before
    (second / "config.json").unlink()  # ours, unfinished, with a file of the user's in it
    (second / "notes.txt").write_text("mine")
    capsys.readouterr()
    assert sweep_main([*argv, "--resume"]) == 2
    assert "notes.txt" in capsys.readouterr().err
    assert (second / "notes.txt").read_text() == "mine"


def test_the_sweep_report_marks_quick_and_single_seed_rows_and_shows_no_spread_for_one():
    from sim.experiment.sweep import combined_report

    def metrics(seeds: int) -> dict:
        m = {"seeds": seeds, "forgetting_final_ade": 0.01}
        for key in ("avg_seen_ade", "avg_seen_ade_k1"):
            m[key], m[key + "_std"] = [0.2], [0.0 if seeds == 1 else 0.02]
        return {"methods": {"finetune": m}}

    quick = ExperimentConfig("crowd_noise_0.1", methods=("finetune",), quick=True)
    full = ExperimentConfig("crowd_noise_0.2", methods=("finetune",))
    report = combined_report([("a", quick, metrics(1)), ("b", full, metrics(3))])
    assert "**one seed and quick**" in report
    one, three = [line for line in report.splitlines() if line.startswith("| crowd_")]
    assert "crowd_noise_0.1 **quick**" in one and "1 (one: no spread)" in one and "±" not in one
    assert "**quick**" not in three and "0.200 ± 0.020" in three
    assert "**" not in combined_report([("b", full, metrics(3))])
