"""Per-seed figures of the C2INet issue (22): test-time rules, liveness, plasticity.

Reads the jobs of finished ``sim.run`` or ``sim.sweep`` folders (``jobs/<method>/seed_<n>/
result.json``) and prints one row per (folder, method) with, mean ± std over seeds:
- final average ADE at K = 1 under each test-time rule for C (posterior, prior, responsible);
- the diagonal (ADE K = 1 right after training each task, averaged over tasks) and the same for
  the last task alone, where a prior draw's harm cannot be forgetting;
- final forgetting of K = 1 ADE;
- liveness after the last task: MI(X; C) in nats and how far a prediction moves (m) when C's
  posterior mean is replaced by a prior draw, with the number of seeds that are live
  (MI >= 0.5 and moves >= 0.1 m) and any seed beyond 3 std of the others;
- probe accuracy from C and the NMI of each agent's most responsible owner task.

    python benchmarks/c2inet_liveness.py RUN_FOLDER [RUN_FOLDER ...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

RULES = ("", "_c_posterior", "_c_prior", "_c_responsible")
LIVE_MI, LIVE_MOVE = 0.5, 0.1


def seed_rows(job: Path) -> list[dict[str, float]]:
    """One dict of figures per seed of a job folder (``jobs/<method>``)."""
    rows = []
    for result in sorted(job.glob("seed_*/result.json")):
        r = json.loads(result.read_text())
        m = {k: np.array(v, dtype=float) for k, v in r["matrices"].items()}
        row = {}
        for rule in RULES:
            key = f"ade_k1{rule}"
            if key in m:
                row[f"final{rule}"] = float(np.mean(m[key][-1]))
                row[f"diag{rule}"] = float(np.mean(np.diag(m[key])))
                row[f"last{rule}"] = float(m[key][-1, -1])
        k1 = m["ade_k1"]
        row["forgetting"] = float(
            np.mean([k1[-1, j] - k1[j:-1, j].min() for j in range(len(k1) - 1)])
        )
        row["final_k20"] = float(np.mean(m["ade"][-1]))
        last = r["diagnostics"][-1] if r["diagnostics"] else {}
        for key in ("mi_xc", "c_effect", "probe_c", "nmi", "probe_observed"):
            if last.get(key) is not None:
                row[key] = float(last[key])
        rows.append(row)
    return rows


def cell(values: list[float]) -> str:
    return f"{np.mean(values):.3f}±{np.std(values):.3f}" if values else "-"


def outliers(values: list[float]) -> int:
    """Seeds beyond 3 std of the other seeds."""
    count = 0
    for i, v in enumerate(values):
        rest = np.delete(np.array(values), i)
        if len(rest) > 1 and abs(v - rest.mean()) > 3 * max(rest.std(), 1e-9):
            count += 1
    return count


def table(folders: list[Path]) -> str:
    head = ["run", "method", "seeds", "final K=1 (default)", "final K=1 C~post", "C~prior"]
    head += ["C~resp", "diag K=1 C~post", "C~prior", "last-task K=1 C~post", "C~prior"]
    head += ["forgetting K=1", "final K=20", "MI(X;C)", "moves (m)", "live", "outliers"]
    head += ["probe C", "NMI"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for folder in folders:
        for job in sorted(folder.glob("**/jobs/*")):
            rows = seed_rows(job)
            if not rows:
                continue

            def col(key: str, data=rows) -> list[float]:
                return [r[key] for r in data if key in r]

            post = "" if "final_c_posterior" not in rows[0] else "_c_posterior"
            live = [
                r.get("mi_xc", 0) >= LIVE_MI and r.get("c_effect", 0) >= LIVE_MOVE for r in rows
            ]
            finals = col("final")
            cells = [
                job.parent.parent.relative_to(folder.parent).as_posix(),
                job.name,
                str(len(rows)),
                cell(finals),
                cell(col(f"final{post}")),
                cell(col("final_c_prior")),
                cell(col("final_c_responsible")),
                cell(col(f"diag{post}")),
                cell(col("diag_c_prior")),
                cell(col(f"last{post}")),
                cell(col("last_c_prior")),
                cell(col("forgetting")),
                cell(col("final_k20")),
                cell(col("mi_xc")),
                cell(col("c_effect")),
                f"{sum(live)}/{len(live)}" if col("mi_xc") else "-",
                str(outliers(finals)),
                cell(col("probe_c")),
                cell(col("nmi")),
            ]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path)
    print(table(parser.parse_args().folders))


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
