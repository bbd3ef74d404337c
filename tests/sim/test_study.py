"""The paper's studies as commands: each writes its table, JSON and figure, and its variants
really differ (a switch that changed nothing would show identical rows)."""

import json

from sim.experiment import Execution, ExperimentConfig
from sim.study import STUDIES, main, run_study


def test_table4_writes_its_table_json_and_figure(tmp_path):
    base = ExperimentConfig("crowd_radius_0.1,0.2", quick=True, record=False)
    summary = run_study("table4", base, tmp_path, Execution(workers=1), ("crowd_radius_0.1,0.2",))
    rows = summary["rows"]
    assert [r["variant"] for r in rows] == list(STUDIES["table4"].variants)
    finals = [r["avg_seen_ade"][-1] for r in rows]
    assert len(set(finals)) > 1, "every switch changed nothing"
    assert json.loads((tmp_path / "study.json").read_text())["rows"][0]["variant"] == "full"
    table = (tmp_path / "study.md").read_text()
    assert table.count("| no ") == 3 and "The paper:" in table
    assert (tmp_path / "study.png").read_bytes()[:4] == b"\x89PNG"


def test_orders_are_curricula_of_their_own():
    fig10 = STUDIES["fig10"]
    assert len(fig10.scenarios) == 6 and fig10.by == "order"
    assert "eth_ucy_hotel,univ,eth,zara1,zara2" in fig10.scenarios


def test_an_unknown_study_is_one_error_line(capsys):
    assert main(["tabel4"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "invalid choice: 'tabel4'" in err
