"""``python -m sim.run`` end to end on --quick sizes: files, shapes, finite values, errors."""

import csv
import json
import math
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import torch

from sim.run import main


def run(*args):
    """``python -m sim.run ARGS`` as a process: its exit code and output."""
    return subprocess.run(
        [sys.executable, "-m", "sim.run", *args], capture_output=True, text=True, check=False
    )


def run_here(capsys, *args) -> subprocess.CompletedProcess:
    """``sim.run`` in this process (torch and the data already imported): its exit code and
    output, as :func:`run` gives them."""
    capsys.readouterr()
    code = main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out, err)


def refused(capsys, *args) -> list[str]:
    """Run ``sim.run`` in this process on bad input: exit code 2 and stderr's lines (the
    command's process exit code is tested once, below)."""
    assert main(list(args)) == 2
    return capsys.readouterr().err.strip().splitlines()


def test_quick_run_writes_every_output(tmp_path, capsys):
    out = tmp_path / "run"
    result = run_here(
        capsys,
        "--scenario",
        "crowd_noise_0.1..0.3",
        "--quick",
        "--out",
        str(out),
        "--methods",
        "c2inet-online,finetune,cv",
        "--cache",
        str(tmp_path / "cache"),
    )
    assert result.returncode == 0, result.stderr
    assert "0.1" in result.stdout and ":0.3" in result.stdout and "c2inet-online" in result.stdout
    # the other test-time rules for C, beside the default (posterior)
    assert "c2inet-online, c from prior" in result.stdout
    assert "c2inet-online, c from responsible" in result.stdout
    closing = result.stdout.strip().splitlines()[-2:]  # what was written, and how to view it
    assert closing[0].endswith(f"wrote {out}: open report.md")
    viewer = Path(shutil.which("rerun") or Path(sys.executable).with_name("rerun"))
    assert closing[1].startswith("view it: ") and f"{out}/recording.rrd" in closing[1]
    assert Path(closing[1].split()[2]).resolve() == viewer.resolve()
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["scenario"] == "crowd_noise_0.1..0.3" and metrics["k"] == 5
    tidy = pq.read_table(out / "results.parquet").to_pydict()  # every matrix cell, one row each
    ade = [v for k, v in zip(tidy["metric"], tidy["value"], strict=True) if k == "ade"]
    assert len(ade) == 3 * 9 and set(tidy["method"]) == {"c2inet-online", "finetune", "cv"}
    assert set(tidy["quick"]) == {True}  # every row says it is a smoke test
    assert metrics["tasks"] == ["crowd_noise_0.1", "crowd_noise_0.2", "crowd_noise_0.3"]
    for name in ("c2inet-online", "finetune", "cv"):
        m = metrics["methods"][name]
        for key in ("ade", "fde", "ade_k1", "fde_k1"):
            assert len(m[key]) == 3 and all(len(row) == 3 for row in m[key])
            assert all(math.isfinite(v) for row in m[key] for v in row)
        assert m["avg_seen_ade"][1] == pytest.approx(
            (m["ade"][1][0] + m["ade"][1][1]) / 2, abs=1e-5
        )
        assert math.isfinite(m["forgetting_final_ade"]) and m["seeds"] == 1
    c2inet = metrics["methods"]["c2inet-online"]
    assert len(c2inet["queue_size"]) == 3
    # every test-time rule for C is scored; baselines have only their own
    for rule in ("c_prior", "c_responsible"):
        assert len(c2inet[f"ade_{rule}"]) == 3 and f"ade_{rule}" not in metrics["methods"]["cv"]
    diagnostics = c2inet["diagnostics"]
    assert len(diagnostics) == 3 and len(diagnostics[-1]["kl_c"]) == 3
    assert 0 <= diagnostics[-1]["probe_c"] <= 1 and diagnostics[-1]["knob_r2"] is not None
    assert set(metrics["methods"]["finetune"]["diagnostics"][-1]) == {
        "probe_observed",
        "probe_context",
    }
    with open(out / "matrices" / "finetune_ade.csv") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["after", *metrics["tasks"]] and len(rows) == 4
    card = json.loads((out / "run_card.json").read_text())
    assert card["versions"]["torch"].startswith("2.13") and len(card["domains"]) == 3
    assert (
        card["threads"] == 1 and card["train"]["k_train"] == 5 and card["train"]["device"] == "cpu"
    )
    assert all(d["hash"] for d in card["domains"])
    assert card["device_used"] == "cpu"  # the device resolved, not only the one asked for
    report = (out / "report.md").read_text()
    assert report.startswith("# Continual run") and "**quick**" in report
    assert "**one seed** (no spread" in report  # one seed is marked, not passed off as spread
    assert "    python -m sim.run --scenario crowd_noise_0.1..0.3" in report
    assert "[average_seen](figures/average_seen.png)" in report
    assert "[recording.rrd](recording.rrd)" in report
    for link in re.findall(r"\]\(([^)]+)\)", report):
        assert (out / link).is_file(), link  # every link opens
    assert card["command"].startswith("python -m sim.run --scenario crowd_noise_0.1..0.3")
    assert card["backend"] == "local" and card["host"] and card["finished"].startswith("20")
    assert card["git_commit"] is None or len(card["git_commit"]) >= 40
    checkpoints = out / "jobs" / "finetune" / "seed_0" / "checkpoints"
    assert sorted(p.name for p in checkpoints.iterdir()) == [
        "manifest.json",  # the job's identity and each checkpoint's SHA-256
        "task_00.pt",
        "task_01.pt",
        "task_02.pt",
    ]


