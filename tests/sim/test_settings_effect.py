"""Two boards on the same seeds, the methods whose settings differ compared with themselves."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.studies.benchmark.settings_effect import settings_effect, settings_effect_markdown
from sim.studies.benchmark.stability import finals

BOARDS = Path(__file__).resolve().parents[2] / "docs" / "leaderboards"


def test_a_method_is_compared_with_itself_where_its_settings_differ():
    """noise under its Optuna and its staged tuning: every method that trains differs and is
    paired with itself by seed; constant velocity, with nothing to tune, matches to the digit."""
    first, second = BOARDS / "noise-shipped", BOARDS / "noise-staged-all"
    result = settings_effect(first, second)
    rows = {r["method"]: r for r in result["rows"]}
    assert len(rows) == 16 and result["same"] == ["cv"]
    a, b = finals(first)["finetune"], finals(second)["finetune"]
    expected = np.mean([b[s] - a[s] for s in a])
    assert rows["finetune"]["difference"] == pytest.approx(expected, abs=1e-12)
    assert rows["finetune"]["settings"][1] == {"train": {"lr": 0.003}}
    assert all(r["p_holm"] >= r["p"] for r in rows.values())
    assert "| finetune | 0.783 | 0.795 | +0.012 [" in settings_effect_markdown(result)
    assert settings_effect(second, second)["rows"] == []


def test_the_same_settings_giving_other_values_is_refused(tmp_path):
    """A pair that is not one seed set (a method with the same settings and other values) is
    one line naming the method, not a table."""
    planted = tmp_path / "noise-shipped"
    shutil.copytree(BOARDS / "noise-shipped", planted)
    board = json.loads((planted / "leaderboard.json").read_text())
    for entry in board["entries"]:
        if entry["method"] == "finetune":
            entry["settings"] = {"train": {"lr": 0.003}}  # the staged board's, values unchanged
    (planted / "leaderboard.json").write_text(json.dumps(board))
    with pytest.raises(InputError, match="finetune: the same settings gave other values"):
        settings_effect(planted, BOARDS / "noise-staged-all")


@pytest.mark.parametrize(
    ("preset", "board"),
    [
        ("noise", "noise-staged-all"),
        ("traffic", "traffic-staged-all"),
        ("eth-ucy", "eth-ucy"),
        ("density", "density-staged-all"),
        ("radius", "radius-staged-all"),
    ],
)
def test_the_keep_rule_check_is_the_shipped_tuning_reselected_and_its_page_current(preset, board):
    """Each board of ``keep-every-draw/`` evaluated exactly what ``reselect`` makes of the
    shipped artefact under ``every-draw``: the methods whose settings that moves from the
    published board's own (``mean``) artefact, with fine-tuning; the same methods and no other
    differ between the two boards, and the folder's page holds ``settings_effect``'s table."""
    from sim.experiment.design import Design
    from sim.experiment.staged import reselect
    from sim.studies.benchmark import artefacts

    check = BOARDS / "keep-every-draw" / preset
    artefact = json.loads((check / f"{preset}.json").read_text())["methods"]
    shipped = json.loads(artefacts.shipped(preset).read_text())
    assert artefact == reselect(shipped, Design(keep_defaults="every-draw"))
    made_by_mean = json.loads((BOARDS / board / f"{preset}.json").read_text())["methods"]
    moved = {m for m, e in artefact.items() if e["settings"] != made_by_mean[m]["settings"]}
    ran = {e["method"]: e["settings"] for e in json.loads((check / "leaderboard.json").read_text())
           ["entries"]}  # fmt: skip
    assert moved and set(ran) == moved | {"finetune"}
    assert all(ran[m] == artefact[m]["settings"] for m in ran)
    result = settings_effect(BOARDS / board, check)
    assert {r["method"] for r in result["rows"]} == moved
    assert settings_effect_markdown(result) in (check.parent / "README.md").read_text()


def test_the_scripts_write_what_they_say_and_refuse_bad_input_in_one_line(tmp_path):
    """``reselect_tuning.py`` names each method whose choice moves and writes the artefact;
    given two boards that rank different metrics, ``settings_effect.py`` prints one error line
    and nothing else, exit 2."""
    import subprocess
    import sys

    root = BOARDS.parents[1]
    out = tmp_path / "noise.json"
    made = subprocess.run(
        [sys.executable, "scripts/reselect_tuning.py", "docs/leaderboards/noise-staged-all",
         "--keep-defaults", "every-draw", "--out", str(out)],
        cwd=root, capture_output=True, text=True,
    )  # fmt: skip
    assert made.returncode == 0, made.stderr
    moved = sorted(line.split(":")[0] for line in made.stdout.splitlines()[:-1])
    assert moved == ["coresets", "finetune", "lwf", "si"]
    assert (
        json.loads(out.read_text())["methods"]
        == json.loads((BOARDS / "noise-every-draw" / "noise.json").read_text())["methods"]
    )
    refused = subprocess.run(
        [sys.executable, "scripts/settings_effect.py", "docs/leaderboards/noise-shipped",
         "docs/leaderboards/eth-ucy"],
        cwd=root, capture_output=True, text=True,
    )  # fmt: skip
    assert refused.returncode == 2 and refused.stdout == ""
    assert refused.stderr.count("\n") == 1 and "not comparable" in refused.stderr
