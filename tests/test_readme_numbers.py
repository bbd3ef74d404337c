"""The numbers README's Results section quotes, recomputed from the committed results they
come from: a README edited to another number, or a result committed anew without the README,
fails here. Each check finds its sentence in the README (so a reworded sentence that drops a
number fails too) and compares every number at the precision printed."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
BOARDS = ROOT / "docs" / "leaderboards"


def quoted(pattern: str) -> list[float]:
    """The numbers the README's text captures with ``pattern`` (whitespace-insensitive)."""
    text = re.sub(r"\s+", " ", README)
    match = re.search(pattern, text)
    assert match, f"README no longer says: {pattern}"
    return [float(g) for g in match.groups()]


def difference(board: str, method: str) -> float:
    """A board's paired final K = 1 ADE difference of ``method`` from fine-tuning."""
    entries = json.loads((BOARDS / board / "leaderboard.json").read_text())["entries"]
    (entry,) = [e for e in entries if e["method"] == method]
    return entry["final_ade_k1"]["difference"]


def averages(folder: str) -> np.ndarray:
    """ADE and FDE averaged over the five ETH-UCY scenes (sgan's windows, per-scene minimum)."""
    table = json.loads((ROOT / "docs" / "reproduction" / folder / "reproduce.json").read_text())
    return np.array(table["measured"]["finetune"]["sgan"]["scene"]).mean(0)


def test_the_published_table_reproduction_is_the_committed_one():
    quotes = quoted(r"averages (\d\.\d+)/(\d\.\d+) m and (\d\.\d+)/(\d\.\d+) \(two seeds")
    measured = np.concatenate([averages("eth-ucy"), averages("eth-ucy-seed1")])
    assert quotes == pytest.approx(np.round(measured, 3).tolist(), abs=1e-9)


def test_c2inet_behind_fine_tuning_under_both_staged_radius_tunings():
    quotes = quoted(r"\+(0\.\d+) and \+(0\.\d+) under the staged ones")
    boards = ("radius-staged/A", "radius-staged/B")
    assert quotes == [round(difference(b, "c2inet-online"), 3) for b in boards]


def test_density_leads_under_both_tunings():
    quotes = quoted(r"\(-(0\.\d+) and -(0\.\d+) m; -(0\.\d+) and -(0\.\d+)\)")
    boards = ("density", "density-tuning-seed-1")
    expected = [-round(difference(b, m), 3) for m in ("coresets", "derpp") for b in boards]
    assert quotes == expected


def test_the_sim_to_real_ranking_is_the_committed_boards_tau():
    (tau,) = quoted(r"Kendall's tau \+(0\.\d\d) \[")
    spec = importlib.util.spec_from_file_location("transfer", ROOT / "scripts/ranking_transfer.py")
    transfer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(transfer)
    sim = transfer.read_board(BOARDS / "fitted-eth-ucy", "ade")  # best of 20, as eth-ucy ranks
    real = transfer.read_board(BOARDS / "eth-ucy", "ade")
    methods = sorted((set(sim) & set(real)) - {"joint", "joint-scratch"})
    a = transfer.seed_table(BOARDS / "fitted-eth-ucy", methods, "ade")
    b = transfer.seed_table(BOARDS / "eth-ucy", methods, "ade")
    assert len(methods) == 17 and tau == round(transfer.transfer(a, b, resamples=1)["tau"], 2)