def test_settings_reach_the_method_and_the_run_card(tmp_path, capsys):
    result = run_here(
        capsys,
        "--scenario",
        "crowd_noise_0.1,0.2",
        "--quick",
        "--no-record",
        "--methods",
        "c2inet-online",
        "--set",
        "c2inet-online.capacity=1",
        "--set",
        "model.beta_z=0",
        "--out",
        str(tmp_path / "run"),
        "--cache",
        str(tmp_path / "cache"),
    )
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["methods"]["c2inet-online"]["queue_size"] == [1, 1]  # pruned to capacity
    card = json.loads((tmp_path / "run" / "run_card.json").read_text())
    assert card["model"]["beta_z"] == 0 and card["settings"]["c2inet-online"] == {"capacity": 1}


def test_seeds_give_mean_and_std(tmp_path, capsys):
    result = run_here(
        capsys,
        "--scenario",
        "crowd_radius_0.2,0.4",
        "--quick",
        "--seeds",
        "2",
        "--methods",
        "finetune",
        "--out",
        str(tmp_path / "run"),
        "--cache",
        str(tmp_path / "cache"),
    )
    assert result.returncode == 0, result.stderr
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())["methods"]["finetune"]
    assert m["seeds"] == 2 and any(v > 0 for row in m["ade_std"] for v in row)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "crowd_noise_0.1", "--methods", "sgd"], "method 'sgd': unknown"),
        (["--scenario", "crowd_noise_0.1", "--backbone", "resnet"], "backbone 'resnet': unknown"),
        (["--scenario", "crowd_noise_0.1", "--seeds", "0"], "--seeds"),
        (["--scenario", "crowd_noise_0.1", "--k", "0"], "--k"),
        (["--scenario", "crowd_noise_1..0"], "reversed"),
        (
            ["--scenario", "crowd_noise_0.1", "--set", "c2inet-online.prunning=false"],
            "unknown key",
        ),
        (
            ["--scenario", "crowd_noise_0.1", "--set", "c2inet-online.pruning=maybe"],
            "true or false",
        ),
        (["--scenario", "crowd_noise_0.1", "--set", "pruning"], "SCOPE.KEY=VALUE"),
        (
            ["--scenario", "crowd_noise_0.1", "--set", "model.z_dim=4", "--set", "model.z_dim=5"],
            "model.z_dim: given twice",
        ),
        (["--scenario", "crowd_noise_0.1", "--set", "ewc.strength=1"], "not data, model, train"),
        (["--scenario", "crowd_noise_0.1", "--workers", "0"], "--workers"),
        (["--scenario", "crowd_noise_0.1", "--seeds", "0"], "--seeds: 0 is not between 1"),
        (["--scenario", "crowd_noise_0.1", "--k", "many"], "--k: 'many' is not an integer"),
        (["--scenario", "crowd_noise_0.1", "--threads", "0"], "--threads: 0 is not between 1"),
        (["--scenario", "crowd_noise_0.1", "--set", "model.c_per=cell"], "expected one of agent"),
        (
            ["--scenario", "crowd_noise_0.1", "--set", "model.c_source=mean"],
            "expected one of posterior",
        ),
        (["--scenario", "crowd_noise_0.1", "--set", "train.k_train=0"], "k_train=0 is out of"),
        (["--scenario", "crowd_noise_0.1", "--set", "model.beta_x=-1"], "beta_x=-1 is out of"),
        (
            ["--scenario", "crowd_noise_0.1", "--set", "c2inet-online.anchor_batch=0"],
            "anchor_batch=0 is out of range [1",
        ),
        (
            ["--scenario", "crowd_noise_0.1", "--set", "c2inet-online.distill_weight=-1"],
            "distill_weight=-1 is out of range [0",
        ),
        (["--scenario", "crowd_noise_0.1", "--set", "train.lr=-1"], "lr=-1 is out of range (0"),
        (["--scenario", "crowd_noise_0.1", "--set", "train.lr=nan"], "'lr' must be finite"),
        (["--scenario", "crowd_noise_0.1", "--set", "model.n_mc=1.5"], "must be an integer"),
        (["--scenario", "crowd_noise_0.1", "--set", "train.epochs=3"], "use --epochs"),
        (["--scenario", "crowd_noise_0.1", "--set", "train.device=cpu"], "use --device"),
        (["--scenario", "crowd_noise_0.1", "--device", "gpu"], "'gpu' is none of auto, cpu"),
        (["--scenario", "crowd_noise_0.1", "--logger", "wandb=cloud"], "offline or online"),
        (["--scenario", "crowd_noise_0.1", "--logger", "csv=x"], "only mlflow=URI and wandb"),
        (["--scenario", "crowd_noise_0.1", "--seed", "-1"], "--seed: -1 is not between 0 and"),
        (["--scenario", "crowd_noise_0.1", "--cache", "x" * 5000], "too long for a file system"),
        (["--scenario", "crowd_noise_0.1", "--device", "cuda:" + "9" * 20], "is none of auto"),
        (["--scenario", "crowd_radius_0.1,00.1"], "are one value of family"),
    ],
)
def test_bad_options_give_one_error_line(capsys, args, message):
    lines = refused(capsys, *args)
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0]


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has a CUDA device")
def test_a_device_this_machine_lacks_is_refused_before_any_work(capsys, tmp_path):
    out = tmp_path / "run"
    lines = refused(capsys, "--scenario", "crowd_noise_0.1", "--device", "cuda", "--out", str(out))
    assert lines == ["error: device 'cuda': this machine has no CUDA device (try auto or cpu)"]
    assert not out.exists()


