"""What a board ranks and its tuning scores: the point prediction's ADE, or the best of K (the
eth-ucy preset's, the published protocol there); every part reads the one the board names."""

from types import SimpleNamespace

import numpy as np
import pytest

from c2inet.errors import InputError
from c2inet.report import summarise
from c2inet.trainer import Result
from sim.experiment import ExperimentConfig
from sim.experiment.trials import objective_so_far
from sim.experiment.tuning import TuneConfig
from sim.studies.benchmark import PRESETS
from sim.studies.benchmark import leaderboard as board_module
from sim.studies.benchmark.board_markdown import boards_table, leaderboard_markdown
from sim.studies.benchmark.config import BenchConfig

# final errors, (point prediction, best of K): EWC is ahead on the first, SI on the second
PLANTED = {"finetune": (0.50, 0.40), "ewc": (0.40, 0.45), "si": (0.60, 0.30)}


def matrices(point: float, best: float, seed: int) -> dict[str, np.ndarray]:
    wobble = 0.01 * np.random.default_rng(seed).standard_normal()
    return {
        "ade_k1": np.full((2, 2), point + wobble),
        "ade": np.full((2, 2), best + wobble),
        "ade_draw": np.full((2, 2), point + 0.1 + wobble),
        "fde": np.full((2, 2), 2 * best),
    }


def summaries() -> dict[str, dict]:
    return {
        name: summarise([matrices(*values, seed) for seed in range(4)], [[{}, {}]] * 4)
        | {"cpu_seconds": 1.0}
        for name, values in PLANTED.items()
    }


def board(metric: str, monkeypatch) -> dict:
    monkeypatch.setattr(board_module, "protocol", lambda bench, run: {"metric": bench.metric})
    bench = SimpleNamespace(
        ranked=tuple(PLANTED), metric=metric, compare=(), width=0.01, references=()
    )
    chosen = {m: {"settings": {}, "trials": []} for m in PLANTED}
    return board_module.leaderboard(bench, summaries(), chosen, None, {})


@pytest.mark.parametrize(
    ("metric", "order"), [("ade_k1", ["ewc", "finetune", "si"]), ("ade", ["si", "finetune", "ewc"])]
)
def test_a_board_ranks_and_tests_by_its_metric(metric, order, monkeypatch):
    made = board(metric, monkeypatch)
    assert [e["method"] for e in made["entries"]] == order
    first = made["entries"][0]
    assert first[f"final_{metric}"]["significant"]  # ahead of fine-tuning on its own metric
    assert "p_signflip" in first[f"final_{metric}"]  # the sign-flip test beside, on it too
    other = "ade" if metric == "ade_k1" else "ade_k1"
    assert "p_signflip" not in first[f"final_{other}"]
    assert first[f"final_{other}"]["difference"] > 0  # behind on the other


def test_the_markdown_names_what_a_board_ranks(monkeypatch):
    made = board("ade", monkeypatch)
    made |= {"alpha": 0.05, "references": [], "k": 20}
    lines = leaderboard_markdown.__globals__["_rankings"](made)
    assert lines[0] == "Best of K (ranked):"
    assert "The point prediction (K = 1) (ordered by its own final average):" in lines
    table = boards_table({"real": made})  # the tuned Table 2 reads each board's own metric
    assert "| si | 0.3" in table and table.startswith("| method | `real` (best of 20) |")


def test_a_trials_objective_is_the_boards_metric():
    result = Result(["a", "b"], matrices(0.5, 0.3, 0), summaries=[{}, {}])
    assert objective_so_far(result)[-1] == pytest.approx(result.matrices["ade_k1"][-1].mean())
    assert objective_so_far(result, "ade")[-1] == pytest.approx(result.matrices["ade"][-1].mean())


