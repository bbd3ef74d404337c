"""Is C2INet live, and what does it buy? The study of issue 9 as one command.

Runs ``sim.run`` for every (curriculum, method); on the first curriculum, every Table 4 switch
and one design variant (one C per scene instead of per agent); and the divergence switch on
crowd_radius, where forgetting is large. Each job runs in its own process with one torch thread
(``--jobs`` at once). Then it prints, per curriculum: average ADE
over seen tasks after the last task at K = 20 and K = 1 (mean and std over seeds), both
forgetting scores, and the confounder's diagnostics after the last task. A finished job (its
``metrics.json`` exists) is read back, not run again.

    python benchmarks/c2inet_study.py [--out runs/study] [--seeds 3] [--jobs 2] [--quick]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

CURRICULA = ("crowd_noise_0.1..0.6", "crowd_radius_0.1..0.6", "crowd_density_0.05..0.30:0.05")
METHODS = ("joint", "c2inet-online", "c2inet-noqueue", "ewc", "coresets", "finetune", "cv")
SWITCHES = {  # Table 4: each part of C2INet switched off in turn
    "no-weight-opt": ["c2inet-online.weight_opt=false"],
    "no-divergence": ["c2inet-online.divergence=false"],
    "no-pruning": ["c2inet-online.pruning=false"],
    "capacity-15": ["c2inet-online.capacity=15"],
    "no-kl": ["model.beta_c=0", "model.beta_z=0"],
    "c-per-scene": ["model.c_per=scene"],  # a design variant, not in Table 4
}
EXTRA = {  # crowd_radius forgets most: there the regularisers have something to prevent
    ("crowd_radius_0.1..0.6", "no-divergence"): ["c2inet-online.divergence=false"],
}
DIAGNOSTICS = ("probe_observed", "probe_context", "probe_c", "mi_xc", "kl_c", "kl_z", "c_effect")
RECOVERY = ("ari", "nmi", "knob_r2")


def jobs() -> list[tuple[str, str, str, list[str]]]:
    """(folder name, scenario, method, --set values), the longest first."""
    out = [(f"{c}/{m}", c, m, []) for m in METHODS for c in CURRICULA]
    out += [
        (f"{CURRICULA[0]}/ablation-{n}", CURRICULA[0], "c2inet-online", s)
        for n, s in SWITCHES.items()
    ]
    out += [(f"{c}/ablation-{n}", c, "c2inet-online", s) for (c, n), s in EXTRA.items()]
    return out


def run(job, root: Path, seeds: int, quick: bool) -> tuple[str, float]:
    name, scenario, method, settings = job
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
    root.mkdir(parents=True, exist_ok=True)
    with open(root / f"{name}.log", "a") as log:
        subprocess.run(command, stdout=log, stderr=subprocess.STDOUT, check=True)
    return name, time.perf_counter() - start


def cell(mean: float, std: float) -> str:
    return f"{mean:.3f}±{std:.3f}"


def table(root: Path, names: list[str]) -> str:
    head = ["run", "ADE K=20", "ADE K=1", "forget final K=20", "forget worst K=20"]
    head += ["forget final K=1", *DIAGNOSTICS, *RECOVERY, "ADE K=1 C~post"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in names:
        path = root / name / "metrics.json"
        if not path.exists():
            continue
        (m,) = json.loads(path.read_text())["methods"].values()
        row = [
            name.split("/")[-1],
            cell(m["avg_seen_ade"][-1], m["avg_seen_ade_std"][-1]),
            cell(m["avg_seen_ade_k1"][-1], m["avg_seen_ade_k1_std"][-1]),
            f"{m['forgetting_final_ade']:+.3f}",
            f"{m['forgetting_worst_ade']:+.3f}",
            f"{m['forgetting_final_ade_k1']:+.3f}",
        ]
        last = m["diagnostics"][-1] if m.get("diagnostics") else {}
        for key in (*DIAGNOSTICS, *RECOVERY):
            value = last.get(key)
            if isinstance(value, list):
                value = sum(value) / len(value)
            row.append("-" if value is None else f"{value:.3g}")
        post = m.get("ade_k1_c_posterior")
        row.append(f"{sum(post[-1]) / len(post[-1]):.3f}" if post else "-")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("runs/study"))
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--quick", action="store_true")
    args = p.parse_args()
    todo = jobs()
    with ThreadPoolExecutor(args.jobs) as pool:
        for name, seconds in pool.map(lambda j: run(j, args.out, args.seeds, args.quick), todo):
            print(f"{name}: {seconds:.0f} s", flush=True)
    for curriculum in CURRICULA:
        names = [n for n, c, _, _ in todo if c == curriculum]
        print(f"\n### {curriculum}\n\n{table(args.out, names)}")


if __name__ == "__main__":
    main()
