"""The fair benchmark: tuning that moves a bad default and cannot see test splits or later
tasks, and one command that tunes, evaluates, ranks and resumes."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from c2inet.errors import InputError
from c2inet.trainer import Result
from sim.bench import main
from sim.experiment import ExperimentConfig
from sim.experiment.config import Execution, Job
from sim.experiment.jobs import JobResult, prepare
from sim.experiment.race import race_seed
from sim.experiment.trials import trial_seconds, validation_inputs
from sim.experiment.tuning import TuneConfig, run_tuning
from sim.studies.benchmark import BATCH, PRESETS
from sim.studies.benchmark.config import BenchConfig
from sim.studies.benchmark.estimate import estimate_bench, estimate_table

BAD_LR = 1e-5  # a default that barely trains in two epochs


def bench_of(scenario: str) -> BenchConfig:
    base = ExperimentConfig(
        scenario,
        methods=("finetune", "cv"),
        quick=True,
        settings={"train": {"lr": BAD_LR}},
        record=False,
    )
    return BenchConfig(base, trials=4)


@pytest.fixture(scope="module")
def tuned(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("tuning")
    tuning = bench_of("crowd_noise_0.1,0.2").tuning()
    return run_tuning(tuning, root / "a", Execution(cache=root / "cache"))


def test_tuning_moves_a_bad_default_and_tries_it_first(tuned):
    finetune = tuned["finetune"]
    assert [t["params"]["train.lr"] for t in finetune["trials"]][0] == BAD_LR
    assert len(finetune["trials"]) == 4 and finetune["settings"]["train"]["lr"] != BAD_LR
    assert finetune["objective"] < finetune["default_objective"]
    assert tuned["cv"] == {"settings": {}, "trials": []}  # nothing to tune: no trials spent


def test_tuning_never_sees_a_test_split_or_a_later_task(tuned, tmp_path):
    other = bench_of("crowd_noise_0.1,0.5")  # another later task (so other test splits too)
    same = bench_of("crowd_noise_0.1,0.2").tuning()
    assert replace(other.tuning(), study_prefix="") == replace(same, study_prefix="")
    assert other.tuning().study_prefix != same.study_prefix  # two benchmarks, never one study
    again = run_tuning(other.tuning(), tmp_path / "b", Execution(cache=tmp_path / "cache"))
    assert again == tuned
    execution = Execution(cache=tmp_path / "cache")
    curriculum = prepare(replace(other.base, record=False), execution)
    inputs = validation_inputs(curriculum)
    for task, original in zip(inputs.tasks, curriculum.inputs.tasks, strict=True):
        assert task.test is original.val and task.test is not original.test


def test_start_up_trials_run_in_one_round_and_choose_as_one_at_a_time(tuned, tmp_path, monkeypatch):
    """Of 4 trials the first 2 (the defaults and a random draw) no result can change: they run
    in one round, and the trials and the choice are those of one trial a round."""
    from sim.experiment import tuning

    rounds = []

    def counted(planned, *args, **kwargs):
        rounds.append(len(planned))
        return run_together(planned, *args, **kwargs)

    run_together = tuning.run_together
    monkeypatch.setattr(tuning, "run_together", counted)
    monkeypatch.setattr(tuning, "_round_size", lambda *_: 1)  # one at a time
    tuning_of = bench_of("crowd_noise_0.1,0.2").tuning()
    alone = run_tuning(tuning_of, tmp_path / "alone", Execution(cache=tmp_path / "cache"))
    assert rounds == [1, 1, 1, 1] and alone == tuned
    rounds.clear()
    monkeypatch.undo()  # the real rounds, still counted
    monkeypatch.setattr(tuning, "run_together", counted)
    run_tuning(tuning_of, tmp_path / "together", Execution(cache=tmp_path / "cache"))
    assert rounds == [2, 1, 1]


def test_trials_skip_what_their_objective_never_reads_and_the_choice_keeps_it(tmp_path):
    """A trial measures no diagnostics, no validation curves and no other test-time rule for
    C (its objective is the final point-prediction ADE); the chosen settings carry none of it."""
    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("c2inet-online",), quick=True)
    chosen = run_tuning(TuneConfig(base, trials=1), tmp_path, Execution(cache=tmp_path / "c"))
    trial = json.loads((tmp_path / "trials/c2inet-online/trial_000/metrics.json").read_text())
    method = trial["methods"]["c2inet-online"]
    assert "ade_k1" in method and "ade_c_prior" not in method
    assert not method["diagnostics"]
    assert not any(key.startswith("val_ade") for row in method["history"] for key in row)
    assert "diagnostics" not in chosen["c2inet-online"]["settings"].get("train", {})


def test_a_domain_without_validation_holds_out_the_end_of_its_training_scenes(tmp_path):
    curriculum = prepare(
        ExperimentConfig("eth_ucy_univ", methods=("cv",), quick=True, record=False),
        Execution(cache=tmp_path / "cache"),
    )
    (original,) = curriculum.inputs.tasks
    assert original.val is None
    (task,) = validation_inputs(curriculum).tasks
    assert len(task.train) + len(task.val) == len(original.train)
    assert len(task.val) == len(original.train) - int(0.8 * len(original.train))
    kept = original.train.subset(np.arange(len(task.train), len(original.train)))
    np.testing.assert_array_equal(task.val.positions, kept.positions)
    assert task.test is task.val


def test_the_command_ranks_every_method_and_resumes_to_the_same_leaderboard(tmp_path, capsys):
    """Three methods ranked, joint-scratch apart; seed s draws its own data, the same for every
    method; the decisive pair gets seeds until its interval is narrow or it has the most."""
    out = tmp_path / "bench"
    argv = [
        "--scenario",
        "crowd_noise_0.1,0.2",
        "--methods",
        "finetune,ewc,cv,joint-scratch",
        "--compare",
        "ewc,finetune",
        "--width",
        "0.0001",
        "--max-seeds",
        "3",
        "--seeds",
        "2",
        "--trials",
        "2",
        "--quick",
        "--no-record",
        "--prune",
        "--cache",
        str(tmp_path / "cache"),
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    board = json.loads((out / "leaderboard.json").read_text())
    assert [e["rank"] for e in board["entries"]] == [1, 2, 3]
    means = [e["final_ade_k1"]["mean"] for e in board["entries"]]
    assert means == sorted(means) and board["tune_scenario"] == "crowd_noise_0.1"
    assert board["prune"] and "stopped early" in (out / "leaderboard.md").read_text()
    entry = {e["method"]: e for e in board["entries"]}
    assert "joint-scratch" not in entry  # a reference is never ranked
    assert [r["method"] for r in board["references"]] == ["joint-scratch"]
    assert "joint-scratch" in (out / "leaderboard.md").read_text().split("References")[1]
    decisive = board["decisive"]  # an interval of 0.1 mm is never reached: the most seeds
    assert decisive["pair"] == ["ewc", "finetune"] and decisive["seeds"] == 3
    assert "undecided" in decisive["verdict"] or "better" in decisive["verdict"]
    assert board["seeds"] == 2 and entry["ewc"]["final_ade_k1"]["interval"] is not None

    def domains(method: str, seed: int) -> list[str]:
        card = out / "evaluation" / method / f"seed_{seed}" / "run_card.json"
        return [d["hash"] for d in json.loads(card.read_text())["domains"]]

    assert domains("ewc", 0) == domains("finetune", 0) == domains("cv", 0)  # paired
    assert domains("finetune", 0) != domains("finetune", 1)  # each seed its own data
    assert (out / "evaluation" / "ewc" / "seed_2").is_dir()  # the pair's third seed
    assert not (out / "evaluation" / "cv" / "seed_2").exists()
    assert entry["ewc"]["memory_floats"] > 0 and entry["finetune"]["memory_floats"] == 0
    assert entry["ewc"]["trials"] == entry["finetune"]["trials"] == 2  # the same budget
    assert "strength" in entry["ewc"]["settings"]["ewc"]
    assert entry["finetune"]["final_ade_k1"]["p_value"] == 1.0  # the reference against itself
    for name in ("leaderboard.md", "leaderboard.png", "results.parquet", "tuning/tuning.json"):
        assert (out / name).stat().st_size > 0
    assert "| 1 |" in (out / "leaderboard.md").read_text()
    assert main([*argv, "--resume"]) == 0
    again = json.loads((out / "leaderboard.json").read_text())
    assert again.pop("run")["calls"] == 2 and board.pop("run")["calls"] == 1
    assert again == board
    from sim.experiment.folders import foreign_entry

    assert foreign_entry(out) is None  # every file is the benchmark's: --overwrite may remove it
    capsys.readouterr()
    assert main(["cubic"]) == 2
    assert "preset 'cubic': unknown" in capsys.readouterr().err


def test_a_replay_budget_gives_every_replay_method_the_same_scenes():
    base = ExperimentConfig(
        "crowd_noise_0.1..0.4", methods=("coresets", "agem", "derpp", "finetune"), quick=True
    )
    settings = BenchConfig(base, replay_budget=60).base.settings
    assert settings.pop("train") == {"batch_scenes": BATCH}  # the protocol's batch
    assert settings == {
        "coresets": {"per_task": 20},  # 3 earlier tasks x 20 replayed at the last task
        "agem": {"per_task": 20},
        "derpp": {"buffer": 60},
    }
    with pytest.raises(InputError, match="replay budget"):
        BenchConfig(base, replay_budget=0)


def test_a_presets_data_sizes_reach_both_curricula_under_the_users_own():
    density = PRESETS["density"]
    assert density.data == {"splits.train": 40}  # many agents a scene: fewer scenes fit the hour
    base = ExperimentConfig(density.scenario, methods=("finetune",))
    tuning = density.tune_scenario
    bench = BenchConfig(base, name="density", tune_scenario=tuning, data=density.data)
    for config in (bench.base, bench.tuning().base):
        assert {spec.family.splits.train for spec in config.specs} == {40}
    given = replace(base, settings={"data": {"splits.train": 90}})
    bench = BenchConfig(given, name="density", tune_scenario=tuning, data=density.data)
    assert {spec.family.splits.train for spec in bench.base.specs} == {90}
    assert bench.given == {"data": {"splits.train": 90}}
    assert BenchConfig(base, data=density.data).key() != BenchConfig(base).key()


def test_bad_tuning_options_are_refused():
    with pytest.raises(InputError, match="trials must be at least 1"):
        TuneConfig(ExperimentConfig("crowd_noise_0.1", methods=("cv",)), trials=0)
    with pytest.raises(InputError, match="warmup tasks must be at least 0"):
        TuneConfig(ExperimentConfig("crowd_noise_0.1", methods=("cv",)), warmup_tasks=-1)


def test_a_diverged_trial_counts_as_the_worst_and_tuning_moves_on(tmp_path, monkeypatch):
    """A NaN objective is told as +inf (asked again, it would get the same settings for ever),
    and written as null."""
    import math

    from sim.experiment import tuning

    def diverging(planned, execution, resume, argv, costs=None, figures=True):
        job = JobResult(Job("finetune", 0), Result(["t"], {"ade_k1": np.array([[math.nan]])}, [{}]))
        return [({}, [job])] * len(planned)

    monkeypatch.setattr(tuning, "run_together", diverging)
    base = ExperimentConfig("crowd_noise_0.1", methods=("finetune",), quick=True, record=False)
    chosen = run_tuning(TuneConfig(base, trials=2), tmp_path, Execution(cache=tmp_path / "c"))
    assert [t["objective"] for t in chosen["finetune"]["trials"]] == [None, None]  # JSON null
    assert len(chosen["finetune"]["trials"]) == 2


def test_trials_worse_than_the_median_so_far_stop_early_and_resume_alike(tmp_path):
    """Pruning: the defaults run alone first; after each task past the warm-up but the last, a
    later trial stops when its objective so far is above the median of the trials finished
    before its round; a pruned trial is never chosen, and a second tuning over the same folder
    changes nothing."""
    base = ExperimentConfig("crowd_noise_0.1..0.3", methods=("finetune",), quick=True, record=False)
    tune = TuneConfig(base, trials=6, prune=True)
    execution = Execution(cache=tmp_path / "cache")
    assert tune.warmup_tasks == 1 and not TuneConfig(base).prune  # off by default
    chosen = run_tuning(tune, tmp_path / "a", execution)["finetune"]
    trials = chosen["trials"]
    rounds = [[0], [1, 2], [3], [4], [5]]  # 3 start-up trials, the defaults alone first
    for i, round_ in enumerate(rounds):
        before = [trials[k]["objective_so_far"] for r in rounds[:i] for k in r]
        before = [curve for curve in before if len(curve) == 3]  # the finished ones
        for k in round_:
            curve, tasks = trials[k]["objective_so_far"], 3
            if before and curve[1] > np.median([c[1] for c in before]):  # not after task 0
                tasks = 2
            assert trials[k]["tasks"] == tasks and trials[k]["pruned"] == (tasks < 3)
            assert (trials[k]["objective"] is None) == trials[k]["pruned"]
    pruned = [k for k, trial in enumerate(trials) if trial["pruned"]]
    assert pruned, "no trial was pruned: the test cannot tell pruning from none"
    best = min(t["objective"] for t in trials if t["objective"] is not None)
    assert len(trials) == 6 and chosen["objective"] == best
    folder = tmp_path / "a" / "trials" / "finetune" / f"trial_{pruned[0]:03d}"
    learnt = json.loads((folder / "metrics.json").read_text())["methods"]["finetune"]
    assert {epoch["task"] for epoch in learnt["history"]} == {0, 1}  # the third not trained
    jobs = tmp_path / "a" / "trials" / "finetune"
    full = [  # what orders the jobs: a full trial's CPU seconds, not a pruned one's part
        json.loads(path.read_text())["cpu_seconds"]
        for path in jobs.glob("trial_*/jobs/*/seed_*/result.json")
        if int(path.parts[-5].removeprefix("trial_")) not in pruned
    ]
    assert trial_seconds(tmp_path / "a", "finetune") == pytest.approx(np.mean(full))
    assert run_tuning(tune, tmp_path / "a", execution)["finetune"] == chosen
    unpruned = run_tuning(replace(tune, prune=False, trials=3), tmp_path / "b", execution)
    unpruned = unpruned["finetune"]
    assert all(t["tasks"] == 3 for t in unpruned["trials"])


def test_the_benchmark_estimate_times_a_trial_as_tuning_runs_it_and_adds_every_job(
    tmp_path, monkeypatch
):
    """``estimate_bench``: a trial is timed on the tuning curriculum's validation data with what
    trials skip switched off, a job on the evaluated curriculum; the totals count every trial of
    every tuned method and every seed, and the wall time shares them over the jobs."""
    from sim.experiment.estimate import lanes_seconds
    from sim.studies.benchmark import estimate as bench_module

    timed = []

    def recorded(config, tasks):
        timed.append((config, tasks))
        return {name: 10.0 * len(tasks) for name in config.methods}  # no clock in a test

    monkeypatch.setattr(bench_module, "job_seconds", recorded)
    base = ExperimentConfig(
        "crowd_noise_0.1,0.2", methods=("finetune", "cv"), seeds=2, quick=True, record=False
    )
    bench = BenchConfig(base, trials=3)
    cost = estimate_bench(bench, Execution(jobs=2, cache=tmp_path / "cache"))
    (trial_config, trial_tasks), (job_config, job_tasks) = timed
    assert trial_config.scenario == "crowd_noise_0.1" and job_config.scenario == base.scenario
    train = trial_config.train_config()
    for config in (trial_config, job_config):  # both lean, as they run
        train = config.train_config()
        assert not train.diagnostics and not train.test_rules and train.val_every == 0
        assert not train.eval_unseen and train.batch_scenes == BATCH
    assert all(task.test is task.val for task in trial_tasks) and len(job_tasks) == 2
    assert cost["trials"] == {"finetune": 3, "cv": 0}
    assert cost["tuning_cpu_seconds"] == 3 * 10.0
    made = cost["generation_cpu_seconds"]  # seed 1's data (its own test below)
    assert cost["cpu_seconds"] == pytest.approx(3 * 10.0 + 2 * (20.0 + 20.0) + made)
    assert cost["wall_seconds"] == pytest.approx((30.0 + made) / 2 + lanes_seconds([20.0] * 4, 2))
    table = estimate_table(bench, cost)  # what ``sim.bench --estimate`` prints
    assert "| finetune | 10.0 | 3 | 20.0 | 2 | 70 |" in table
    assert "| cv | - | 0 | 20.0 | 2 | 40 |" in table
    assert "3 tuning trials and 4 evaluation jobs, 2 at a time" in table
    raced = estimate_bench(
        replace(bench, race=2, race_seeds=2), Execution(jobs=2, cache=tmp_path / "cache")
    )
    assert raced["trials"] == {"finetune": 3 + 2 * 2, "cv": 0}  # the race's runs count


def test_the_estimate_counts_the_staged_designs_grids_not_optunas_trials():
    """The staged design runs each method's learning rates, then two new points of each further
    knob (every other value of a choice), on every draw: the estimate counts those runs (it
    counted Optuna's 10 trials a method: 160 on eth-ucy, whose tuning ran 458)."""
    from sim.experiment.design import Design
    from sim.studies.benchmark.estimate import tuning_runs

    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("finetune", "ewc", "c2inet-online"))
    staged = BenchConfig(base, design=Design(lr_points=5, draws=2))
    assert tuning_runs(staged, "finetune") == 5 * 2
    assert tuning_runs(staged, "ewc") == (5 + 2) * 2  # its strength
    # five knobs of a range and one choice of two values (c_detached)
    assert tuning_runs(staged, "c2inet-online") == (5 + 5 * 2 + 1) * 2
    assert tuning_runs(staged, "cv") == 0
    assert tuning_runs(BenchConfig(base, trials=7), "c2inet-online") == 7