def test_list_shows_families_methods_and_knobs(capsys):
    def listed(*args: str) -> str:
        assert main(list(args)) == 0
        return capsys.readouterr().out

    families = listed("--list", "families")
    assert "crowd_radius" in families and "eth_ucy" in families and "radius" in families
    methods = listed("--list", "methods")
    assert all(m in methods for m in ("c2inet-online", "ewc", "cv", "joint"))
    knobs = listed("--list", "knobs", "crowd_noise")
    assert "agents" in knobs and "noise" in knobs and "<- the scenario" in knobs
    with pytest.raises(SystemExit):
        main(["--help"])
    help_text = capsys.readouterr().out
    assert "examples:" in help_text and "``" not in help_text and "--list" in help_text


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "crowd_nose_0.1"], "did you mean 'crowd_noise'?"),
        (["--scenario", "crowd_noise_0.1", "--methods", "finetun"], "did you mean 'finetune'?"),
        (["--scenario", "crowd_noise_0.1", "--methods", "c2inet"], "'c2inet-offline' or"),
        (["--scenario", "crowd_noise_0.1-0.6"], "a range is written 0.1..0.6"),
        (["--scenario", "crowd_noise"], "needs values"),
        (["--scenario", "crowd_noise_0.1", "--set", "data.agentz=3"], "did you mean 'agents'?"),
        (["--scenario", "crowd_noise_0.1", "--set", "data.noise=0.3"], "what crowd_noise's values"),
        (["--scenario", "crowd_noise_0.1", "--set", "train.lrr=1"], "did you mean 'lr'?"),
        (["--scenario", "crowd_noise_0.1", "--logger", "tensorbord"], "did you mean"),
        (["--list", "knobs", "crowd_nois"], "did you mean 'crowd_noise'?"),
        (
            ["--list", "everything"],
            "expected families, methods, backbones, generators, studies, loggers",
        ),
        ([], "required: --scenario"),
    ],
)
def test_mistakes_get_a_hint(capsys, args, message):
    lines = refused(capsys, *args)
    assert len(lines) == 1 and message in lines[0], lines


