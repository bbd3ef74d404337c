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


def test_radius_verdicts_are_those_of_its_four_tunings_of_every_method():
    """C2INet-online's gap over the four independent tunings of every method, and under the
    staged one that ships; the methods said to hold are exactly those whose over-tunings
    interval clears 0 after Holm."""
    from sim.studies.benchmark.stability import stability

    four = ("radius-protocol", "radius-attention", "radius-shipped", "radius-staged-all")
    result = stability([BOARDS / board for board in four])
    pattern = r"\(\+(0\.\d+) m over the four, \[\+(0\.\d+), \+(0\.\d+)\]; "
    pattern += r"\+(0\.\d+) under the staged one\)"
    over = result["methods"]["c2inet-online"]["over_tunings"]
    expected = [over["difference"], *over["interval"], difference(four[-1], "c2inet-online")]
    assert quoted(pattern) == [round(v, 3) for v in expected]
    holds = {m: e["over_tunings"]["holds"] for m, e in result["methods"].items()}
    assert {m for m, v in holds.items() if v == "ahead"} == {"coresets", "derpp"}
    behind = {"c2inet-online", "mog", "pecnet", "adaptive", "cv"}
    assert {m for m, v in holds.items() if v == "behind"} == behind


def test_density_leads_under_both_tunings():
    quotes = quoted(r"\(-(0\.\d+) and -(0\.\d+) m; -(0\.\d+) and -(0\.\d+)\)")
    boards = ("density", "density-tuning-seed-1")
    expected = [-round(difference(b, m), 3) for m in ("coresets", "derpp") for b in boards]
    assert quotes == expected


def test_noise_verdicts_are_those_both_of_its_tunings_star():
    """Coresets ahead of fine-tuning under both tunings of noise at the quoted gaps and over
    the two, the adaptive baseline and constant velocity behind under both, PECNet withdrawn
    (starred by the Optuna tuning alone), C2INet-online level under both."""
    from sim.studies.benchmark.stability import stability

    boards = ("noise-shipped", "noise-every-draw")
    pattern = r"ahead of tuned fine-tuning under both tunings\*\* \(-(0\.\d+) and -(0\.\d+) m; "
    pattern += r"over the two, -(0\.\d+) \[-(0\.\d+), -(0\.\d+)\], Holm p (0\.\d+)\)"
    result = stability([BOARDS / b for b in boards])["methods"]
    over = result["coresets"]["over_tunings"]
    expected = [-round(difference(b, "coresets"), 3) for b in boards]
    expected += [-round(v, 3) for v in (over["difference"], *over["interval"])]
    assert quoted(pattern) == [*expected, round(over["p_holm"], 3)]
    verdicts = {m: e["verdicts"] for m, e in result.items()}
    both = {m: v[0] for m, v in verdicts.items() if v[0] == v[1] and v[0] != "level"}
    assert both == {"coresets": "ahead", "adaptive": "behind", "cv": "behind"}
    assert {m for m, v in verdicts.items() if v[0] != v[1]} == {"pecnet"}
    assert verdicts["c2inet-online"] == ["level", "level"]


def test_traffic_verdicts_are_those_both_of_its_tunings_star():
    """The adaptive baseline and invariant behind fine-tuning under both tunings of traffic at
    the quoted gaps, nothing ahead under either, PECNet and GCRL behind on the staged board
    alone, C2INet-online level under both at the quoted gaps."""
    from sim.studies.benchmark.stability import stability

    boards = ("traffic-shipped", "traffic-every-draw")
    quotes = quoted(
        r"behind it under both\*\* \(\+(0\.\d+) and \+(0\.\d+) m; \+(0\.\d+) and \+(0\.\d+)\)"
    )
    assert quotes == [round(difference(b, m), 3) for m in ("adaptive", "invariant") for b in boards]
    online = quoted(r"by tuning\*\* \(\+(0\.\d+) and -(0\.\d+) m\)")
    assert online == [abs(round(difference(b, "c2inet-online"), 3)) for b in boards]
    verdicts = {
        m: e["verdicts"] for m, e in stability([BOARDS / b for b in boards])["methods"].items()
    }
    both = {m: v[0] for m, v in verdicts.items() if v[0] == v[1] and v[0] != "level"}
    assert both == {"adaptive": "behind", "invariant": "behind"}
    assert {m for m, v in verdicts.items() if v == ["level", "behind"]} == {"pecnet", "gcrl"}
    assert verdicts["c2inet-online"] == ["level", "level"]
    assert not any("ahead" in v for v in verdicts.values())


def test_the_keep_rule_figures_are_the_committed_check_boards():
    """The walk's choice against the kept defaults, method by method on each preset's seeds:
    how many it beats, by how much on average, and fine-tuning's gain on traffic and noise."""
    from sim.studies.benchmark.settings_effect import settings_effect

    published = {
        "noise": "noise-staged-all",
        "traffic": "traffic-staged-all",
        "eth-ucy": "eth-ucy",
        "density": "density-staged-all",
        "radius": "radius-staged-all",
    }
    rows = {
        (preset, r["method"]): r["difference"]
        for preset, board in published.items()
        for r in settings_effect(BOARDS / board, BOARDS / "keep-every-draw" / preset)["rows"]
    }
    pattern = r"better for (\d+) of the (\d+) methods that rule decided \((\d\.\d) cm on "
    pattern += r"average; fine-tuning, every board's reference, by (\d\.\d) cm on traffic and "
    pattern += r"(\d\.\d) on noise\)"
    gains = [-100 * rows["traffic", "finetune"], -100 * rows["noise", "finetune"]]
    expected = [sum(d < 0 for d in rows.values()), len(rows), -100 * np.mean(list(rows.values()))]
    assert quoted(pattern) == [*expected[:2], *(round(v, 1) for v in [expected[2], *gains])]


def test_the_sim_to_real_ranking_is_the_committed_boards_tau():
    (tau,) = quoted(r"Kendall's tau \+(0\.\d\d) \[")
    spec = importlib.util.spec_from_file_location("transfer", ROOT / "scripts/ranking_transfer.py")
    transfer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(transfer)
    sim = transfer.read_board(BOARDS / "fitted-eth-ucy", "ade")  # best of 20, as eth-ucy ranks
    real = transfer.read_board(BOARDS / "eth-ucy-walk", "ade")  # the settings fitted ran with
    methods = sorted((set(sim) & set(real)) - {"joint", "joint-scratch"})
    a = transfer.seed_table(BOARDS / "fitted-eth-ucy", methods, "ade")
    b = transfer.seed_table(BOARDS / "eth-ucy-walk", methods, "ade")
    assert len(methods) == 17 and tau == round(transfer.transfer(a, b, resamples=1)["tau"], 2)
