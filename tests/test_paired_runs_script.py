"""``scripts/paired_runs.py``: two runs of one curriculum paired by seed, every part and rule."""

import json

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

TASKS = ("a", "b", "c")


def plant(folder, method, errors, data="d1", rule_errors=None):
    """A finished run: after the last task, task t's error = errors[t] + 0.01 * seed."""
    folder.mkdir()
    (folder / "run_card.json").write_text(json.dumps({"domains": [{"name": "x", "hash": data}]}))
    rows = []
    for seed in range(4):
        for metric, values in (("ade_k1", errors), ("ade", errors), ("ade_k1_c_own", rule_errors)):
            for task, value in zip(TASKS, values or (), strict=False):
                rows.append({"method": method, "seed": seed, "after_task": "c", "on_task": task,
                             "metric": metric, "value": value + 0.01 * seed})  # fmt: skip
        rows.append({"method": method, "seed": seed, "after_task": "a", "on_task": "a",
                     "metric": "ade_k1", "value": 9.0})  # fmt: skip
    pq.write_table(pa.Table.from_pylist(rows), folder / "results.parquet")
    return folder


def test_the_pair_reads_every_part_after_the_last_task_and_refuses_other_data(script, tmp_path):
    paired = script("scripts/paired_runs.py")
    first = plant(tmp_path / "ft", "finetune", [0.5, 0.4, 0.3])
    second = plant(tmp_path / "c2", "c2inet-online", [0.45, 0.4, 0.3], rule_errors=[0.4, 0.4, 0.3])
    text = paired.report(first, second)
    row = "| c2inet-online | K = 1 | task 1 | 4 | 0.5150 | 0.4650 | -0.0500 [-0.0500, -0.0500] |"
    assert row in text  # the first task's error, each seed paired with its own
    assert "| c2inet-online, c from own | K = 1 | old tasks | 4 | 0.4650 | 0.4150 |" in text
    assert "| c2inet-online | best of K | all tasks | 4 | 0.4150 | 0.3983 |" in text
    other = plant(tmp_path / "other", "ewc", [0.5, 0.4, 0.3], data="d2")
    with pytest.raises(Exception, match="not the same data"):
        paired.report(first, other)
