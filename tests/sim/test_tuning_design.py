"""Tuning as a shipped artefact: the staged design (one grid of learning rates, each knob in
turn, every setting on the same draws, a fitted choice, a bound marked), tuning curricula with
the evaluated configuration, designs that differ by preset, a resumed tuning equal to an
uninterrupted one, and a board that evaluates a shipped artefact without running a trial."""

import json
import math
import shutil
from dataclasses import replace
from importlib import import_module

import numpy as np
import pytest

from c2inet.errors import InputError
from c2inet.options import Choice, Tunable
from c2inet.trainer import TRAIN_SPACE, TrainConfig
from sim.bench import main
from sim.experiment import ExperimentConfig
from sim.experiment.config import Execution
from sim.experiment.design import Design, choose, near_bound
from sim.experiment.staged import MethodSearch, draw_seed, record, run_staged
from sim.scenario import parse_scenario
from sim.studies.benchmark import PRESETS, artefacts
from sim.studies.benchmark.board_markdown import leaderboard_markdown
from sim.studies.benchmark.config import BenchConfig
from sim.studies.benchmark.leaderboard import bounds_of
from sim.studies.benchmark.protocol import run_bench

LR = TRAIN_SPACE["train.lr"]


def test_the_learning_rate_grid_is_one_log_grid_and_a_second_design_moves_it():
    design = Design(lr_low=1e-4, lr_high=1e-2, lr_points=5)
    grid = design.first_points("train.lr", LR, 1e-3)
    np.testing.assert_allclose(np.log10(grid), [-4, -3.5, -3, -2.5, -2])
    moved = design.shifted(0.5).first_points("train.lr", LR, 1e-3)
    np.testing.assert_allclose(np.log10(moved), [-3.75, -3.25, -2.75, -2.25, -1.75])
    strength = Tunable(0.01, 1e4, log=True)  # a knob: its default and a neighbour either side
    knob = design.first_points("strength", strength, 100.0)  # a quarter of 6 decades either side
    np.testing.assert_allclose(knob, [10**0.5, 100.0, 10**3.5])
    assert design.first_points("c_detached", Choice((True, False)), True) == [True, False]
    assert design.beyond(LR, grid, low_side=True) == pytest.approx(10**-4.5)
    assert design.beyond(strength, knob, low_side=False) == pytest.approx(1e4)  # clipped
    assert design.beyond(strength, [*knob, 1e4], low_side=False) is None  # at the bound
    with pytest.raises(InputError):
        Design(lr_points=2)


def test_a_stage_chooses_the_planted_minimum_between_its_grid_points():
    planted = 10**-2.8  # a quadratic in log10(lr) with its minimum between two grid points
    means = {lr: 0.2 + (math.log10(lr) + 2.8) ** 2 for lr in (1e-4, 10**-3.5, 1e-3, 10**-2.5, 1e-2)}
    value, how = choose(LR, means)
    assert value == pytest.approx(planted) and "parabola" in how
    noisy = {**means, 10**-2.5: means[10**-2.5] + 0.3}  # a noisy point cannot throw it far
    assert 10**-3.5 <= choose(LR, noisy)[0] <= 10**-2.5
    edge = {lr: lr for lr in means}  # best at the low edge: the edge itself
    assert choose(LR, edge) == (1e-4, "the best mean, at the grid's edge")
    diverged = {**means, 10**-2.5: math.inf}
    assert choose(LR, diverged)[0] == 1e-3  # a diverged neighbour: no fit through it
    assert choose(Choice((True, False)), {True: 0.3, False: 0.2})[0] is False