def test_the_estimate_counts_making_the_data_the_cache_lacks_and_makes_it_once(
    tmp_path, monkeypatch
):
    """Every evaluation seed draws its own data, made by the driver beside the running jobs:
    the estimate makes the first seed the cache lacks (timed, so the cache then holds it) and
    counts it for each such seed; once every seed is cached, it counts nothing."""
    from sim.experiment.curriculum import is_cached
    from sim.studies.benchmark import estimate as bench_module

    monkeypatch.setattr(
        bench_module, "job_seconds", lambda config, tasks: dict.fromkeys(config.methods, 1.0)
    )
    execution = Execution(jobs=2, cache=tmp_path / "cache")
    base = ExperimentConfig(
        "crowd_noise_0.1", methods=("finetune", "cv"), seeds=3, quick=True, record=False
    )
    bench = BenchConfig(base, trials=1)
    cost = estimate_bench(bench, execution)
    assert cost["generation_cpu_seconds"] > 0
    seeds = [replace(base, seed=s) for s in range(3)]
    assert [is_cached(config, execution) for config in seeds] == [True, True, False]
    jobs = 1.0 * 3 * 2 + 1.0 * 1  # every job and the trial
    assert cost["cpu_seconds"] == pytest.approx(jobs + cost["generation_cpu_seconds"])
    assert "of them making data" in estimate_table(bench, cost)
    for config in seeds:  # every seed made: nothing left to make
        prepare(config, execution)
    assert estimate_bench(bench, execution)["generation_cpu_seconds"] == 0.0


