"""scripts/c2inet_chain.py (issue 61's chain): task 1's error after task 2, each configuration
and rule paired with fine-tuning over the same seeds, on a planted sweep."""

import importlib.util
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

ROOT = Path(__file__).resolve().parents[1]
TASKS = ("crowd_radius_0.1", "crowd_radius_0.6")


def chain_module():
    spec = importlib.util.spec_from_file_location("chain", ROOT / "scripts" / "c2inet_chain.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def planted(folder: Path, method: str, settings: dict[str, dict[str, float]]) -> Path:
    """A sweep's results.parquet: per setting, per metric, task 1 after task 2 = the value plus
    the seed times 0.002 (and a decoy cell, task 2 after task 2, of 9)."""
    rows = []
    for setting, metrics in settings.items():
        for metric, value in metrics.items():
            for seed in range(4):
                for after, on, cell in (
                    (TASKS[1], TASKS[0], value + seed / 500),
                    (*TASKS[1:] * 2, 9),
                ):
                    rows.append({"scenario": "crowd_radius_0.1,0.6", "method": method,
                                 "seed": seed, "setting": setting, "after_task": after,
                                 "on_task": on, "metric": metric, "value": cell})  # fmt: skip
    folder.mkdir()
    first = {**rows[0], "after_task": TASKS[0], "on_task": TASKS[0]}  # task 1 trained first
    pq.write_table(pa.Table.from_pylist([first, *rows]), folder / "results.parquet")
    return folder


def test_the_chain_pairs_each_configuration_and_rule_with_fine_tuning(tmp_path):
    queue = "c2inet-online.anchor_inputs=windows,c2inet-online.oracle=False,model.c_detached=True"
    oracle = "c2inet-online.anchor_inputs=decoded,c2inet-online.oracle=True,model.c_detached=False"
    ours = planted(tmp_path / "sweep", "c2inet-online", {
        queue: {"ade_k1": 0.30, "ade_k1_c_own": 0.25, "ade": 0.2, "ade_c_own": 0.2},
        oracle: {"ade_k1": 0.40, "ade_k1_c_own": 0.20, "ade": 0.2, "ade_c_own": 0.2},
    })  # fmt: skip
    theirs = planted(tmp_path / "finetune", "finetune", {"": {"ade_k1": 0.28, "ade": 0.2}})
    text = chain_module().report(ours, theirs)
    assert "| fine-tuning | - | 0.283 | | |" in text  # the seeds' mean, not the decoy
    assert (
        "| queue, windows anchors, detached | posterior | 0.303 | +0.020 [+0.020, +0.020]" in text
    )
    assert "| oracle, decoded anchors, connected | own components | 0.203 | -0.080" in text
    assert text.count("4 paired seeds") == 2  # a table a metric