def test_bad_input_is_exit_code_2_and_one_line_from_the_command():
    result = run("--scenario", "crowd_nose_0.1")
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: ")
    assert "did you mean 'crowd_noise'?" in lines[0]


def test_knob_overrides_reach_the_domains_and_the_run_card(tmp_path, capsys):
    args = ["--scenario", "crowd_noise_0.1 + crowd_noise_0.2", "--quick", "--methods", "cv"]
    args += ["--cache", str(tmp_path / "cache"), "--no-record", "--logger", "csv,tensorboard"]
    plain = run_here(capsys, *args, "--out", str(tmp_path / "plain"))
    tweaked = run_here(capsys, *args, "--set", "data.agents=4", "--out", str(tmp_path / "tweaked"))
    assert plain.returncode == 0 and tweaked.returncode == 0, tweaked.stderr
    cards = [json.loads((tmp_path / n / "run_card.json").read_text()) for n in ("plain", "tweaked")]
    assert [d["knobs"]["agents"] for d in cards[1]["domains"]] == [4, 4]
    assert cards[0]["domains"][0]["knobs"]["agents"] == 10
    assert cards[0]["domains"][0]["hash"] != cards[1]["domains"][0]["hash"]
    assert cards[1]["settings"]["data"] == {"agents": 4}