def test_the_estimate_flag_prints_the_cost_and_writes_nothing(tmp_path, capsys, monkeypatch):
    from sim.studies.benchmark import estimate as bench_module

    monkeypatch.setattr(
        bench_module, "job_seconds", lambda config, tasks: dict.fromkeys(config.methods, 1.0)
    )
    monkeypatch.chdir(tmp_path)
    args = ["--scenario", "crowd_noise_0.1,0.2", "--methods", "finetune,cv", "--quick"]
    assert main([*args, "--seeds", "2", "--estimate", "--cache", "cache"]) == 0
    assert "| finetune | 1.0 |" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache"]  # no benchmark folder


@pytest.mark.parametrize("kind", ["sqlite", "journal"])
def test_a_shared_storage_keeps_two_benchmarks_apart(tmp_path, kind):
    """Two benchmarks tuned on the same curriculum but evaluating different ones, into one
    database or one journal file: each runs its own trials under its own studies (the second
    once took the first's and ran none)."""
    import optuna

    from sim.experiment.storage import storage_of

    url = f"sqlite:///{tmp_path / 'shared.db'}" if kind == "sqlite" else f"journal:{tmp_path / 'j'}"
    storage = storage_of(url)
    execution = Execution(cache=tmp_path / "cache")
    for name, scenario in (("a", "crowd_noise_0.1,0.2"), ("b", "crowd_noise_0.1,0.3")):
        base = ExperimentConfig(scenario, methods=("finetune",), quick=True, record=False)
        bench = BenchConfig(base, name=name, trials=1, storage=url)
        run_tuning(bench.tuning(), tmp_path / name, execution)
        assert (tmp_path / name / "trials" / "finetune" / "trial_000" / "metrics.json").is_file()
    names = sorted(optuna.get_all_study_names(storage))
    assert len(names) == 2 and [n.split("-")[0] for n in names] == ["a", "b"]
    assert all(n.endswith(":finetune") for n in names)
    assert all(len(optuna.load_study(study_name=n, storage=storage).trials) == 1 for n in names)


