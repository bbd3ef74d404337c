"""Runs that survive and scale: fresh folders, resume after kill -9 or Ctrl-C, any backend.

Every check compares ``metrics.json`` byte for byte with an uninterrupted run's.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from c2inet.errors import InputError
from c2inet.files import write_atomic
from sim.experiment import Execution, ExperimentConfig, run_experiment
from sim.experiment.folders import TEMPORARY, claim, output_folder

QUICK = ["--scenario", "crowd_noise_0.1..0.2", "--quick", "--methods", "c2inet-online,finetune"]
QUICK_CONFIG = {  # QUICK with --epochs EPOCHS, as the engine takes it
    "scenario": "crowd_noise_0.1..0.2",
    "quick": True,
    "methods": ("c2inet-online", "finetune"),
    "epochs": 2,
}
EPOCHS = str(QUICK_CONFIG["epochs"])  # the runs of these tests, killed, resumed and parallel


def start(out: Path, cache: Path, *extra: str) -> subprocess.Popen:
    return launch(
        [sys.executable, "-m", "sim.run", *QUICK, "--cache", str(cache), *extra, "--out", str(out)]
    )


def launch(command: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # a runner started in the background ignores Ctrl-C, and so would the run it starts
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def finish(process: subprocess.Popen) -> subprocess.CompletedProcess:
    stdout, stderr = process.communicate(timeout=300)
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


@pytest.fixture(scope="session")
def reference(made_once):
    """An uninterrupted quick run, made once for the session: its folder, its metrics.json,
    and the domain cache it filled (the tests below read it rather than generate the same
    domains). Read only: a test that changes a run copies it first."""

    def make(root: Path) -> None:
        config = ExperimentConfig(**QUICK_CONFIG)
        run_experiment(config, root / "run", Execution(cache=root / "cache", workers=1))

    root = made_once("reference", make)
    return root / "run", (root / "run" / "metrics.json").read_bytes(), root / "cache"


def wait_for(process: subprocess.Popen, path: Path, seconds: float = 120) -> None:
    deadline = time.monotonic() + seconds
    while not path.exists():
        assert process.poll() is None, f"run ended before {path} appeared: {process.stderr.read()}"
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.005)


def stop_at(process: subprocess.Popen, path: Path, signum: int) -> subprocess.CompletedProcess:
    """Send ``signum`` to the run the moment ``path`` appears; what it printed as it ended."""
    wait_for(process, path)
    process.send_signal(signum)
    return finish(process)


def test_a_run_killed_or_interrupted_at_every_moment_resumes_to_the_same_metrics(
    tmp_path, reference
):
    """One run stopped three times, each stop resumed: kill -9 while it generates and between
    jobs, and Ctrl-C mid-job (after a task's checkpoint), whose last line is the command that
    resumes it from that checkpoint. Each stop leaves no metrics, a folder refused without
    --resume, and the end is the uninterrupted run's metrics.json byte for byte."""
    out, cache = tmp_path / "run", tmp_path / "cache"  # a cache of its own: killed generating
    job = out / "jobs" / "c2inet-online" / "seed_0"
    moments = {
        "generating": (out / "config.json", signal.SIGKILL),
        "ctrl-c mid-job": (job / "checkpoints" / "task_00.pt", signal.SIGINT),
        "between jobs": (job / "result.json", signal.SIGKILL),
    }
    process = start(out, cache, "--epochs", EPOCHS)
    for moment, (path, signum) in moments.items():
        stopped = stop_at(process, path, signum)
        assert not (out / "metrics.json").exists(), moment
        assert not (out / "recording.rrd").exists(), moment
        with pytest.raises(InputError, match="--resume"):  # never mixed into
            claim(out, ExperimentConfig(**QUICK_CONFIG), Execution())
        if signum == signal.SIGKILL:
            assert stopped.returncode == -signal.SIGKILL, moment
            process = start(out, cache, "--epochs", EPOCHS, "--resume")
            continue
        assert stopped.returncode == 130 and "Traceback" not in stopped.stderr
        last = stopped.stderr.strip().splitlines()[-1]
        assert last.startswith("interrupted:") and last.endswith("--resume")
        command = last.partition("continue with: ")[2].split()
        assert command[:3] == ["python", "-m", "sim.run"]
        process = launch([sys.executable, *command[1:]])  # the command it printed
    resumed = finish(process)
    assert resumed.returncode == 0, resumed.stderr
    assert (out / "metrics.json").read_bytes() == reference[1]
    assert (out / "recording.rrd").stat().st_size > 0
    assert not list(out.rglob("*.partial.rrd")) and not list(out.rglob(".*.tmp*"))


@pytest.mark.parametrize("backend", ["local", "ray"])
def test_parallel_jobs_give_the_same_metrics(tmp_path, reference, backend, monkeypatch, capfd):
    monkeypatch.setenv("HOME", str(tmp_path))  # Ray writes its token under the home folder
    config = ExperimentConfig(**QUICK_CONFIG)
    execution = Execution(backend=backend, jobs=2, cache=reference[2], workers=1)
    run_experiment(config, tmp_path / "run", execution)
    assert (tmp_path / "run" / "metrics.json").read_bytes() == reference[1]
    if backend == "ray" and os.geteuid() == 0:  # the cluster ran in a namespace of its own
        assert "every interface" not in capfd.readouterr().err
    card = json.loads((tmp_path / "run" / "run_card.json").read_text())
    assert card["backend"] == backend and card["jobs"] == 2


def test_each_run_gets_a_fresh_folder_and_latest_points_to_it(tmp_path, monkeypatch, capsys):
    from sim.run import main

    monkeypatch.chdir(tmp_path)  # runs/ lies in the current folder
    argv = [*QUICK, "--cache", str(tmp_path / "cache"), "--methods", "cv", "--no-record"]
    assert main(argv) == 0 and main(argv) == 0  # folders, not training
    root = tmp_path / "runs" / "crowd_noise_0.1..0.2"
    runs = sorted(p for p in root.iterdir() if p.name != "latest")
    assert len(runs) == 2 and all((p / "metrics.json").exists() for p in runs)
    assert (root / "latest").resolve() == runs[-1].resolve()
    capsys.readouterr()
    assert main([*argv, "--resume"]) == 0
    assert str(runs[-1].relative_to(tmp_path)) in capsys.readouterr().out


def test_a_folder_is_only_replaced_when_it_holds_a_run(tmp_path):
    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True, record=False)
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not empty"):
        claim(tmp_path, config, Execution())
    with pytest.raises(InputError, match="holds no run"):
        claim(tmp_path, config, Execution(), overwrite=True)
    with pytest.raises(InputError, match="holds no run to resume"):
        claim(tmp_path, config, Execution(), resume=True)
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_overwrite_removes_only_a_folder_that_is_provably_a_run_of_ours(tmp_path, monkeypatch):
    """Issue 26, item 1: another program's config.json, the user's notes in a finished run, the
    current folder: none is removed."""
    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True, record=False)
    foreign = tmp_path / "demo"
    foreign.mkdir()
    (foreign / "config.json").write_text('{"theme": "dark"}')
    (foreign / "thesis.tex").write_text("x")
    with pytest.raises(InputError, match="holds no run of this project"):
        claim(foreign, config, Execution(), overwrite=True)
    assert (foreign / "thesis.tex").read_text() == "x"

    run = tmp_path / "run"
    claim(run, config, Execution())
    (run / "metrics.json").write_text("{}")
    (run / ".report.md.abcd_123.c2i-tmp").write_text("")  # a temporary file of an interrupted write
    (run / "jobs" / "cv" / "seed_0").mkdir(parents=True)
    (run / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="holds notes.txt, which no run writes"):
        claim(run, config, Execution(), overwrite=True)
    assert (run / "notes.txt").read_text() == "mine"
    (run / "notes.txt").unlink()
    claim(run, config, Execution(), overwrite=True)  # only our files: replaced
    assert sorted(p.name for p in run.iterdir()) == [".c2i-run", ".c2i-run.lock", "config.json"]

    monkeypatch.chdir(run)
    for here in (Path("."), Path("")):
        with pytest.raises(InputError, match="is not a run folder"):
            claim(here, config, Execution(), overwrite=True)
    assert (run / "config.json").exists()