def test_the_defaults_are_kept_where_they_score_better_than_the_stages_choice():
    """A walk one knob at a time can end worse than where it began (C2INet-online on density);
    the defaults, run on the same draws, are then what ships, with no bound mark of the walk's."""
    space = {"train.lr": LR, "strength": Tunable(0.01, 1e4, log=True)}
    search = MethodSearch(
        "ewc", space, {"train.lr": 1e-2, "strength": 1e4}, {"train.lr": 3e-3, "strength": 1.0},
        ["train.lr", "strength"],
        stages=[{"knob": "strength", "chosen": 1e4, "at_bound": "high"}],
    )  # fmt: skip
    worse = record(search, chosen=[0.450], defaults=[0.439])
    assert worse["kept"] == "defaults" and worse["at_bound"] == {}
    assert worse["settings"] == {"train": {"lr": 3e-3}, "ewc": {"strength": 1.0}}
    assert (worse["objective"], worse["default_objective"]) == (0.450, 0.439)
    better = record(search, chosen=[0.430], defaults=[0.439])
    assert better["kept"] == "stages" and better["at_bound"] == {"strength": "high"}
    assert better["settings"] == {"train": {"lr": 1e-2}, "ewc": {"strength": 1e4}}
    assert record(search, chosen=[math.inf], defaults=[0.5])["kept"] == "defaults"
    diverged = record(search, chosen=[0.5], defaults=[math.inf])
    assert diverged["kept"] == "stages" and diverged["default_objective"] is None
    assert record(search, chosen=[0.5], defaults=[0.5])["kept"] == "stages"  # a tie: the walk's


def test_the_rule_that_keeps_the_defaults_is_an_option_of_the_design():
    """``every-draw`` (the default) keeps the defaults only where they are lower on each draw,
    ``mean`` on a lower mean over the draws (as every shipped tuning was made): noise's fine-
    tuning, its defaults 0.4 cm better on the mean and 0.5 cm worse on one draw, keeps the
    walk's rate under the first. ``mean`` is left out of the design's JSON, so an artefact made
    before the rule was an option names the same design."""
    search = MethodSearch("finetune", {"train.lr": LR}, {"train.lr": 7e-4}, {"train.lr": 3e-3},
                          ["train.lr"])  # fmt: skip
    chosen, defaults = [0.705576, 0.735331], [0.711041, 0.721142]  # noise's two draws
    mean = Design(keep_defaults="mean")
    assert record(search, chosen, defaults, mean)["kept"] == "defaults"
    assert record(search, chosen, defaults)["settings"] == {"train": {"lr": 7e-4}}
    assert record(search, chosen, [0.7050, 0.7350])["kept"] == "defaults"  # lower on both
    assert Design().keep_defaults == "every-draw"
    assert "keep_defaults" not in mean.to_json()
    assert Design().to_json()["keep_defaults"] == "every-draw"
    from sim.studies.benchmark.board_markdown import _design_text  # what a board says of it

    assert "only where better on every draw" in _design_text(Design().to_json())
    assert "where better on the mean" in _design_text(mean.to_json())
    with pytest.raises(InputError, match="keep_defaults 'median'"):
        Design(keep_defaults="median")


def test_a_choice_at_a_bound_and_kept_defaults_are_marked_on_the_board():
    assert near_bound(LR, LR.low) == "low" and near_bound(LR, LR.high) == "high"
    assert near_bound(LR, 1e-3) is None and near_bound(Choice((1, 2)), 1) is None
    marks = bounds_of("ewc", {"train": {"lr": 1e-3}, "ewc": {"strength": 1e4}})
    assert marks == {"strength": "high"}
    board = {
        "preset": "p", "study_prefix": "p-0:", "scenario": "s", "tune_scenario": "t",
        "sizes": "quick", "epochs": 2,
        "batch_scenes": 16, "k": 5, "trials": 0, "seeds": 2, "reference": "finetune",
        "alpha": 0.05, "run": {"settings": {}, "wall_seconds": 1, "cpu_seconds": 1, "calls": 1,
        "decisive_seconds": 0, "commits": ["x"], "machine": "m", "jobs": 1, "command": "c"},
        "references": [], "decisive": None,
    }  # fmt: skip
    cell = {"mean": 0.2, "interval": None, "difference": 0.0, "difference_interval": None,
            "p_value": None, "significant": False}  # fmt: skip
    entry = {"rank": 1, "method": "ewc", "final_ade_k1": {**cell, "p_signflip": None},
             "final_ade": cell, "forgetting_final_ade_k1": cell, "forgetting_final_ade": cell,
             "memory_floats": 0, "cpu_seconds": 1.0, "settings": {}, "trials": 0, "pruned": 0,
             "at_bound": marks}  # fmt: skip
    text = leaderboard_markdown({**board, "entries": [entry]})
    assert "| ewc † |" in text and "strength at its high bound" in text
    kept = leaderboard_markdown({**board, "entries": [{**entry, "kept": "defaults"}]})
    assert "(its defaults, kept" in kept and "(its defaults, kept" not in text


