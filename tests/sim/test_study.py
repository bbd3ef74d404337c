"""The studies: one registry and one command. The paper's studies write their table, JSON and
figure, and their variants really differ (a switch that changed nothing would show identical
rows); every registered study takes the shared options and refuses a foreign folder."""

import json
import subprocess
import sys

import numpy as np
import pytest

from sim.studies.base import STUDIES, Study, discover, register
from sim.studies.paper import PRESETS
from sim.study import main, study_parser


def test_table4_writes_its_table_json_and_figure(tmp_path, capsys):
    argv = ["table4", "--quick", "--scenario", "crowd_radius_0.1,0.2", "--no-record"]
    assert main([*argv, "--workers", "1", "--out", str(tmp_path)]) == 0
    assert f"wrote {tmp_path}: open study.md" in capsys.readouterr().err
    rows = json.loads((tmp_path / "study.json").read_text())["rows"]
    assert [r["variant"] for r in rows] == list(PRESETS["table4"].variants)
    finals = [r["avg_seen_ade"][-1] for r in rows]
    assert len(set(finals)) > 1, "every switch changed nothing"
    table = (tmp_path / "study.md").read_text()
    assert table.count("| no ") == 6 and "The paper:" in table  # one switch a row
    assert "| composite: no weight optimisation, divergence or KL of Z" in table
    assert (tmp_path / "study.png").read_bytes()[:4] == b"\x89PNG"


def test_a_study_row_is_paired_with_the_first_rows_seeds():
    """Table 4's last column: each row's final ADE minus the first row's on the same seeds, with
    its interval and p; the first row and a one-seed row get a dash."""
    from sim.studies.paper import paired_text

    full = {"final_ade_per_seed": [0.20, 0.22, 0.21, 0.23]}
    worse = {"final_ade_per_seed": [0.25, 0.26, 0.27, 0.27]}
    text = paired_text(worse, full)
    assert text == "+0.0475 [+0.0323, +0.0627], p = 0.002"
    assert (
        paired_text(full, full) == "-" and paired_text({"final_ade_per_seed": [0.2]}, full) == "-"
    )


def test_orders_are_curricula_of_their_own():
    fig10 = PRESETS["fig10"]
    assert len(fig10.scenarios) == 6 and fig10.by == "order"
    assert "eth_ucy_hotel,univ,eth,zara1,zara2" in fig10.scenarios


def test_every_study_is_registered_once_with_the_shared_options():
    studies = discover()
    assert set(studies) >= {"active", "drift", "fidelity", "shift", "table4", "fig9", "fig10"}
    for name, study in studies.items():
        options = {a.dest for a in study_parser(study)._actions}
        shared = {"methods", "epochs", "seeds", "set", "cache", "overwrite", "out", "threads"}
        assert shared | {"resume", "jobs", "backend"} <= options, name
        assert ("logger" in options) == study.sweeps, name
        assert ("no_record" in options) == (study.sweeps and study.records), name
    with pytest.raises(ValueError, match="registered twice"):
        register(STUDIES["drift"])
    with pytest.raises(ValueError, match="empty"):
        register(Study())


def test_an_unknown_study_is_one_error_line(capsys):
    assert main(["tabel4"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'tabel4': unknown; did you mean 'table4'?" in err


@pytest.mark.parametrize("name", ["drift", "fidelity"])
def test_a_study_refuses_a_folder_holding_the_users_files(tmp_path, capsys, name):
    (tmp_path / "notes.txt").write_text("mine")
    argv = [name, "--scenario", "crowd_radius_0.1,0.2", "--reference", "orca_radius_0.1,0.2"]
    argv = argv if name == "fidelity" else argv[:3]
    assert main([*argv, "--quick", "--out", str(tmp_path), "--overwrite"]) == 2
    assert "holds no run of this project" in capsys.readouterr().err
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_the_listing_names_every_study(capsys):
    assert main([]) == 2
    out = capsys.readouterr().out
    assert all(name in out for name in discover())


def test_the_papers_studies_refuse_another_method(capsys):
    argv = ["fig9", "--quick", "--scenario", "crowd_radius_0.1,0.2", "--methods", "finetune"]
    assert main(argv) == 2
    assert "the paper's studies are of c2inet-online alone" in capsys.readouterr().err


def test_listing_the_studies_and_asking_their_options_loads_no_learner():
    """Discovery imports every study module: each must stay light at import (the learner, the
    engine and the figures load inside its functions), so ``python -m sim.study`` and any
    study's ``--help`` (``sim.bench --help`` too) answer without torch."""
    code = (
        "import sys\n"
        "from sim.study import listing, study_parser\n"
        "from sim.studies.base import discover\n"
        "listing()\n"
        "[study_parser(s) for s in discover().values()]\n"
        "heavy = {'torch', 'scipy.stats', 'matplotlib', 'pandas', 'pyarrow', 'rerun', 'optuna'}\n"
        "print(sorted(heavy & set(sys.modules)), len(discover()))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    loaded, count = done.stdout.split("] ")
    assert loaded == "[" and int(count) >= 9, done.stdout


def test_the_benchmark_is_a_study_under_both_commands(capsys):
    from sim import bench

    options = {a.dest for a in study_parser(discover()["bench"])._actions}
    assert {"preset", "trials", "race", "storage", "compare", "estimate"} <= options
    assert main(["bench", "radius", "--scenario", "crowd_radius_0.1,0.2"]) == 2
    assert capsys.readouterr().err == "error: give a preset or --scenario (one of them)\n"
    assert bench.main(["radios"]) == 2
    assert "preset 'radios': unknown; did you mean 'radius'?" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["fidelity", "drift", "shift", "active"])
def test_each_studys_console_script_takes_a_command_line(capsys, name):
    """``c2i-drift`` and friends: the study's own command (a bad scenario is one line, exit 2)."""
    import sim.study

    reference = ["--reference", "orca_radius_0.1,0.2"] if name == "fidelity" else []
    assert getattr(sim.study, name)(["--scenario", "crowd_nois_0.1,0.2", *reference]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "crowd_nois" in err


def test_table_4_says_its_k_and_what_its_seeds_can_detect():
    """The paper study's table prints best of K with K named, the point prediction (K = 1) with
    its own paired test, and the smallest effect its seed count detects."""
    from sim.studies.paper import study_markdown

    rng = np.random.default_rng(0)
    seeds = rng.normal(0.2, 0.01, 8)

    def row(variant: str, shift: float) -> dict:
        finals = list(seeds + shift + rng.normal(0, 0.005, 8))
        return {
            "scenario": "crowd_radius_0.1,0.2", "variant": variant, "labels": ["0.1", "0.2"],
            "seeds": 8, "avg_seen_ade": [0.1, 0.2], "avg_seen_ade_std": [0.0, 0.01],
            "avg_seen_fde": [0.2, 0.4], "forgetting_final_ade": 0.01,
            "final_ade_per_seed": finals, "avg_seen_ade_k1": [0.15, 0.25 + shift],
            "final_ade_k1_per_seed": [f + 0.05 for f in finals],
        }  # fmt: skip

    text = study_markdown(
        {"study": "Table 4", "paper": "p", "k": 20, "rows": [row("full", 0), row("off", 0.03)]}
    )
    assert "best of K = 20" in text and "| best of 20 vs first row |" in text
    assert "| final K = 1 | K = 1 vs first row |" in text and "| 0.280 |" in text
    assert "With 8 paired seeds this table detects a difference of about" in text