def test_one_process_at_a_time_holds_a_run_folder(tmp_path):
    """Issue 26, item 6: a second run or resume of a folder in use gets one line."""
    import fcntl

    from sim.experiment.folders import LOCK

    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True, record=False)
    run = tmp_path / "run"
    run.mkdir()
    with open(run / LOCK, "w") as other:  # another process's lock: its own open file
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(InputError, match="another run or resume is using this folder"):
            claim(run, config, Execution())
    claim(run, config, Execution())  # released: free to take
    assert (run / "config.json").exists()


def claim_at_once(run: str, barrier, answers) -> None:
    """One of two processes claiming ``run`` at the same instant; its answer goes to ``answers``
    and it lives (holding what it claimed) until the other has tried too."""
    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True, record=False)
    barrier.wait()
    try:
        claim(Path(run), config, Execution())
        answers.put("claimed")
    except InputError as error:
        answers.put(f"refused: {error}")
    barrier.wait()


def test_two_runs_claiming_one_folder_at_once_get_one_claim(tmp_path):
    """Issue 26, item 6, as a race: the two claims meet at a barrier."""
    import multiprocessing

    # two processes of their own, forked: a spawned one imports torch anew (3.5 CPU s each)
    context = multiprocessing.get_context("fork")
    barrier, answers = context.Barrier(2), context.Queue()
    args = (str(tmp_path / "run"), barrier, answers)
    racers = [context.Process(target=claim_at_once, args=args) for _ in range(2)]
    for racer in racers:
        racer.start()
    results = sorted(answers.get(timeout=120) for _ in racers)
    for racer in racers:
        racer.join(timeout=60)
    assert results[0] == "claimed" and results[1].startswith("refused: "), results