def test_every_preset_tunes_on_its_evaluated_configuration_and_its_own_design():
    for name, preset in PRESETS.items():
        evaluated = parse_scenario(preset.scenario)
        tuning = parse_scenario(preset.tune_scenario)
        if evaluated[0].family.name.startswith("eth_ucy"):
            continue  # no other recording: held-out training scenes of the same ones
        values = [float(s.label) for s in evaluated]
        tuned = [float(s.label) for s in tuning]
        assert len(tuned) == len(values), name  # as many tasks
        assert np.allclose(np.diff(tuned), np.diff(values)), name  # at the same step
        assert not set(np.round(tuned, 6)) & set(np.round(values, 6)), name  # none evaluated
    designs = {name: preset.design for name, preset in PRESETS.items()}
    assert len(set(designs.values())) == len(designs)  # no two presets share one design


@pytest.fixture(scope="module")
def staged(tmp_path_factory):
    root = tmp_path_factory.mktemp("staged")
    base = ExperimentConfig(
        "crowd_noise_0.1,0.2", methods=("finetune", "ewc", "cv"), quick=True, record=False
    )
    design = Design(lr_low=1e-3, lr_high=1e-2, lr_points=3, draws=2, extend=0)
    execution = Execution(cache=root / "cache")
    return root, base, design, execution, run_staged(base, design, root / "a", execution)


def test_the_staged_tuning_scores_every_setting_on_the_same_draws(staged):
    root, base, design, _, chosen = staged
    assert chosen["cv"] == {"settings": {}, "trials": []}
    for method in ("finetune", "ewc"):
        runs = chosen[method]["trials"]
        assert {r["draw"] for r in runs} == {0, 1}
        for draw in (0, 1):  # common random numbers: one data draw for every setting and method
            assert {r["seed"] for r in runs if r["draw"] == draw} == {draw_seed(base.seed, draw)}
        lr = chosen[method]["stages"][0]
        assert lr["knob"] == "train.lr" and len(lr["points"]) >= 3
        kept = chosen[method]["kept"]
        shipped = chosen[method]["settings"]["train"]["lr"]
        assert shipped == (lr["chosen"] if kept == "stages" else TrainConfig().lr)
        assert math.isfinite(chosen[method]["objective"])
    ewc = chosen["ewc"]
    assert [s["knob"] for s in ewc["stages"]] == ["train.lr", "strength"]
    if ewc["kept"] == "stages":
        assert ewc["settings"]["ewc"]["strength"] == ewc["stages"][1]["chosen"]
    assert draw_seed(0, 0) != draw_seed(1, 0)  # another tuning seed, other draws


def test_a_resumed_staged_tuning_gives_the_same_artefact(staged, tmp_path):
    root, base, design, execution, chosen = staged
    copy = tmp_path / "a"
    shutil.copytree(root / "a", copy)
    ewc_runs = sorted((copy / "trials" / "ewc").iterdir())
    for folder in ewc_runs[-3:]:  # killed: its last runs gone, one half-written
        shutil.rmtree(folder)
    (copy / "tuning.json").unlink()

    def without_cost(table):
        for entry in table.values():
            for run in entry["trials"]:
                run.pop("cpu_seconds", None)
        return table

    again = run_staged(base, design, copy, execution)
    assert without_cost(again) == without_cost(json.loads(json.dumps(chosen)))