def test_a_tuning_seed_reseeds_the_tuning_alone_under_a_key_of_its_own():
    """``--tuning-seed``: a second tuning of one benchmark draws its own trials (the sampler
    and the trials' data follow the tuning's seed) while the evaluation keeps its seeds, so the
    two tunings' choices are compared on the same evaluation; its studies never share a key."""
    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("finetune",), quick=True, seed=3)
    first, second = BenchConfig(base), BenchConfig(base, tuning_seed=7)
    assert first.tuning().base.seed == 3 and second.tuning().base.seed == 7
    assert first.base.seed == second.base.seed == 3
    assert first.key() != second.key()
    assert BenchConfig(base, tuning_seed=3).key() == first.key()  # its own seed: the same tuning
    assert "tuning_seed" not in first.to_json() and second.to_json()["tuning_seed"] == 7


def test_a_gp_sampler_asks_its_own_trials_under_a_key_of_its_own_and_resumes(tmp_path):
    """``--sampler gp``: after the start-up draws Optuna's Gaussian process asks (other settings
    than TPE from the same seeds), its studies have a key of their own (TPE's boards keep theirs),
    the board says so, and a resumed tuning asks and chooses the same."""
    import optuna

    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("finetune",), quick=True, record=False)
    tpe, gp = BenchConfig(base, trials=3), BenchConfig(base, trials=3, sampler="gp")
    assert tpe.key() != gp.key() and "sampler" not in tpe.to_json()
    execution = Execution(cache=tmp_path / "cache")
    asked = {}
    for name, bench in (("tpe", tpe), ("gp", gp)):
        chosen = run_tuning(bench.tuning(), tmp_path / name, execution)
        storage = f"sqlite:///{tmp_path / name / 'tuning.db'}"
        study = optuna.load_study(study_name=f"{bench.key()}finetune", storage=storage)
        asked[name] = [t.params["train.lr"] for t in study.trials]
        assert run_tuning(bench.tuning(), tmp_path / name, execution) == chosen  # resumed
    assert asked["tpe"][0] == asked["gp"][0] == base.train_config().lr  # the defaults first
    assert asked["tpe"][1] != asked["gp"][1] and asked["tpe"][2] != asked["gp"][2]
    with pytest.raises(InputError, match="sampler 'cma'"):
        TuneConfig(base, sampler="cma")
    with pytest.raises(InputError, match="--sampler 'cma': expected one of tpe, gp"):
        BenchConfig(base, sampler="cma")  # before any folder is claimed
    from sim.studies.benchmark.board_markdown import _sampler_text

    assert _sampler_text(gp.to_json()) == "; then asked by a Gaussian process"
    assert _sampler_text(tpe.to_json()) == ""