def test_loggers_write_the_numbers_of_metrics_json(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["--scenario", "crowd_noise_0.1,0.2", "--quick", "--methods", "finetune", "--no-record"]
    loggers = "csv,tensorboard,mlflow,wandb"
    done = run_here(
        capsys, *args, "--logger", loggers, "--set", "train.lr=0.002", "--out", str(out)
    )
    assert done.returncode == 0, done.stderr
    metrics = json.loads((out / "metrics.json").read_text())["methods"]["finetune"]
    job = out / "jobs" / "finetune" / "seed_0"
    with open(job / "log.csv") as f:
        rows = list(csv.DictReader(f))
    logged = {(r["name"], int(r["step"])): float(r["value"]) for r in rows}
    assert logged["matrix_ade/crowd_noise_0.1", 3] == pytest.approx(metrics["ade"][1][0])
    assert ("val_ade/crowd_noise_0.2", 2) in logged and ("nll", 0) in logged
    assert any(name.startswith("diagnostics/") for name, _ in logged)
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(job / "tensorboard"))
    events.Reload()
    (point,) = [s for s in events.Scalars("matrix_ade/crowd_noise_0.1") if s.step == 3]
    assert point.value == pytest.approx(metrics["ade"][1][0], rel=1e-6)
    final = events.Scalars("final/ade")[0].value  # the HParams tab's score, beside the settings
    assert final == pytest.approx(sum(metrics["ade"][1]) / 2, rel=1e-6)
    from mlflow.tracking import MlflowClient

    client = MlflowClient(f"sqlite:///{out.resolve() / 'mlflow.db'}")
    (experiment,) = [e for e in client.search_experiments() if e.name.endswith("/run")]
    runs = client.search_runs([experiment.experiment_id])
    (tracked,) = [r for r in runs if "c2i_job" in r.data.tags]
    (report,) = [r for r in runs if "c2i_parent" in r.data.tags]  # the run, its files attached
    assert report.info.run_name == "run" and tracked.info.run_name == "finetune seed 0"
    assert tracked.data.tags["mlflow.parentRunId"] == report.info.run_id
    assert report.info.start_time <= tracked.info.start_time < tracked.info.end_time
    assert tracked.info.end_time <= report.info.end_time  # it ends with the report's files
    shown = {a.path for a in client.list_artifacts(report.info.run_id)}
    assert {"report.md", "metrics.json", "figures"} <= shown
    figures = {a.path for a in client.list_artifacts(report.info.run_id, "figures")}
    assert "figures/average_seen.png" in figures
    assert (out / "mlartifacts").is_dir()  # beside the store, not in the working directory
    assert tracked.data.tags["c2i_job"] == "jobs/finetune/seed_0"
    assert tracked.data.params["train.lr"] == "0.002" and tracked.data.params["seed"] == "0"
    # what the runs table sorts and compares by (issue 65): the final scores, the sizes
    final = tracked.data.metrics  # each metric's latest value: after the last task
    assert final["seen/ade"] == pytest.approx(sum(metrics["ade"][1]) / 2, rel=1e-6)
    lost = metrics["ade"][1][0] - metrics["ade"][0][0]
    assert final["forgetting/ade"] == pytest.approx(lost, abs=2e-6)  # metrics.json: 6 places
    assert {"seen/ade_k1", "seen/col_pred_primary", "forgetting/ade_k1"} <= set(final)
    assert tracked.data.params["quick"] == "True" and tracked.data.params["size"] == "quick"
    assert tracked.data.params["splits.train"] == "300"
    history = client.get_metric_history(tracked.info.run_id, "matrix_ade/crowd_noise_0.1")
    assert [(m.step, m.value) for m in history if m.step == 3] == [
        (3, pytest.approx(metrics["ade"][1][0], rel=1e-6))
    ]
    (offline,) = (job / "wandb").glob("offline-run-*/run-*.wandb")
    records = wandb_records(offline)
    (started,) = [r.run for r in records if r.HasField("run")]
    assert (started.project, started.run_group, started.display_name) == (
        tmp_path.name,
        "run",
        "jobs/finetune/seed_0",
    )
    config = {u.key: json.loads(u.value_json) for u in started.config.update}
    assert config["train.lr"] == 0.002 and config["seed"] == 0
    steps = {}
    for r in records:
        if r.HasField("history"):
            items = {i.key or i.nested_key[0]: json.loads(i.value_json) for i in r.history.item}
            steps.setdefault(items["_step"], {}).update(items)
    assert steps[3]["matrix_ade/crowd_noise_0.1"] == pytest.approx(metrics["ade"][1][0])
    assert "nll" in steps[0] and "val_ade/crowd_noise_0.2" in steps[2]
    (kept,) = (out / "wandb").glob("offline-run-*/run-*.wandb")  # the report's run
    (report_run,) = [r.run for r in wandb_records(kept) if r.HasField("run")]
    assert (report_run.run_group, report_run.display_name) == ("run", "report")
    assert any(r.HasField("artifact") for r in wandb_records(kept))


