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