def test_a_race_chooses_the_best_mean_over_more_seeds_not_the_best_single_score(
    tmp_path, monkeypatch
):
    """``race``: the best trials by their one score run again on more seeds, each a seed of its
    own (its own data), and the best mean wins. Planted scores rank the trials by learning rate
    on their own seed and the other way round on the race's, so the race must change the
    choice; a race never reads the studies' trials again, so the key is the same."""
    from sim.experiment import race, tuning

    seen = []

    def planted(planned, execution, resume, argv, costs=None, figures=True):
        results = []
        for label, config, folder, _ in planned:
            lr = config.train_config().lr
            score = 1 - lr if "race" in label else lr  # the race reverses the order
            seen.append((label, config.seed, folder.name))
            matrix = np.array([[score]])
            results.append(
                ({}, [JobResult(Job("finetune", 0), Result(["t"], {"ade_k1": matrix}, [{}]))])
            )
        return results

    monkeypatch.setattr(tuning, "run_together", planted)
    monkeypatch.setattr(race, "run_together", planted)
    base = ExperimentConfig("crowd_noise_0.1", methods=("finetune",), quick=True, record=False)
    single = run_tuning(TuneConfig(base, trials=4), tmp_path / "a", Execution())["finetune"]
    raced = run_tuning(TuneConfig(base, trials=4, race=2), tmp_path / "b", Execution())["finetune"]
    lrs = sorted(t["params"]["train.lr"] for t in single["trials"])
    assert single["settings"]["train"]["lr"] == lrs[0] and "race" not in single
    assert raced["settings"]["train"]["lr"] == lrs[1]  # the second best, by its mean
    asked = [t["params"]["train.lr"] for t in raced["trials"]]
    assert [r["trial"] for r in raced["race"]] == sorted(range(4), key=asked.__getitem__)[:2]
    means = [r["mean"] for r in raced["race"]]
    assert raced["objective"] == pytest.approx(min(means))
    assert raced["objective"] == pytest.approx((lrs[1] + 2 * (1 - lrs[1])) / 3)
    race_runs = [(seed, folder) for label, seed, folder in seen if "race" in label]
    assert len(race_runs) == 2 * 2 and len({seed for seed, _ in race_runs}) == 2
    assert base.seed not in {seed for seed, _ in race_runs}  # seeds of their own
    assert {folder for _, folder in race_runs} == {
        f"race_{r['trial']:03d}_seed_{k}" for r in raced["race"] for k in (1, 2)
    }
    assert race.race_seed(0, 1) != race.race_seed(1, 1)  # two tunings share no race data
    bench = BenchConfig(replace(base, methods=("finetune", "cv")))
    assert replace(bench, race=3).key() == bench.key()  # the trials are the same
    assert "race" not in bench.to_json() and replace(bench, race=3).to_json()["race"] == 3
    with pytest.raises(InputError, match="race seeds must be at least 1"):
        TuneConfig(base, race=2, race_seeds=0)