def test_resume_removes_the_temporary_files_of_interrupted_writes(tmp_path):
    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True, record=False)
    run = tmp_path / "run"
    claim(run, config, Execution())
    job = run / "jobs" / "cv" / "seed_0"
    job.mkdir(parents=True)
    leftovers = [run / ".recording.rrd.k2j4_9xq.c2i-tmp", job / ".result.json.ab12cd34.c2i-tmp"]
    users = [job / ".hidden-notes", run / ".bashrc.original", run / ".notes.20241201"]
    for path in leftovers + users:
        path.write_text("half")
    claim(run, config, Execution(), resume=True)
    assert not any(p.exists() for p in leftovers)
    assert all(p.exists() for p in users)  # shaped like temporaries, but not write_atomic's


@pytest.mark.parametrize(
    "damage", [b'{"experiment": {"scen', b"[]", b"{}", b"\xff\xfe\x00binary", b'{"experiment": 3}']
)
def test_resume_of_a_run_whose_config_json_is_damaged_is_one_clear_refusal(tmp_path, damage):
    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True, record=False)
    run = tmp_path / "run"
    claim(run, config, Execution())
    (run / "config.json").write_bytes(damage)
    with pytest.raises(InputError, match=r"config.json is damaged .*--overwrite"):
        claim(run, config, Execution(), resume=True)
    claim(run, config, Execution(), overwrite=True)  # ours (marked): replaced
    assert json.loads((run / "config.json").read_text())["experiment"]["scenario"]


def test_write_atomic_names_its_temporary_so_a_resume_can_tell_it_from_a_users_file(tmp_path):
    seen = []
    write_atomic(tmp_path / "result.json", lambda tmp: (seen.append(tmp), tmp.write_text("{}")))
    assert TEMPORARY.match(seen[0].name) and not seen[0].exists()
    assert (tmp_path / "result.json").read_text() == "{}"