def test_a_resumed_tuning_artefact_names_every_call_that_ran_it(staged, tmp_path, monkeypatch):
    root, base, _, execution, _ = staged
    design = Design(lr_low=1e-3, lr_high=1e-2, lr_points=3, draws=1, extend=0)
    bench = BenchConfig(replace(base, methods=("finetune", "cv")), design=design)
    out = tmp_path / "board"
    protocol = import_module(run_bench.__module__)
    monkeypatch.setattr(protocol, "git_commit", lambda: "first")
    first = run_bench(bench, out, execution, tune_only=True)
    [call] = first["provenance"]["calls"]
    assert call["commit"] == "first" and call["runs"] == len(first["methods"]["finetune"]["trials"])
    # killed before it chose (a copy: this process holds the first folder's runs): its last
    # run and the artefact gone, resumed by another commit
    killed = tmp_path / "killed"
    shutil.copytree(out, killed)
    shutil.rmtree(sorted((killed / "tuning" / "trials" / "finetune").iterdir())[-1])
    (killed / f"{bench.name}.json").unlink()
    (killed / "tuning" / "tuning.json").unlink()
    monkeypatch.setattr(protocol, "git_commit", lambda: "second")
    again = run_bench(bench, killed, execution, resume=True, tune_only=True)
    made = again["provenance"]
    assert made["commits"] == ["first", "second"]
    assert [c["runs"] for c in made["calls"]] == [call["runs"], 1]  # the second ran the lost one
    assert made["wall_seconds"] == pytest.approx(sum(c["wall_seconds"] for c in made["calls"]))
    chosen = [
        {m: (e["settings"], e.get("objective")) for m, e in a["methods"].items()}
        for a in (first, again)
    ]
    assert chosen[0] == chosen[1]  # the same choice (a rerun's CPU seconds differ)


def test_a_board_evaluates_its_presets_shipped_tuning_and_runs_no_trial(
    tmp_path, monkeypatch, capsys
):
    shipped = tmp_path / "tunings"
    shipped.mkdir()
    planted = {
        "finetune": {"settings": {"train": {"lr": 0.00123}}, "trials": [], "kept": "defaults"},
        "cv": {"settings": {}, "trials": []},
    }
    artefacts.write_artefact(
        shipped / "noise.json", "noise", "crowd_noise_0.1..0.6", "crowd_noise_0.05..0.55:0.1",
        Design().to_json(), 0, {"made_by": "a test"}, planted,
    )  # fmt: skip
    # on the module itself: the package's name for it is a lazy stand-in until some test
    # imports it, and a value set on the stand-in is read by none of the module's functions
    monkeypatch.setattr(import_module(artefacts.__name__), "SHIPPED", shipped)
    out = tmp_path / "board"
    argv = [
        "noise", "--methods", "finetune,cv", "--seeds", "2", "--quick", "--no-record",
        "--set", "data.splits.train=6", "--cache", str(tmp_path / "cache"), "--out", str(out),
    ]  # fmt: skip
    assert main(argv) == 0
    assert not (out / "tuning").exists()  # no trial ran
    for seed in (0, 1):
        config = json.loads((out / "evaluation" / "finetune" / f"seed_{seed}" / "config.json")
                            .read_text())  # fmt: skip
        assert config["experiment"]["settings"]["train"]["lr"] == 0.00123
    board = json.loads((out / "leaderboard.json").read_text())
    # by its place in the package, not the folder it is installed in
    assert board["tuned_from"]["file"] == "sim/studies/benchmark/tunings/noise.json"
    assert board["tuned_from"]["design"]["kind"] == "staged"
    assert "rests on that one tuning" in (out / "leaderboard.md").read_text()
    (entry,) = [e for e in board["entries"] if e["method"] == "finetune"]
    assert entry["kept"] == "defaults"  # the artefact's mark carried onto the board
    capsys.readouterr()
    assert main([*argv, "--trials", "3", "--out", str(tmp_path / "no")]) == 2
    err = capsys.readouterr().err
    assert "--trials" in err and "--retune" in err and err.count("\n") == 1
    assert not (tmp_path / "no").exists()


