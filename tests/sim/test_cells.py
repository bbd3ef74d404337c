"""A study's cells: run on the backend, kept as each ends, read back on resume, refused when
damaged or another run's."""

import json

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.experiment import Execution
from sim.experiment.cells import cell_identity, run_cells
from sim.study import main

CALLS: list[tuple] = []


def square(x: int, offset: int) -> dict:
    CALLS.append((x, offset))
    return {"value": x * x + offset}


def test_cells_are_kept_and_only_the_missing_ones_run_again(tmp_path):
    cells = {f"x_{x}": (x,) for x in range(3)}
    CALLS.clear()
    first = run_cells(square, cells, (10,), Execution(), tmp_path, "id")
    assert first == {"x_0": {"value": 10}, "x_1": {"value": 11}, "x_2": {"value": 14}}
    assert sorted(p.name for p in (tmp_path / "cells").iterdir()) == [
        f"x_{x}.json" for x in range(3)
    ]
    (tmp_path / "cells" / "x_1.json").unlink()
    CALLS.clear()
    again = run_cells(square, cells, (10,), Execution(), tmp_path, "id", resume=True)
    assert again == first and CALLS == [(1, 10)]
    CALLS.clear()
    run_cells(square, cells, (10,), Execution(), tmp_path, "id")  # no resume: all again
    assert len(CALLS) == 3


def test_a_kept_cell_of_other_options_or_damaged_is_refused(tmp_path):
    cells = {"x_2": (2,)}
    run_cells(square, cells, (0,), Execution(), tmp_path, "id")
    with pytest.raises(InputError, match="x_2.json is the result of other options"):
        run_cells(square, cells, (5,), Execution(), tmp_path, "other id", resume=True)
    (tmp_path / "cells" / "x_2.json").write_text('{"identity": "id"')
    with pytest.raises(InputError, match="x_2.json is damaged"):
        run_cells(square, cells, (0,), Execution(), tmp_path, "id", resume=True)


def test_a_cell_identity_follows_its_options_and_its_data():
    data = np.zeros(4)
    base = cell_identity("drift", {"seeds": 1}, arrays=[data])
    assert base == cell_identity("drift", {"seeds": 1}, arrays=[np.zeros(4)])
    assert base != cell_identity("drift", {"seeds": 2}, arrays=[data])
    assert base != cell_identity("drift", {"seeds": 1}, arrays=[np.ones(4)])


def test_a_study_in_parallel_resumes_to_the_same_report(tmp_path):
    out = tmp_path / "drift"
    argv = ["drift", "--scenario", "crowd_noise_0.1,0.3", "--methods", "finetune", "--seeds", "2"]
    argv += ["--quick", "--out", str(out), "--cache", str(tmp_path / "cache")]
    assert main([*argv, "--jobs", "2"]) == 0
    report = (out / "drift.json").read_text()
    kept = out / "cells" / "finetune-seed_0.json"
    before = kept.stat().st_mtime_ns
    (out / "cells" / "finetune-seed_1.json").unlink()
    assert main([*argv, "--resume"]) == 0
    assert (out / "drift.json").read_text() == report
    assert kept.stat().st_mtime_ns == before  # read back, not run again
    assert json.loads(kept.read_text())["result"]["ade"]
    assert main([*argv, "--resume", "--chunks", "2"]) == 2  # other options: refused