def test_a_sweeps_nested_runs_count_as_ours_and_a_stray_file_among_them_does_not(tmp_path):
    config = ExperimentConfig("crowd_noise_0.1", methods=("cv",), quick=True, record=False)
    sweep = tmp_path / "sweep"
    claim(sweep, config, Execution())
    claim(sweep / "crowd_noise_0.1" / "default", config, Execution())
    (sweep / "crowd_noise_0.1" / "draft.txt").write_text("mine")
    with pytest.raises(InputError, match="draft.txt"):
        claim(sweep, config, Execution(), overwrite=True)
    (sweep / "crowd_noise_0.1" / "draft.txt").unlink()
    claim(sweep, config, Execution(), overwrite=True)
    assert not (sweep / "crowd_noise_0.1").exists()


def test_the_experiment_is_a_function(tmp_path):
    config = ExperimentConfig("crowd_noise_0.1,0.2", methods=("cv",), quick=True, record=False)
    metrics = run_experiment(config, tmp_path / "run", Execution(cache=tmp_path / "cache"))
    assert metrics["tasks"] == ["crowd_noise_0.1", "crowd_noise_0.2"]
    assert json.loads((tmp_path / "run" / "metrics.json").read_text()) == metrics
    assert output_folder("x", tmp_path / "given") == tmp_path / "given"


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"methods": ("sgd",)}, "method 'sgd': unknown"),
        ({"methods": ()}, "no method"),
        ({"settings": {"ewc": {"strength": 1}}}, "not data, model, train"),
        ({"scenario": "crowd_noise_1..0"}, "reversed"),
    ],
)
def test_bad_configurations_are_refused_on_construction(options, message):
    with pytest.raises(InputError, match=message):
        ExperimentConfig(**{"scenario": "crowd_noise_0.1", **options})


def test_the_cache_must_be_a_writable_folder(tmp_path):
    from c2inet.files import writable_folder

    file = tmp_path / "file"
    file.write_text("")
    with pytest.raises(InputError, match="--cache .*: not a folder"):
        Execution(cache=file)
    with pytest.raises(InputError, match="cannot create it"):
        writable_folder(file / "sub", "--cache")
    assert writable_folder(tmp_path / "a" / "b", "--cache").is_dir()


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda job: (job / "result.json").write_text("{not json"), "result.json is damaged"),
        (lambda job: (job / "result.json").write_text('{"tasks": 3}'), "result.json is damaged"),
        (lambda job: (job / "predictions.npz").write_bytes(b"PK\x03\x04junk"), "predictions.npz"),
    ],
)
def test_a_damaged_finished_job_is_one_line_naming_the_file(tmp_path, damage, message):
    """Issue 26, item 3: a damaged result.json or predictions.npz was a traceback."""
    from c2inet.trainer import Result
    from sim.experiment import Job
    from sim.experiment.jobs import JobResult

    job = tmp_path / "jobs" / "cv" / "seed_0"
    job.mkdir(parents=True)
    JobResult(Job("cv", 0), Result([], {})).save(job, identity="cv")
    damage(job)
    with pytest.raises(InputError, match=message):
        JobResult.load(Job("cv", 0), job, identity="cv")


def tampered(reference, tmp_path, tamper) -> Path:
    """A copy of the reference run with one change made by ``tamper(jobs folder)``."""
    out = tmp_path / "run"
    shutil.copytree(reference[0], out, ignore=shutil.ignore_patterns(".lock"))
    tamper(out / "jobs")
    return out


def redo(job: Path) -> Path:
    """Make a finished job unfinished, so that a resume continues from its checkpoints."""
    (job / "result.json").unlink()
    return job / "checkpoints"