def test_sim_run_takes_a_presets_tuned_settings_by_its_name(capsys, tmp_path):
    from sim.run import main as run

    assert run(["--scenario", "crowd_radius_0.1..0.6", "--methods", "derpp", "--tuned-from",
                "radius", "--print-config"]) == 0  # fmt: skip
    printed = capsys.readouterr()
    entry = json.loads(artefacts.shipped("radius").read_text())["methods"]["derpp"]
    assert f"lr = {entry['settings']['train']['lr']}" in printed.out
    assert "batch_scenes = 16" in printed.out and "buffer = 200" in printed.out
    assert run(["--scenario", "crowd_radius_0.1,0.2", "--methods", "derpp,ewc", "--tuned-from",
                "radius", "--print-config"]) == 2  # fmt: skip
    assert "different train.lr" in capsys.readouterr().err
    listed = tmp_path / "list.json"
    listed.write_text("[1, 2]")
    for given, why in ((str(listed), "expected a table of methods"), ("nope", "neither a preset")):
        assert run(["--scenario", "crowd_radius_0.1,0.2", "--methods", "derpp", "--tuned-from",
                    given, "--print-config"]) == 2  # fmt: skip
        err = capsys.readouterr().err
        assert why in err and err.count("\n") == 1
    planted = json.loads(artefacts.shipped("radius").read_text())  # issue 64's case 6
    planted["methods"]["derpp"]["settings"]["data"] = {"agents": 3}
    planted["methods"]["ewc"]["settings"]["model"] = {"z_dim": 4}
    bad = tmp_path / "planted.json"
    bad.write_text(json.dumps(planted))
    for method, why in (("derpp", "scope 'data'"), ("ewc", "model.z_dim is outside ewc's")):
        assert run(["--scenario", "crowd_radius_0.1,0.2", "--methods", method, "--tuned-from",
                    str(bad), "--print-config"]) == 2  # fmt: skip
        err = capsys.readouterr().err
        assert why in err and err.count("\n") == 1


def test_two_presets_optuna_designs_differ_and_one_presets_does_not_follow_its_curriculum():
    import optuna
    from optuna.distributions import FloatDistribution

    from sim.experiment.tuning import _sampler

    def first_draw(prefix: str) -> float:  # a start-up draw (index 3 of 10 trials)
        study = optuna.create_study(sampler=_sampler(0, "finetune", 3, 10, "tpe", prefix))
        return study.ask({"train.lr": FloatDistribution(1e-5, 5e-2, log=True)}).params["train.lr"]

    assert first_draw("radius-aaaa:") == first_draw("radius-bbbb:")  # another curriculum
    assert first_draw("radius-aaaa:") != first_draw("density-aaaa:")  # another preset


def test_a_setting_two_stages_ask_runs_once(staged):
    """The staged design names a run by its settings and draw: the chosen and the default
    settings, where a stage already ran them, are read back, not run again."""
    _, _, design, _, chosen = staged
    for method in ("finetune", "ewc"):
        runs = chosen[method]["trials"]
        keys = [(json.dumps(r["params"], sort_keys=True), r["draw"]) for r in runs]
        assert len(keys) == len(set(keys))  # no setting ran twice on one draw


@pytest.mark.parametrize(
    ("folder", "preset", "source"),
    [
        ("radius-shipped", "radius", "radius-compiled"),
        ("noise-shipped", "noise", "noise"),
        ("traffic-shipped", "traffic", "traffic"),
    ],
)
def test_a_board_of_an_optuna_tuning_keeps_the_artefact_it_ran(
    folder, preset, source, tmp_path, monkeypatch
):
    """The artefacts that shipped before the staged ones were made from a committed board's
    Optuna tuning: the board evaluated from one keeps it beside it, the very bytes its
    leaderboard names by SHA-256, and ``from_board`` remakes it byte for byte from the source
    board's tuning.json (run from the repository's root, as it was made)."""
    import hashlib
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    kept = root / "docs" / "leaderboards" / folder / f"{preset}.json"
    named = json.loads((kept.parent / "leaderboard.json").read_text())["tuned_from"]
    assert hashlib.sha256(kept.read_bytes()).hexdigest() == named["sha256"]
    monkeypatch.chdir(root)
    artefacts.from_board(Path("docs/leaderboards") / source, preset, tmp_path / "a.json")
    assert (tmp_path / "a.json").read_bytes() == kept.read_bytes()
    assert json.loads(kept.read_text())["design"]["kind"] == "optuna"