def test_a_sweeps_runs_are_one_tracking_experiment_side_by_side(tmp_path):
    """A sweep is one MLflow experiment (its folder's) in one store, each variant's jobs and
    report a run of it; so is its W&B group."""
    from mlflow.tracking import MlflowClient

    from sim.sweep import main as sweep_main

    out = tmp_path / "sweep"
    argv = ["--scenario", "crowd_noise_0.1,0.2", "--quick", "--methods", "finetune"]
    argv += ["--set", "train.lr=0.001,0.002", "--no-record", "--logger", "mlflow,wandb"]
    assert sweep_main([*argv, "--jobs", "2", "--out", str(out)]) == 0
    client = MlflowClient(f"sqlite:///{out.resolve() / 'mlflow.db'}")
    (experiment,) = [e for e in client.search_experiments() if e.name.endswith("/sweep")]
    runs = client.search_runs([experiment.experiment_id])
    variants = sorted(p.name for p in (out / "crowd_noise_0.1,0.2").iterdir())
    assert len(variants) == 2 and len(runs) == 4  # a variant's run and its job's
    parents = {r.info.run_name: r.info.run_id for r in runs if "c2i_parent" in r.data.tags}
    assert sorted(parents) == [f"crowd_noise_0.1,0.2/{v}" for v in variants]
    children = [r for r in runs if "c2i_job" in r.data.tags]
    assert {r.info.run_name for r in children} == {"finetune seed 0"}  # short, under its variant
    assert {r.data.tags["mlflow.parentRunId"] for r in children} == set(parents.values())
    assert not list(out.glob("*/*/mlflow.db"))  # no store of its own in a variant
    for job in out.glob("*/*/jobs/finetune/seed_0"):
        (offline,) = (job / "wandb").glob("offline-run-*/run-*.wandb")
        (started,) = [r.run for r in wandb_records(offline) if r.HasField("run")]
        assert started.run_group == "sweep"


def wandb_records(path: Path) -> list:
    """The records of a W&B run file: a 7-byte header, then LevelDB's log format (32 KiB
    blocks of chunks, each with a 7-byte header: checksum, length, kind) around W&B's protobuf
    ``Record`` messages. W&B 0.31 has no Python reader of its own."""
    from wandb.proto import wandb_internal_pb2

    raw, block, position, parts, out = path.read_bytes(), 32768, 7, b"", []
    while position + 7 <= len(raw):
        left = block - position % block
        _, length, kind = struct.unpack("<IHB", raw[position : position + 7])
        if left < 7 or length == kind == 0:  # the padding at a block's end
            position += left
            continue
        chunk = raw[position + 7 : position + 7 + length]
        position += 7 + length
        parts = chunk if kind in (1, 2) else parts + chunk  # full, first | middle, last
        if kind in (1, 4):
            record = wandb_internal_pb2.Record()
            record.ParseFromString(parts)
            out.append(record)
    return out


def test_usage_names_the_command_as_the_user_typed_it(monkeypatch):
    from sim.cli import parser

    monkeypatch.setattr(sys, "argv", ["/venv/bin/c2i-run"])
    assert parser("sim.run", "d").format_usage().startswith("usage: c2i-run ")
    monkeypatch.setattr(sys, "argv", ["/clone/sim/run.py"])
    assert parser("sim.run", "d").format_usage().startswith("usage: python -m sim.run ")


def test_a_command_starts_without_scikit_learn():
    """scikit-learn is imported where a probe or k-means runs: bad input and --help stay quick."""
    code = "import sys, sim.run, sim.study; assert 'sklearn' not in sys.modules, 'sklearn'"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def in_private_mount(folder, options: str, command: list[str]) -> subprocess.CompletedProcess:
    """``command`` with a small tmpfs mounted at ``folder`` in a mount namespace of its own."""
    mount = f'mount -t tmpfs -o {options} tmpfs {folder} && exec "$@"'
    return subprocess.run(
        ["unshare", "-m", "sh", "-c", mount, "sh", *command], capture_output=True, text=True
    )


def test_a_full_or_read_only_disk_is_one_line(tmp_path):
    if subprocess.run(["unshare", "-m", "true"], capture_output=True).returncode:
        pytest.skip("this machine allows no private mount namespace")
    command = [sys.executable, "-m", "sim.run", "--scenario", "crowd_noise_0.1", "--quick"]
    command += ["--methods", "finetune", "--no-record", "--out", str(tmp_path / "run")]
    full = in_private_mount(tmp_path, "size=200k", command)
    assert full.returncode == 1 and "Traceback" not in full.stderr
    assert full.stderr.strip().splitlines()[-1].startswith("error: cannot write ")
    assert "no space left on its device" in full.stderr
    read_only = in_private_mount(tmp_path, "ro,size=200k", command)
    assert read_only.returncode == 2 and "Traceback" not in read_only.stderr
    assert read_only.stderr.strip().splitlines()[-1].endswith("Read-only file system")