def test_a_real_race_runs_and_resumes_to_the_same_choice(tmp_path):
    base = ExperimentConfig("crowd_noise_0.1", methods=("finetune",), quick=True, record=False)
    tune, execution = TuneConfig(base, trials=2, race=1, race_seeds=1), Execution(cache=tmp_path)
    chosen = run_tuning(tune, tmp_path / "t", execution)["finetune"]
    (entry,) = chosen["race"]
    folder = tmp_path / "t" / "trials" / "finetune" / f"race_{entry['trial']:03d}_seed_1"
    config = json.loads((folder / "config.json").read_text())["experiment"]
    assert config["seed"] == race_seed(base.seed, 1)
    assert len(entry["objectives"]) == 2 and entry["objectives"][0] != entry["objectives"][1]
    assert run_tuning(tune, tmp_path / "t", execution)["finetune"] == chosen


def test_every_preset_tunes_on_three_tasks_or_more_outside_what_it_evaluates():
    """The tuning curriculum shares no value with the evaluated one (ETH-UCY, with no other
    real recording, tunes on held-out training scenes of its own: it has no validation split,
    so trials never read what it evaluates)."""
    from sim.scenario import parse_scenario
    from sim.studies.benchmark import PRESETS

    for name, preset in PRESETS.items():
        evaluated, tuning = parse_scenario(preset.scenario), parse_scenario(preset.tune_scenario)
        assert len(tuning) >= 3, name
        if name == "eth-ucy":
            assert all(not spec.knobs["val"] for spec in tuning)
            continue
        shared = {s.value for s in evaluated} & {s.value for s in tuning}
        assert not shared, f"{name} tunes on {sorted(shared)}, which it evaluates"
    with pytest.raises(InputError, match="three or more"):
        BenchConfig(ExperimentConfig("crowd_noise_0.1..0.3"), tune_scenario="crowd_noise_0.15")
    with pytest.raises(InputError, match="against finetune"):
        BenchConfig(ExperimentConfig("crowd_noise_0.1..0.3", methods=("ewc", "cv")))


def test_holm_over_the_board_unmarks_a_borderline_method():
    """A p of 0.03 is significant alone; on a board of three tests it is 0.09 after Holm."""
    from sim.studies.benchmark.leaderboard import adjust

    def cell(p):
        return {"p_value": p, "significant": p is not None and p < 0.05}

    comparison = {
        name: {"final_ade_k1": cell(p), "final_ade": cell(p)}
        for name, p in (("finetune", 1.0), ("a", 0.03), ("b", 0.5), ("c", 0.6))
    }
    assert comparison["a"]["final_ade_k1"]["significant"]
    adjust(comparison)
    a = comparison["a"]["final_ade_k1"]
    assert a["p_raw"] == 0.03 and a["p_value"] == pytest.approx(0.09) and not a["significant"]
    assert comparison["finetune"]["final_ade_k1"]["p_value"] == 1.0  # not in the family


