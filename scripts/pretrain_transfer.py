"""What pre-training on a calibrated crowd buys on real pedestrians, at a tenth and at all of the
real training data (issue 44).

Per ETH-UCY scene, fine-tuning (20 epochs a task, best of 20, ``--seeds`` seeds) on three
curricula, each a ``python -m sim.run`` into ``RUNS/SCENE/ARM`` (resumed when it exists):

- ``tenth``: the scene's first tenth of training windows alone (family ``eth_ucy_tenth``);
- ``fitted+tenth``: the scene's calibrated crowd (``docs/calibration/SCENE``), then that tenth;
- ``fitted+all``: the calibrated crowd, then all of the scene's training windows;

and prints, beside them, what ``sim.study fidelity`` measured with the same training
(``docs/calibration/SCENE/transfer_fitted.json``): the fitted crowd alone, all the real windows
alone, constant velocity. Every number is the final model's ADE on the scene's ``_val`` file,
which neither the calibration nor any training read. Writes ``OUT/pretrain.md`` and
``OUT/pretrain.json``.

    python scripts/pretrain_transfer.py [--seeds 3] [--jobs 2] [--runs bench/pretrain]
        [--out docs/calibration/pretrain]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from c2inet.errors import InputError
from c2inet.files import writable_folder, write_text_atomic
from viz.cli import guarded

CALIBRATION = Path("docs/calibration")
SCENES = ("eth", "hotel", "univ", "zara1", "zara2")
ARMS = {  # name -> scenario, from the fitted crowd's scenario and the scene's name
    "tenth": lambda fitted, scene: f"eth_ucy_tenth_{scene}",
    "fitted+tenth": lambda fitted, scene: f"{fitted}+eth_ucy_tenth_{scene}",
    "fitted+all": lambda fitted, scene: f"{fitted}+eth_ucy_{scene}",
}


def final_ade(run: Path) -> tuple[float, float]:
    """The final model's ADE on the curriculum's last task, mean and std over seeds."""
    finetune = json.loads((run / "metrics.json").read_text())["methods"]["finetune"]
    return finetune["ade"][-1][-1], finetune["ade_std"][-1][-1]


def run_arm(scenario: str, scene: str, out: Path, seeds: int, jobs: int) -> tuple[float, float]:
    """One arm's run (resumed where it was left), and its final ADE."""
    command = [sys.executable, "-m", "sim.run", "--scenario", scenario, "--methods", "finetune"]
    command += ["--scenarios-dir", str(CALIBRATION / scene), "--seeds", str(seeds)]
    command += ["--jobs", str(jobs), "--no-record", "--out", str(out)]
    if (out / "config.json").exists():
        command.append("--resume")
    if not (out / "metrics.json").exists() and subprocess.run(command).returncode:
        raise InputError(f"the run of {scenario} into {out} failed (its error is above)")
    return final_ade(out)


def scene_row(scene: str, out: Path, seeds: int, jobs: int) -> dict[str, float]:
    source = CALIBRATION / scene / "transfer_fitted.json"
    try:
        measured = json.loads(source.read_text())["transfer"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise InputError(f"{source}: cannot read its transfer ({type(error).__name__}); run "
                         "python -m sim.study fidelity for that scene first") from None  # fmt: skip
    fitted = measured["tasks"][0]
    row = {
        "fitted alone": measured["ade"][0][1],
        "all real alone": measured["ade"][1][1],
        "constant velocity": measured["cv_ade"][1],
    }
    for arm, scenario in ARMS.items():
        row[arm], row[f"{arm} std"] = run_arm(
            scenario(fitted, scene), scene, out / scene / arm, seeds, jobs
        )
    return row


def markdown(rows: dict[str, dict[str, float]], seeds: int) -> str:
    head = (
        "| scene | constant velocity | fitted crowd alone | a tenth of real | fitted, then a "
        "tenth | all real | fitted, then all |\n|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for scene, r in rows.items():
        lines.append(
            f"| {scene} | {r['constant velocity']:.3f} | {r['fitted alone']:.3f} | "
            f"{r['tenth']:.3f} ± {r['tenth std']:.3f} | "
            f"{r['fitted+tenth']:.3f} ± {r['fitted+tenth std']:.3f} | {r['all real alone']:.3f} | "
            f"{r['fitted+all']:.3f} ± {r['fitted+all std']:.3f} |"
        )
    mean = {k: sum(r[k] for r in rows.values()) / len(rows) for k in next(iter(rows.values()))}
    lines.append(
        f"| mean | {mean['constant velocity']:.3f} | {mean['fitted alone']:.3f} | "
        f"{mean['tenth']:.3f} | {mean['fitted+tenth']:.3f} | {mean['all real alone']:.3f} | "
        f"{mean['fitted+all']:.3f} |"
    )
    return (
        f"Fine-tuning, best-of-20 ADE (m) on each scene's `_val` file, mean ± std over {seeds} "
        "seeds (the fitted-alone and all-real columns: `transfer_fitted.json`, 3 seeds).\n\n"
        + head
        + "\n".join(lines)
        + "\n"
    )


@guarded
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--scenes", default=",".join(SCENES))
    p.add_argument("--runs", type=Path, default=Path("bench/pretrain"), help="the runs' folders")
    p.add_argument("--out", type=Path, default=CALIBRATION / "pretrain", help="the table's")
    args = p.parse_args(argv)
    for name, value in (("--seeds", args.seeds), ("--jobs", args.jobs)):
        if not 1 <= value <= 64:
            raise InputError(f"{name} {value}: expected 1 to 64")
    scenes = args.scenes.split(",")
    unknown = sorted(set(scenes) - set(SCENES))
    if unknown:
        raise InputError(f"--scenes: {unknown[0]!r} is no ETH-UCY scene ({', '.join(SCENES)})")
    writable_folder(args.out, "--out")  # before hours of training, not after
    writable_folder(args.runs, "--runs")
    rows = {s: scene_row(s, args.runs, args.seeds, args.jobs) for s in scenes}
    write_text_atomic(args.out / "pretrain.json", json.dumps(rows, indent=1) + "\n")
    text = markdown(rows, args.seeds)
    write_text_atomic(args.out / "pretrain.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