def test_a_finished_job_whose_recording_is_lost_is_drawn_again_on_resume(tmp_path):
    argv = ["--scenario", "crowd_noise_0.1", "--quick", "--methods", "cv,finetune"]
    argv += ["--out", str(tmp_path / "run"), "--cache", str(tmp_path / "cache")]
    assert main(argv) == 0
    metrics = (tmp_path / "run" / "metrics.json").read_text()
    lost = tmp_path / "run" / "jobs" / "finetune" / "seed_0" / "recording.rrd"
    lost.unlink()
    assert main([*argv, "--resume"]) == 0
    assert lost.stat().st_size > 0 and (tmp_path / "run" / "recording.rrd").stat().st_size > 0
    assert json.loads((tmp_path / "run" / "metrics.json").read_text()) == json.loads(metrics)


def test_a_config_file_gives_the_options_and_flags_override_it(tmp_path, capsys):
    (tmp_path / "exp.toml").write_text(
        'scenario = "crowd_noise_0.1"\nmethods = ["cv", "finetune"]\nquick = true\n'
        "record = false\nepochs = 1\n[settings.train]\nlr = 0.01\nbatch_scenes = 4\n"
    )
    cache = ["--cache", str(tmp_path / "cache")]
    first = tmp_path / "first"
    assert main(["--config", str(tmp_path / "exp.toml"), "--out", str(first), *cache]) == 0
    saved = json.loads((first / "config.json").read_text())["experiment"]
    assert saved["methods"] == ["cv", "finetune"] and saved["epochs"] == 1
    assert saved["settings"] == {"train": {"lr": 0.01, "batch_scenes": 4}} and not saved["record"]
    card = json.loads((first / "run_card.json").read_text())
    assert card["config_file"]["path"] == str(tmp_path / "exp.toml")
    # a run's own config.json runs it again; a flag and a --set override what it says
    again = tmp_path / "again"
    argv = [f"--config={first / 'config.json'}", "--methods", "finetune"]
    assert main([*argv, "--set", "train.lr=0.02", "--out", str(again), *cache]) == 0
    saved = json.loads((again / "config.json").read_text())["experiment"]
    assert saved["methods"] == ["finetune"]
    card = json.loads((again / "run_card.json").read_text())
    assert card["config_file"]["path"] == str(first / "config.json")
    assert saved["settings"] == {"train": {"lr": 0.02, "batch_scenes": 4}}
    (tmp_path / "bad.toml").write_text("epoch = 3\n")
    capsys.readouterr()
    assert refused(capsys, "--config", str(tmp_path / "bad.toml")) == [
        f"error: --config {tmp_path / 'bad.toml'}: unknown option 'epoch'; did you mean 'epochs'?"
    ]
    (tmp_path / "bad.toml").write_text('quick = "false"\n')  # text, which argparse took as true
    assert (
        "quick = 'false': expected true or false"
        in refused(capsys, "--config", str(tmp_path / "bad.toml"))[-1]
    )
    for line, expected in (
        ('epochs = "3"', "epochs = '3': expected a number"),  # text once taken as the number
        ("epochs = [1]", "epochs = [1]: expected a number"),
        ("device = true", "device = True: expected text"),
        ("methods = {a = 1}", "methods = {'a': 1}: expected text or a list of texts"),
        ("scenario = 2024-01-01", "expected text"),
    ):
        (tmp_path / "bad.toml").write_text(line + "\n")
        assert expected in refused(capsys, "--config", str(tmp_path / "bad.toml"))[-1], line
    (tmp_path / "bad.toml").write_text('scenario = "crowd_noise_0.1"\nepochs = -3\n')
    assert (
        "argument --epochs: -3 is not between 0"
        in refused(capsys, "--config", str(tmp_path / "bad.toml"))[-1]
    )