def flip_a_byte(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def doubled_number(job: Path) -> None:
    result = json.loads((job / "result.json").read_text())
    result["matrices"]["ade"][0][0] *= 2
    (job / "result.json").write_text(json.dumps(result))


@pytest.mark.parametrize(
    ("tamper", "message"),
    [
        (lambda jobs: flip_a_byte(redo(jobs / "finetune/seed_0") / "task_01.pt"), "task_01.pt is"),
        (lambda jobs: doubled_number(jobs / "finetune/seed_0"), "result.json is damaged"),
        (
            lambda jobs: shutil.copy(
                jobs / "c2inet-online/seed_0/result.json", jobs / "finetune/seed_0"
            ),
            "result of another job",
        ),
        (
            lambda jobs: shutil.copytree(
                redo(jobs / "c2inet-online/seed_0"),
                redo(jobs / "finetune/seed_0"),
                dirs_exist_ok=True,
            ),
            "checkpoints of another job",
        ),
    ],
    ids=["checkpoint byte", "result number", "foreign result", "foreign checkpoints"],
)
def test_resume_refuses_damaged_or_foreign_work(tmp_path, reference, tamper, message):
    """Issue 26, item 2: each of these resumed with exit 0 and other metrics."""
    out = tampered(reference, tmp_path, tamper)
    config = ExperimentConfig(**QUICK_CONFIG)
    with pytest.raises(InputError, match=message):
        run_experiment(config, out, Execution(cache=reference[2]), resume=True)


def test_a_job_identity_follows_its_data_options_method_and_seed():
    from c2inet.data import Windows
    from c2inet.trainer import Task
    from sim.experiment import Job
    from sim.experiment.curriculum import JobInputs
    from sim.experiment.jobs import job_identity

    def inputs(shift: float) -> JobInputs:
        windows = Windows(np.zeros((2, 20, 2)) + shift, np.array([0, 1, 2]))
        return JobInputs([Task("a", windows, None, windows)], [])

    config = ExperimentConfig("crowd_noise_0.1", methods=("finetune", "cv"), quick=True)
    same = job_identity(Job("finetune", 0), config, inputs(0.0))
    assert same == job_identity(Job("finetune", 0), config, inputs(0.0))
    others = [
        job_identity(Job("finetune", 0), config, inputs(1e-9)),  # a data file changed
        job_identity(Job("finetune", 1), config, inputs(0.0)),
        job_identity(Job("cv", 0), config, inputs(0.0)),
        job_identity(
            Job("finetune", 0),
            ExperimentConfig("crowd_noise_0.1", quick=True, epochs=3),
            inputs(0.0),
        ),
    ]
    assert same not in others and len(set(others)) == len(others)


def test_an_option_added_since_a_job_ran_keeps_its_identity_at_the_earlier_behaviour(
    monkeypatch,
):
    """``train.select_metric`` came after jobs were identified: at ``ade`` (the behaviour
    before it) it is left out of the identity, so a run begun before it resumes (the noise
    board's, refused until then); set otherwise, it makes another job. (Given by ``--set`` at
    all, it is in the configuration's text, which is hashed too.)"""
    from c2inet.data import Windows
    from c2inet.trainer import Task
    from sim.experiment import Job, jobs
    from sim.experiment.curriculum import JobInputs

    windows = Windows(np.zeros((2, 20, 2)), np.array([0, 1, 2]))
    inputs = JobInputs([Task("a", windows, None, windows)], [])

    def identity(**train) -> str:
        config = ExperimentConfig("crowd_noise_0.1", ("finetune",), settings={"train": train})
        return jobs.job_identity(Job("finetune", 0), config, inputs)

    default = identity()
    assert default != identity(select_metric="fde")
    monkeypatch.setattr(jobs, "SINCE", {})  # hashed like every other option
    assert identity() != default


def test_a_damaged_or_foreign_checkpoint_is_one_line_naming_it(tmp_path):
    import torch

    from c2inet.checkpoints import load_checkpoint

    broken = tmp_path / "task_00.pt"
    broken.write_bytes(b"\x80\x02 not a checkpoint")
    with pytest.raises(InputError, match="task_00.pt is damaged"):
        load_checkpoint(broken)
    foreign = tmp_path / "task_01.pt"
    torch.save({"weights": torch.zeros(2)}, foreign)
    with pytest.raises(InputError, match="no checkpoint of this project"):
        load_checkpoint(foreign)


def test_folder_names_stay_short_and_distinct_for_long_scenarios():
    """Issue 26, item 7: a valid 64-value scenario made a 394-character folder name."""
    from sim.experiment.folders import MAX_NAME, run_root

    values = ",".join(f"0.{i:03d}" for i in range(1, 65))
    long_one, other = f"crowd_noise_{values}", f"crowd_noise_{values},0.9"
    assert len(run_root(long_one).name) == MAX_NAME
    assert run_root(long_one).name.startswith("crowd_noise_0.001,0.002")
    assert run_root(long_one) != run_root(other)
    assert run_root("crowd_noise_0.1..0.6").name == "crowd_noise_0.1..0.6"  # short: unchanged


def test_the_estimate_steps_through_the_windows_each_method_trains_on():
    """An epoch's steps are those of the windows a method trains on: the task's for fine-tuning,
    joint's growing union, coresets' task beside its buffer (counting the task alone made
    density's estimate 23 % low), none where joint-scratch skips a task."""
    from c2inet.data import Windows
    from c2inet.methods.base import TaskContext, get_method
    from c2inet.model_config import ModelConfig
    from c2inet.trainer import TrainConfig, start_training
    from sim.experiment.estimate import task_seconds

    positions = np.random.default_rng(0).normal(size=(4, 20, 2)).astype(np.float32)
    windows = Windows(positions, np.arange(5))  # 4 scenes of one agent
    train = TrainConfig(batch_scenes=2)

    def steps(name: str, **options) -> list[int]:
        method = get_method(name)(ModelConfig(), options)
        model, optimiser, rng = start_training(method, train)
        counted = []
        for i in range(3):
            seen = [windows] * i if method.sees_old_tasks else []
            ctx = TaskContext(i, f"t{i}", windows, model, optimiser, rng, seen, tasks=3)
            counted.append(task_seconds(method, ctx, train, 1)[1])
        return counted

    assert steps("finetune") == [2, 2, 2]
    assert steps("joint") == [2, 4, 6]
    assert steps("coresets", per_task=4) == [2, 4, 6]  # the task's 4 scenes and the buffer's
    assert steps("joint-scratch", final_only=True) == [0, 0, 6]


def test_the_estimate_times_a_tasks_steps_with_its_past_and_every_hook():
    """Replay, teachers and projections start with the second task, Eq 8 fits at epoch ends:
    a method that spends 50 ms of CPU a step from its second task on, 30 ms at each epoch's end
    and 40 ms at each task's end is timed with all three (in CPU time: a sleep would not count)."""
    from c2inet.data import Windows
    from c2inet.methods.base import TaskContext
    from c2inet.methods.finetune import Finetune
    from c2inet.model_config import ModelConfig
    from c2inet.trainer import TrainConfig, start_training
    from sim.experiment.estimate import task_seconds

    def spin(seconds: float) -> None:  # CPU time, as the estimate counts it
        until = time.process_time() + seconds
        while time.process_time() < until:
            pass

    class Slow(Finetune):
        """Fine-tuning that spins in its hooks."""

        def before_backward(self, ctx):
            spin(0.05 if ctx.index else 0)

        def after_epoch(self, ctx, epoch):
            spin(0.03)

        def after_task(self, ctx):
            spin(0.04)

    positions = np.random.default_rng(0).normal(size=(8, 20, 2)).astype(np.float32)
    windows = Windows(positions, np.arange(9))  # 8 scenes of one agent
    method, train = Slow(ModelConfig()), TrainConfig(batch_scenes=2)
    model, optimiser, rng = start_training(method, train)
    timed = [
        task_seconds(method, TaskContext(i, "t", windows, model, optimiser, rng), train, 10)
        for i in (0, 1)
    ]
    (step_0, _, hooks_0), (step_1, _, hooks_1) = timed
    assert step_1 > step_0 + 0.03
    for hooks in (hooks_0, hooks_1):
        assert 10 * 0.03 + 0.04 <= hooks < 2 * (10 * 0.03 + 0.04)  # each once, not per step


def test_the_estimate_times_every_task_on_its_own_scenes():
    """A stream of unlike tasks (ETH-UCY: univ's crowds, then eth's pairs) costs what each task
    costs: a third task whose steps are slow makes the job dearer than the first two foretell."""
    from types import SimpleNamespace

    from c2inet.data import Windows
    from c2inet.methods.finetune import Finetune
    from c2inet.model_config import ModelConfig
    from c2inet.trainer import Task, TrainConfig
    from sim.experiment.estimate import method_seconds

    def spin(seconds: float) -> None:
        until = time.process_time() + seconds
        while time.process_time() < until:
            pass

    SLOW = 0.1  # CPU seconds a step on big: the planted cost stands well above the timing noise

    class SlowOnBig(Finetune):
        """Fine-tuning whose steps on the task named big are slow."""

        def before_backward(self, ctx):
            spin(SLOW if ctx.name == "big" else 0)

    positions = np.random.default_rng(0).normal(size=(8, 20, 2)).astype(np.float32)
    windows = Windows(positions, np.arange(9))
    config = SimpleNamespace(
        method=lambda name: SlowOnBig(ModelConfig()),
        train_config=lambda: TrainConfig(batch_scenes=2, val_every=0),
        epochs=2,
        k=2,
    )
    names = {"alike": ["a", "b", "c"], "unlike": ["a", "b", "big"]}
    method_seconds(config, "slow", [Task("a", windows, None, windows)], warm_up=True)  # imports
    cost = {
        kind: method_seconds(config, "slow", [Task(n, windows, None, windows) for n in tasks])
        for kind, tasks in names.items()
    }
    # 4 steps an epoch, 2 epochs: 8 slow steps on the third task alone (0.1 s a step: at 0.05, on
    # a loaded machine, the other costs' timing noise reached a fifth of the planted cost)
    assert cost["unlike"] - cost["alike"] > 8 * SLOW * 0.8


def test_the_estimate_counts_the_selections_evaluation_every_epoch(monkeypatch):
    """With ``train.select=val`` a job scores each task's validation split at best of select_k
    every epoch (the eth-ucy preset's recipe): the estimate counts it, so a planted slow
    selection makes the job dearer by its count (2 tasks x 2 epochs) and nothing else does."""
    from types import SimpleNamespace

    import sim.experiment.estimate as estimate
    from c2inet.data import Windows
    from c2inet.methods.finetune import Finetune
    from c2inet.model_config import ModelConfig
    from c2inet.trainer import Task, TrainConfig

    SLOW, PICKS = 0.05, 7  # CPU seconds a selection's evaluation; its K, no other evaluation's
    evaluate = estimate.evaluate

    def slow_selection(model, windows, k, *args, **kwargs):
        until = time.process_time() + (SLOW if k == PICKS else 0)
        while time.process_time() < until:
            pass
        return evaluate(model, windows, k, *args, **kwargs)

    monkeypatch.setattr(estimate, "evaluate", slow_selection)
    positions = np.random.default_rng(0).normal(size=(8, 20, 2)).astype(np.float32)
    windows = Windows(positions, np.arange(9))
    tasks = [Task(name, windows, windows, windows) for name in ("a", "b")]

    def cost(select: str) -> float:
        train = TrainConfig(batch_scenes=4, val_every=0, select=select, select_k=PICKS)
        config = SimpleNamespace(
            method=lambda name: Finetune(ModelConfig()), train_config=lambda: train, epochs=2, k=2
        )
        return estimate.method_seconds(config, "finetune", tasks, warm_up=True)

    planted = 2 * 2 * SLOW
    assert cost("val") - cost("last") > 0.5 * planted


def test_a_report_is_ours_because_the_marker_records_it_not_because_of_its_name(tmp_path):
    """No list of report names: a folder's marker records the reports its owner wrote, so
    --overwrite removes those and refuses a user's file of the same shape."""
    from sim.experiment.folders import foreign_entry, mark_run
    from sim.experiment.outputs import write_report

    out = tmp_path / "study"
    out.mkdir()
    mark_run(out)
    figure = lambda report, path: path.write_bytes(b"\x89PNG")  # noqa: E731
    write_report(out, "echo", {"rows": []}, lambda report: "# echo\n", figure)
    assert sorted(p.name for p in out.iterdir() if p.name != ".c2i-run") == [
        "echo.json",
        "echo.md",
        "echo.png",
    ]
    assert foreign_entry(out) is None
    (out / "study.md").write_text("a user's notes, named like a report")
    assert foreign_entry(out) == out / "study.md"