@pytest.mark.parametrize(
    ("preset", "folder", "metric"),
    [
        ("radius", "radius-staged-all", "ade_k1"),
        ("density", "density-staged-all", "ade_k1"),
        ("noise", "noise-every-draw", "ade_k1"),
        ("traffic", "traffic-every-draw", "ade_k1"),
        ("eth-ucy", "eth-ucy", "ade"),
    ],
)
def test_a_staged_shipped_tuning_is_its_boards_own_and_its_bounds_are_marked(
    preset, folder, metric
):
    """Every preset's board tuned every method by the staged design, scoring what the board
    ranks, and wrote the artefact that ships, byte for byte; every knob chosen at a bound of
    its range is marked on the board (on eth-ucy no learning rate is), and so is every method
    whose defaults were kept."""
    from pathlib import Path

    board = Path(__file__).resolve().parents[2] / "docs" / "leaderboards" / folder
    shipped = artefacts.shipped(preset)
    assert shipped.read_bytes() == (board / f"{preset}.json").read_bytes()
    artefact = json.loads(shipped.read_text())
    design = artefact["design"]
    assert design["kind"] == "staged" and design.get("metric", "ade_k1") == metric
    assert json.loads((board / "leaderboard.json").read_text())["metric"] == metric
    tuned = {m: e for m, e in artefact["methods"].items() if "train" in e["settings"]}
    assert len(tuned) == 16
    table = (board / "leaderboard.md").read_text().split("References")[0]
    settings = (board / "leaderboard.md").read_text().split("Chosen settings and cost")[1]
    for method, entry in tuned.items():
        assert (f"| {method} † |" in table) == bool(entry["at_bound"]), method
        row = next(line for line in settings.splitlines() if line.startswith(f"| {method} |"))
        assert ("(its defaults, kept" in row) == (entry["kept"] == "defaults"), method
    if preset == "eth-ucy":
        assert not any("train.lr" in e["at_bound"] for e in tuned.values())


def test_a_tuning_is_found_by_a_presets_name_or_beside_a_staged_board(tmp_path, monkeypatch):
    """``sim.bench --tuned-from``: a preset's name is its shipped artefact, and a staged
    board's folder holds its artefact (``PRESET.json``) where an Optuna board holds
    ``tuning.json``; a bare name that is neither is one line naming what ships."""
    from pathlib import Path

    board = Path(__file__).resolve().parents[2] / "docs" / "leaderboards" / "eth-ucy"
    monkeypatch.chdir(tmp_path)  # no folder of that name here
    by_name, artefact, _ = artefacts.read_tuning(Path("eth-ucy"))
    assert by_name == artefacts.shipped("eth-ucy") and artefact["design"]["kind"] == "staged"
    assert artefacts.read_tuning(board)[0] == board / "eth-ucy.json"
    with pytest.raises(
        InputError, match=r"neither a preset .*eth-ucy, noise, radius, traffic\) nor"
    ):
        artefacts.read_tuning(Path("nowhere"))


def test_sim_run_and_sim_bench_read_a_name_alike(tmp_path, monkeypatch):
    """A file named like a preset where the command runs is that file for both commands (sim.run
    had its own rule and took the shipped artefact); only a preset's own artefact brings its
    board's batch and data sizes."""
    from pathlib import Path

    monkeypatch.chdir(tmp_path)
    Path("radius").write_text(json.dumps({"finetune": {"settings": {"train": {"lr": 0.0123}}}}))
    settings, path = artefacts.tuned_settings("radius", ("finetune",), 2)
    assert Path(path) == Path("radius") == artefacts.read_tuning(Path("radius"))[0]
    assert settings == {"train": {"lr": 0.0123}}  # no board's batch or data sizes
    Path("radius").unlink()
    settings, path = artefacts.tuned_settings("radius", ("finetune",), 2)
    assert Path(path) == artefacts.shipped("radius") and settings["train"]["batch_scenes"] == 16
    assert settings["data"] == {"splits.train": 200}


def test_keep_defaults_sets_the_staged_designs_rule_and_is_refused_elsewhere(capsys, tmp_path):
    """``--keep-defaults`` reaches the design a tuning runs; without ``--retune`` (the board
    evaluates its shipped tuning) or with Optuna's design it is one line, exit 2."""
    from argparse import Namespace

    from sim.studies.benchmark import Benchmark

    args = Namespace(
        retune=True, tune_only=False, tuned_from=None, design=None, design_offset=0.5,
        keep_defaults="every-draw", trials=10, prune=False, race=0, sampler="tpe",
        tune_scenario=None, tuning_seed=None, storage=None,
    )  # fmt: skip
    _, design = Benchmark().tuning_source(args, PRESETS["noise"])
    assert design == PRESETS["noise"].design.shifted(0.5).keeping("every-draw")
    for extra in (["--design", "optuna", "--retune"], []):
        argv = ["noise", "--keep-defaults", "every-draw", *extra, "--out", str(tmp_path / "x")]
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "--keep-defaults" in err and err.count("\n") == 1
    assert not (tmp_path / "x").exists()