def test_print_config_gives_a_file_that_runs_as_the_same_configuration(tmp_path, capsys):
    argv = ["--scenario", "crowd_noise_0.1..0.3", "--methods", "finetune,c2inet-online"]
    argv += ["--set", "c2inet-online.pruning=false", "--set", "data.splits.train=10", "--epochs=3"]
    assert main([*argv, "--print-config"]) == 0
    printed = capsys.readouterr().out
    assert 'methods = ["finetune", "c2inet-online"]' in printed and "epochs = 3" in printed
    assert '[settings."c2inet-online"]\npruning = false' in printed
    (tmp_path / "printed.toml").write_text(printed)
    assert main(["--config", str(tmp_path / "printed.toml"), "--print-config"]) == 0
    assert capsys.readouterr().out == printed  # read back, it resolves to itself


def test_a_config_file_that_never_ends_or_sends_data_away_is_refused_or_trimmed(tmp_path, capsys):
    """A FIFO, a device, a huge or deeply nested file is one line; of a run's config.json only
    the execution settings that size the work on this machine are taken, and it says so."""
    import os

    from c2inet.errors import InputError
    from sim.config_file import read_config

    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 5000 + "]" * 5000)
    huge = tmp_path / "huge.toml"
    huge.write_text("# " + "x" * (1 << 21) + "\n")
    for path, why in (
        (fifo, "not a regular file"),
        (Path("/dev/zero"), "not a regular file"),
        (deep, "nested too deeply"),
        (huge, "larger than"),
    ):
        with pytest.raises(InputError, match=why):
            read_config(path)
    theirs = tmp_path / "config.json"
    execution = {
        "jobs": 2,
        "cache": "/elsewhere",
        "loggers": ["mlflow=http://far.example"],
        "rerun": "rerun+http://far.example/proxy",
        "ray_address": "far:6379",
    }
    theirs.write_text(
        json.dumps({"experiment": {"scenario": "crowd_noise_0.1"}, "execution": execution})
    )
    assert read_config(theirs) == {"jobs": 2, "scenario": "crowd_noise_0.1"}
    said = capsys.readouterr().err
    assert "applies jobs=2; not cache, loggers, ray_address, rerun (give them as flags)" in said


def test_a_run_prints_its_estimate_first_and_a_quick_run_does_not(tmp_path, capsys):
    """Timing a quick run (over in seconds) would cost as much as running it."""
    argv = ["--scenario", "crowd_noise_0.1", "--methods", "finetune", "--epochs", "1"]
    argv += ["--no-record", "--cache", str(tmp_path / "cache")]
    small = [f"--set=data.splits.{split}=2" for split in ("train", "val", "test")]
    full = run_here(capsys, *argv, *small, "--out", str(tmp_path / "small"))
    quick = run_here(capsys, *argv, "--quick", "--out", str(tmp_path / "quick"))
    assert full.returncode == quick.returncode == 0
    assert "1 jobs x 1 tasks, 1 at a time: about" in full.stderr
    assert "(timed on this machine)" not in quick.stderr


@pytest.mark.parametrize("command", ["sim.run", "sim.bench", "sim.sweep", "sim.generate"])
@pytest.mark.parametrize("argv", [["--help"], ["--epochs", "x"]])
def test_help_and_a_bad_argument_answer_without_loading_the_learner(command, argv):
    """torch, pandas, pyarrow and rerun load once a command has work: --help and a typo cost
    a fraction of a second, not the 2 to 3 CPU seconds of those imports."""
    probe = (
        "import runpy, sys\n"
        f"sys.argv = [{command!r}, *{argv!r}]\n"
        "try:\n"
        f"    runpy.run_module({command!r}, run_name='__main__')\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = [m for m in ('torch', 'pandas', 'pyarrow', 'rerun') if m in sys.modules]\n"
        "print('LOADED', heavy, file=sys.__stdout__)\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert "LOADED []" in done.stdout, done.stdout + done.stderr