def test_a_bad_storage_is_one_line_before_anything_is_written(tmp_path, capsys):
    """Refused before the folder is claimed: a URL that is none, a file that is no database, a
    database of another application (left as it was), a server that does not answer."""
    import sqlite3

    foreign = tmp_path / "app.db"
    with sqlite3.connect(foreign) as db:
        db.execute("CREATE TABLE accounts (id INTEGER)")
    before = foreign.read_bytes()
    (tmp_path / "notes.txt").write_text("not a database")
    cases = {
        "notaurl": "not a database URL",
        f"sqlite:///{tmp_path / 'notes.txt'}": "no SQLite database",
        f"sqlite:///{foreign}": "another application's tables",
        f"sqlite:///{tmp_path / 'missing' / 'x.db'}": "cannot be opened",
        f"journal:{tmp_path / 'missing' / 'journal'}": "folder",
        f"journal:{tmp_path / 'notes.txt'}": "no Optuna journal",
    }
    for url, message in cases.items():
        out = tmp_path / "bench"
        argv = ["--scenario", "crowd_noise_0.1..0.3", "--methods", "finetune", "--quick"]
        assert main([*argv, "--storage", url, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1 and not out.exists()
    assert foreign.read_bytes() == before
    assert (tmp_path / "notes.txt").read_text() == "not a database"


def test_a_planted_trial_outside_the_search_space_is_refused_not_chosen(tmp_path):
    """A stored study of the benchmark's name holding a finished trial the search could not
    have asked (a data knob, a rate beyond the range), and the best of them: never the choice."""
    import optuna
    from optuna.distributions import FloatDistribution

    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("finetune",), quick=True)
    tune = TuneConfig(base, trials=1)
    storage = f"sqlite:///{(tmp_path / 'tuning.db').resolve()}"
    study = optuna.create_study(study_name="finetune", storage=storage, direction="minimize")
    planted = optuna.trial.create_trial(
        params={"train.lr": 9.0},
        distributions={"train.lr": FloatDistribution(1e-5, 10.0, log=True)},
        value=0.0,
    )
    study.add_trial(planted)
    with pytest.raises(InputError, match=r"holds a trial with train.lr=9.0, which finetune"):
        run_tuning(tune, tmp_path, Execution(cache=tmp_path / "cache"))


def test_reproductions_tuned_table_is_made_from_the_committed_boards():
    """REPRODUCTION's tuned Table 2 is the boards' own numbers: stale, the check fails."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    check = [sys.executable, str(root / "scripts" / "tuned_table.py"), "--check"]
    done = subprocess.run(check, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout


def test_the_tuned_table_ranks_methods_by_their_mean_rank_and_marks_holm():
    from sim.studies.benchmark.board_markdown import boards_table

    def entry(method, rank, mean, significant):
        return {
            "method": method,
            "rank": rank,
            "final_ade_k1": {"mean": mean, "significant": significant},
        }

    boards = {
        "a": {"entries": [entry("x", 1, 0.1, True), entry("finetune", 2, 0.2, False)]},
        "b": {
            "entries": [entry("y", 1, 0.2, True), entry("finetune", 2, 0.3, False)]
            + [entry("x", 3, 0.4, False)],
            "decisive": {
                "pair": ["x", "finetune"],
                "seeds": 30,
                "difference": 0.1,
                "interval": [0.05, 0.15],
                "verdict": "finetune is better",
            },
            "references": [{"method": "joint", "final_ade_k1": {"mean": 0.25}}],
        },
    }
    table = boards_table(boards).splitlines()
    assert table[0] == "| method | `a` | `b` |"
    assert table[2:5] == [  # mean ranks: y 1, finetune 2, x 2 (1 and 3; ties by name)
        "| y | - | 0.200 (1) * |",
        "| finetune | 0.200 (2) | 0.300 (2) |",
        "| x | 0.100 (1) * | 0.400 (3) |",
    ]
    assert (
        "- `b`: x minus finetune, 30 paired seeds: +0.1000 m [+0.0500, +0.1500]; finetune is better"
        in table
    )
    assert "- `b`: joint 0.250" in table


def test_settings_tuned_by_another_benchmark_reach_every_job_and_no_trial_runs(tmp_path, capsys):
    """``--tuned-from``: every method's chosen settings come from another board's tuning.json
    (its folder found), no trial runs, the board says whose settings it used, and a resume with
    another file is refused; a file without a method's settings, or with a setting no option
    takes, is one line before anything is written."""
    source = tmp_path / "source"
    (source / "tuning").mkdir(parents=True)
    chosen = {
        "finetune": {"settings": {"train": {"lr": 0.0123}}, "trials": [{"pruned": False}] * 3},
        "ewc": {"settings": {"train": {"lr": 0.0045}, "ewc": {"strength": 7.5}}, "trials": []},
        "cv": {"settings": {}, "trials": []},
    }
    (source / "tuning" / "tuning.json").write_text(json.dumps(chosen))
    (source / "leaderboard.json").write_text(json.dumps({"tune_scenario": "crowd_noise_0.3"}))
    out = tmp_path / "bench"
    argv = [
        *("--scenario", "crowd_noise_0.1,0.2", "--methods", "finetune,ewc,cv", "--seeds", "2"),
        *("--quick", "--no-record", "--cache", str(tmp_path / "cache"), "--out", str(out)),
    ]
    capsys.readouterr()
    assert main([*argv, "--tuned-from", str(source)]) == 0
    said = capsys.readouterr().err
    assert "--tuned-from: ewc: train.lr=0.0045, ewc.strength=7.5" in said
    assert "--tuned-from: cv: its defaults" in said
    config = json.loads((out / "evaluation" / "ewc" / "seed_1" / "config.json").read_text())
    assert config["experiment"]["settings"]["train"]["lr"] == 0.0045
    assert config["experiment"]["settings"]["ewc"]["strength"] == 7.5
    finetune = json.loads((out / "evaluation" / "finetune" / "seed_0" / "config.json").read_text())
    assert finetune["experiment"]["settings"]["train"]["lr"] == 0.0123
    assert not (out / "tuning").exists()  # no trial ran
    board = json.loads((out / "leaderboard.json").read_text())
    assert board["tuned_from"]["file"].endswith("tuning.json")
    assert board["tune_scenario"] == "crowd_noise_0.3"
    assert {e["method"]: e["trials"] for e in board["entries"]}["finetune"] == 0
    assert "**no tuning here**" in (out / "leaderboard.md").read_text()
    chosen["ewc"]["settings"]["ewc"]["strength"] = 1.0
    (source / "tuning" / "tuning.json").write_text(json.dumps(chosen))
    capsys.readouterr()
    assert main([*argv, "--tuned-from", str(source), "--resume"]) == 2  # other settings
    assert "error:" in capsys.readouterr().err
    for broken, why in (
        ({"finetune": chosen["finetune"], "cv": chosen["cv"]}, "no chosen settings of 'ewc'"),
        ({**chosen, "ewc": {"settings": {"ewc": {"strenght": 1}}}}, "ewc:"),
        ([1, 2], "expected a table of methods"),
        # issue 64's cases: what --set refuses, and what no tuning of the method could choose
        ({**chosen, "ewc": {"settings": {"data": {"agents": 3}}}}, "the data are the board's"),
        ({**chosen, "ewc": {"settings": {"model": {"z_dim": 4}}}}, "outside ewc's search"),
        ({**chosen, "ewc": {"settings": {"derpp": {"alpha": 1}}}}, "an unknown scope"),
    ):
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps(broken))
        assert main([*argv, "--tuned-from", str(bad), "--out", str(tmp_path / "no")]) == 2
        err = capsys.readouterr().err
        assert why in err and err.count("\n") == 1 and not (tmp_path / "no").exists()
    assert main([*argv, "--tuned-from", str(tmp_path / "none"), "--out", str(tmp_path / "no")]) == 2
    assert "neither a preset" in capsys.readouterr().err


def test_the_ranking_transfer_is_one_for_one_ranking_and_falls_as_it_reverses(script, monkeypatch):
    """``scripts/ranking_transfer.py``: Kendall's tau of a board with itself is 1; with its
    methods' errors reversed, -1; a ranking that holds only within noise has an interval that
    holds less than the point; the committed density boards (40 and 60 scenes) agree partly."""
    root = Path(__file__).resolve().parents[2]
    monkeypatch.syspath_prepend(str(root / "scripts"))  # it imports tuning_stability beside it
    ranking = script("scripts/ranking_transfer.py")
    rng = np.random.default_rng(0)
    a = np.linspace(0.1, 0.5, 6) + rng.normal(0, 0.01, (8, 6))  # 8 seeds, 6 methods well apart
    same = ranking.transfer(a, a + rng.normal(0, 0.01, a.shape), resamples=200)
    assert same["tau"] == pytest.approx(1.0) and same["interval"][1] == pytest.approx(1.0)
    assert ranking.transfer(a, -a, resamples=200)["tau"] == pytest.approx(-1.0)
    noisy = ranking.transfer(a, rng.normal(0.3, 0.2, a.shape), resamples=200)
    assert (
        noisy["interval"][0] < noisy["tau"] < 1
        and noisy["interval"][1] - noisy["interval"][0] > 0.3
    )
    boards = root / "docs" / "leaderboards"
    text = ranking.report(boards / "density", boards / "density-60")
    assert "Kendall's tau +0.65" in text and "| coresets | 0.423 | 1 | 0.423 | 1 | +0 |" in text
    best = ranking.report(boards / "density", boards / "density-60", metric="ade")
    assert "by final ADE of best of K" in best and "| coresets | 0.423 |" not in best
    assert ranking.main([str(root), str(boards / "density")]) == 2  # no board: one line


def test_a_board_says_how_its_jobs_shared_the_machine():
    """Locally its jobs at a time (one job, singular); on Ray the cluster, not ``--jobs``."""
    from sim.studies.benchmark.board_markdown import _parallel_text

    assert _parallel_text({"jobs": 1}) == "1 job at a time"
    assert _parallel_text({"jobs": 2, "backend": "local"}) == "2 jobs at a time"
    assert _parallel_text({"jobs": 2, "backend": "ray"}) == "on a local Ray cluster of 2 CPUs"
    ray = {"jobs": 1, "backend": "ray", "ray_address": "10.0.0.5:6379"}
    assert _parallel_text(ray) == "on the Ray cluster at 10.0.0.5:6379"


def test_a_board_of_a_family_from_a_scenarios_dir_is_sized_without_parsing_it_bare():
    """The fitted crowds' board failed after its last job: its sizes were judged on the scenario
    parsed without ``--scenarios-dir``."""
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "docs" / "calibration" / "hotel"
    base = ExperimentConfig(
        "calibrated_eth_ucy_hotel_0.25",
        methods=("finetune", "cv"),
        epochs=2,
        scenarios_dir=(folder,),
    )
    assert BenchConfig(base, trials=2).sizes() == "reduced"


def test_the_tuning_noise_measure_reads_a_planted_race(script):
    """``benchmarks/tuning_noise.py``: two candidates that move together from draw to draw have
    no paired noise; one better on its own draw than on the others carries a winner's curse."""
    module = script("benchmarks/tuning_noise.py")
    together = np.array([[0.10, 0.20, 0.30], [0.15, 0.25, 0.35]])
    n = module.noise([together])
    assert n["paired"] == pytest.approx(0.0) and n["one_draw"] == pytest.approx(0.1)
    assert n["curse"] == pytest.approx(0.15)  # each scored 0.15 better on its own draw
    cursed = np.array([[0.10, 0.20, 0.20], [0.20, 0.10, 0.30]])
    n = module.noise([cursed])
    assert n["paired"] > 0.1 and n["curse"] == pytest.approx(0.05)  # 0.10 and 0.0 by row
