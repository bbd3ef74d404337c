"""What a change of settings does on the board: two boards on the same seeds whose settings
differ for some methods (one tuning chosen two ways, e.g. by ``scripts/reselect_tuning.py``),
each of those methods compared with itself, paired by seed: its final metric under each board,
the difference (second minus first) with its 95 % interval, the t-test's and the sign-flip p,
Holm-adjusted over those methods. The methods whose settings agree must agree to the digit
(training on CPU is deterministic): that is checked, not assumed.

``python scripts/settings_effect.py FIRST SECOND [FIRST SECOND ...]`` prints it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError
from c2inet.significance import holm, paired, sign_flip
from sim.studies.benchmark.stability import finals


def settings_effect(first: Path, second: Path) -> dict[str, Any]:
    """Each method whose settings differ between two boards, compared with itself by seed."""
    boards = [json.loads((b / "leaderboard.json").read_text()) for b in (first, second)]
    metric, other = (b.get("metric", "ade_k1") for b in boards)  # boards before it: K = 1
    if other != metric:
        raise InputError(f"{first} ranks {metric}, {second} {other}: not comparable")
    settings = [{e["method"]: e["settings"] for e in b["entries"]} for b in boards]
    values = [finals(b, metric) for b in (first, second)]
    rows, same = [], []
    for method in sorted(set(settings[0]) & set(settings[1])):
        seeds = sorted(set(values[0][method]) & set(values[1][method]))
        a, b = ([v[method][s] for s in seeds] for v in values)
        if settings[0][method] == settings[1][method]:
            same.append(method)
            if not np.allclose(a, b, rtol=0, atol=1e-9, equal_nan=True):
                raise InputError(f"{method}: the same settings gave other values: not one seed set")
            continue
        test = paired(b, a)
        rows.append(
            {
                "method": method,
                "settings": [settings[0][method], settings[1][method]],
                "means": [float(np.mean(a)), float(np.mean(b))],
                "seeds": len(seeds),
                "difference": test.difference,
                "interval": test.interval,
                "p": test.p_value,
                "p_sign_flip": sign_flip(np.subtract(b, a)),
            }
        )
    for row, adjusted in zip(rows, holm([r["p"] for r in rows]), strict=True):
        row["p_holm"] = adjusted
    return {"boards": [str(first), str(second)], "metric": metric, "rows": rows, "same": same}


def settings_effect_markdown(result: dict[str, Any]) -> str:
    """One table row a method whose settings differ, then the methods that matched."""
    first, second = (Path(b) for b in result["boards"])
    first, second = (  # two boards of one name (a preset's) by their folders too
        (f"{first.parent.name}/{first.name}", f"{second.parent.name}/{second.name}")
        if first.name == second.name
        else (first.name, second.name)
    )
    lines = [
        f"| method | `{first}` | `{second}` | 2nd minus 1st [95 % CI] | t p (Holm) | sign-flip p |",
        "|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        low, high = r["interval"] or (float("nan"),) * 2
        held = "-" if r["p_holm"] is None else f"{r['p']:.3f} ({r['p_holm']:.3f})"
        flip = "-" if r["p_sign_flip"] is None else f"{r['p_sign_flip']:.3f}"
        lines.append(
            f"| {r['method']} | {r['means'][0]:.3f} | {r['means'][1]:.3f} | "
            f"{r['difference']:+.3f} [{low:+.3f}, {high:+.3f}] | {held} | {flip} |"
        )
    lines += [
        "",
        f"Final {result['metric']} on {result['rows'][0]['seeds'] if result['rows'] else 0} "
        f"seeds; the methods whose settings agree gave the same values to 1e-9 on every seed: "
        + (", ".join(result["same"]) or "none")
        + ".",
    ]
    return "\n".join(lines) + "\n"