def test_the_eth_ucy_preset_ranks_best_of_k_with_its_recipe_and_validation_split():
    preset = PRESETS["eth-ucy"]
    base = ExperimentConfig(preset.scenario, methods=("finetune",))
    bench = BenchConfig(
        base, name="eth-ucy", data=preset.data, metric=preset.metric, recipe=preset.recipe
    )
    train = bench.base.train_config()
    assert (train.schedule, train.select, train.augment) == ("cosine", "val", "axes")
    assert bench.base.settings["model"]["noise_per"] == "scene"
    data = bench.base.settings["data"]
    assert (data["windows.val_share"], data["windows.val_stride"]) == (0.2, 5)
    assert bench.tuning().metric == "ade" and preset.metric == "ade"
    given = {"train": {"select": "last"}}  # the user's own --set wins over the recipe
    user = BenchConfig(
        ExperimentConfig(preset.scenario, methods=("finetune",), settings=given),
        recipe=preset.recipe,
    )
    assert user.base.train_config().select == "last"
    point = BenchConfig(base, name="eth-ucy", data=preset.data, recipe=preset.recipe)
    assert point.key() != bench.key()  # another objective: another tuning's trials
    assert PRESETS["radius"].metric == "ade_k1" and not PRESETS["radius"].recipe


def test_a_metric_the_board_cannot_rank_or_prune_by_is_one_line(tmp_path):
    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("finetune", "cv"))
    with pytest.raises(InputError, match="metric 'fde': expected one of ade_k1, ade"):
        BenchConfig(base, metric="fde")
    with pytest.raises(InputError, match="--prune stops trials on the point prediction"):
        BenchConfig(base, metric="ade", prune=True)
    with pytest.raises(InputError, match="--prune stops trials on the point prediction"):
        TuneConfig(base, prune=True, metric="ade")
    shipped = PRESETS["radius"]  # tuned on the point prediction: not for a best-of-K board
    with pytest.raises(InputError, match="scored on ade_k1, but this board ranks ade: tune anew"):
        BenchConfig(
            ExperimentConfig(shipped.scenario, methods=("finetune", "cv")),
            metric="ade",
            tuned_from=board_module.__file__.replace("leaderboard.py", "tunings/radius.json"),
        )


def test_a_boards_folder_lends_its_tuning_to_a_board_of_its_own_metric(tmp_path):
    """A board's folder carries its metric in ``leaderboard.json`` (its ``tuning.json`` does not):
    a best-of-K board borrows it, a point-prediction board refuses it in one line."""
    import json

    (tmp_path / "tuning").mkdir()
    chosen = {"finetune": {"settings": {"train": {"lr": 1e-3}}}, "cv": {"settings": {}}}
    (tmp_path / "tuning" / "tuning.json").write_text(json.dumps(chosen))
    (tmp_path / "leaderboard.json").write_text(json.dumps({"tune_scenario": "x", "metric": "ade"}))
    base = ExperimentConfig("crowd_noise_0.1,0.2", methods=("finetune", "cv"))
    lent = BenchConfig(base, metric="ade", tuned_from=tmp_path)
    assert lent.borrowed[0]["finetune"]["settings"] == {"train": {"lr": 1e-3}}
    with pytest.raises(InputError, match="scored on ade, but this board ranks ade_k1"):
        BenchConfig(base, tuned_from=tmp_path)


@pytest.mark.parametrize(("metric", "label"), [("ade_k1", "K = 1"), ("ade", "best of 20")])
def test_the_figure_draws_the_metric_the_board_ranks(metric, label, monkeypatch, tmp_path):
    """The eth-ucy board's figure drew the point prediction beside a best-of-K ranking (its rows
    in one order, its points and stars from the other metric)."""
    import viz.study_figures as figures

    made = board(metric, monkeypatch)
    made |= {"alpha": 0.05, "k": 20, "reference": "finetune", "scenario": "x"}
    made |= {"seeds": 8, "trials": 10}
    drawn = {}
    monkeypatch.setattr(figures, "save_figure", lambda fig, path: drawn.setdefault("fig", fig))
    figures.leaderboard_figure(made, tmp_path / "board.png")
    ade = drawn["fig"].axes[0]
    assert ade.get_xlabel() == f"final average ADE, {label} (m)"
    points = [line.get_xdata()[0] for line in ade.lines if line.get_marker() == "o"]
    assert points == pytest.approx([e[f"final_{metric}"]["mean"] for e in made["entries"]])
