"""Is C2INet live, and what does it buy? The study of issue 22 as one command.

Runs ``sim.run`` for every (curriculum, method) with ``--seeds`` seeds, then, on the first
curriculum, C2INet-online with one switch changed per row: each of Table 4's parts, each of
BooVAE's additions, and each design choice of the model (the decoder's input, Q(Z|X,C), the
past reconstruction's input, free bits, C per scene) with ``--ablation-seeds`` seeds. Each job
runs in its own process with one torch thread (``--jobs`` at once); a finished job (its
``metrics.json`` exists) is read back, not run again. Then it prints, per curriculum, the
per-seed table of ``c2inet_liveness.py``: each test-time rule, the diagonal, forgetting and
liveness, mean ± std over seeds.

    python benchmarks/c2inet_study.py [--out runs/study] [--seeds 5] [--jobs 2] [--quick]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from c2inet_liveness import table

CURRICULA = ("crowd_radius_0.1..0.6", "crowd_density_0.05..0.30:0.05")
METHODS = ("c2inet-online", "c2inet-noqueue", "finetune", "ewc", "coresets", "derpp", "joint", "cv")
SWITCHES = {  # one change per row
    # the model's design choices (issue 22)
    "bottleneck": ["model.decoder_input=latents"],
    "past-reconstruction": ["model.beta_x=1"],
    "no-mi-floor": ["model.mi_floor_c=0"],
    "c-not-detached": ["model.c_detached=false"],
    "no-context-dropout": ["model.context_dropout=0"],
    "no-free-bits": ["model.free_bits_c=0"],
    "z-not-given-c": ["model.z_given_c=false"],
    "c-per-scene": ["model.c_per=scene"],
    # BooVAE's additions
    "task-kl": ["c2inet-online.task_kl=true"],
    "no-distill": ["c2inet-online.distill_decoder=false", "c2inet-online.distill_encoder=false"],
    "no-mass-bounds": ["c2inet-online.mass_bounds=false"],
    # Table 4
    "no-divergence": ["c2inet-online.divergence=false"],
    "no-weight-opt": ["c2inet-online.weight_opt=false"],
    "no-pruning": ["c2inet-online.pruning=false"],
    "capacity-15": ["c2inet-online.capacity=15"],
    "no-kl": ["model.beta_c=0", "model.beta_z=0"],
}


def jobs(seeds: int, ablation_seeds: int) -> list[tuple[str, str, str, list[str], int]]:
    """(folder name, scenario, method, --set values, seeds), the longest first."""
    out = [(f"{c}/{m}", c, m, [], seeds) for m in METHODS for c in CURRICULA]
    out += [
        (f"{CURRICULA[0]}/ablation-{n}", CURRICULA[0], "c2inet-online", s, ablation_seeds)
        for n, s in SWITCHES.items()
    ]
    return out


def run(job, root: Path, quick: bool) -> tuple[str, float]:
    name, scenario, method, settings, seeds = job
    out = root / name
    if (out / "metrics.json").exists():
        return name, 0.0
    command = [sys.executable, "-m", "sim.run", "--scenario", scenario, "--methods", method]
    command += ["--seeds", str(seeds), "--out", str(out), "--no-record", "--threads", "1"]
    command += ["--workers", "1"] + (["--quick"] if quick else [])
    for item in settings:
        command += ["--set", item]
    if (out / "config.json").exists():  # an interrupted run continues where it stopped
        command.append("--resume")
    start = time.perf_counter()
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(root / f"{name}.log", "a") as log:
        subprocess.run(command, stdout=log, stderr=subprocess.STDOUT, check=True)
    return name, time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("runs/study"))
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--ablation-seeds", type=int, default=3)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--quick", action="store_true")
    p.add_argument(
        "--only", nargs="*", help="run only these folder names (e.g. ablation-bottleneck)"
    )
    args = p.parse_args()
    todo = [
        j
        for j in jobs(args.seeds, args.ablation_seeds)
        if not args.only or j[0].split("/")[-1] in args.only
    ]
    with ThreadPoolExecutor(args.jobs) as pool:
        for name, seconds in pool.map(lambda j: run(j, args.out, args.quick), todo):
            print(f"{name}: {seconds:.0f} s", flush=True)
    for curriculum in CURRICULA:
        print(f"\n### {curriculum}\n\n{table([args.out / curriculum])}")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