def test_every_shipped_staged_tuning_is_what_its_rule_reselects_from_its_own_runs():
    """``reselect`` chooses every method's entry anew from the runs an artefact recorded: under
    the rule it was made by (``mean`` where its design names none) it remakes each staged
    artefact that ships entry for entry, so the rule is live and the runs are the choice's; the
    two rules split the methods ``docs/leaderboards/keep-every-draw/`` evaluated, at no run."""
    from sim.experiment.staged import reselect

    moved = set()
    for preset in PRESETS:
        artefact = json.loads(artefacts.shipped(preset).read_text())
        if artefact["design"]["kind"] != "staged":
            continue
        mean = reselect(artefact, Design(keep_defaults="mean"))
        every = reselect(artefact, Design(keep_defaults="every-draw"))
        own = {"mean": mean, "every-draw": every}[artefact["design"].get("keep_defaults", "mean")]
        assert own == artefact["methods"], preset
        for method, entry in every.items():
            if entry.get("kept") != mean[method].get("kept"):
                assert entry["kept"] == "stages"  # it only ever keeps the defaults less often
                moved.add(f"{preset}:{method}")
    assert moved == MOVED_BY_EVERY_DRAW


MOVED_BY_EVERY_DRAW = {
    "radius:c2inet-offline",
    "density:c2inet-online",
    "density:coresets",
    "noise:coresets",
    "noise:finetune",
    "noise:lwf",
    "noise:si",
    "traffic:derpp",
    "traffic:finetune",
    "eth-ucy:counterfactual",
    "eth-ucy:derpp",
}


def test_a_reselected_artefact_names_its_rule_and_source_and_only_a_staged_one_is(tmp_path):
    """``artefacts.reselected`` (``scripts/reselect_tuning.py``) writes an artefact a board can
    evaluate: the rule in its design, the file it came from by SHA-256, noise's fine-tuning at the
    walk's learning rate; an Optuna artefact has no draws to compare and is one line."""
    from pathlib import Path

    from c2inet.files import file_digest

    made = artefacts.reselected(Path("noise"), "every-draw", tmp_path / "noise.json")
    assert made["design"]["keep_defaults"] == "every-draw"
    assert made["provenance"]["sha256"] == file_digest(artefacts.shipped("noise"))
    assert made["methods"]["finetune"]["settings"] == {"train": {"lr": 0.0007028831112648117}}
    assert artefacts.read_tuning(tmp_path / "noise.json")[2] == made["methods"]
    back = artefacts.reselected(tmp_path / "noise.json", "mean", tmp_path / "back.json")
    assert "keep_defaults" not in back["design"]  # the mean rule, as the shipped one says it
    made_by_mean = Path(__file__).resolve().parents[2] / "docs/leaderboards/noise-staged-all"
    assert back["methods"] == json.loads((made_by_mean / "noise.json").read_text())["methods"]
    optuna = Path(__file__).resolve().parents[2] / "docs/leaderboards/traffic-shipped/traffic.json"
    with pytest.raises(InputError, match="not a staged tuning's artefact"):
        artefacts.reselected(optuna, "every-draw", tmp_path / "no.json")
    assert not (tmp_path / "no.json").exists()
    planted = json.loads(artefacts.shipped("noise").read_text())  # its defaults' runs lost
    trials = planted["methods"]["finetune"]["trials"]
    trials[:] = [r for r in trials if r["params"] != {"train.lr": 0.003}]
    (tmp_path / "planted.json").write_text(json.dumps(planted))
    with pytest.raises(InputError, match="finetune: no recorded run of"):
        artefacts.reselected(tmp_path / "planted.json", "every-draw", tmp_path / "no.json")
