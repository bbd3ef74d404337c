"""Write the ORCA reference set with RVO2 itself (through pyrvo), and the RVO2 test fixture.

The reference stands in for the paper's synthetic data (causalmotion's ``v4``, ORCA circle
crossing) in the geometry ``crowd_radius`` simulates: 2 agents starting 4 to 5 m from the centre,
126 to 180 degrees apart, walking to the opposite side at 1 m/s from the first frame. RVO2 runs
with the TrajNet++ ORCA settings (``trajnetdataset/orca_helper.py``: 100 steps a second, neighbour
distance 10 m, 10 neighbours, unit preferred speed slowing within 1 m of the goal, maximum speed
1 m/s) and the ``v4`` files' time horizon of 2 s and radius r; positions are kept every 0.4 s.

It writes ``sim/scenarios/data/orca/radius_R_{train,val,test}.txt`` (ETH-UCY text format, one
block of frames per scene), read by the ``orca_radius`` family, and
``tests/sim/data/rvo2_velocities.npz``: random crowds and the velocities RVO2 chose for them,
which ``tests/sim/test_orca.py`` holds this project's ORCA to. pyrvo installs (``--no-deps``)
into ``.cache/bench-deps``; it is never part of the core install.

    python benchmarks/orca_reference.py [--radii 0.1,...,0.6] [--scenes 300,50,100]
"""

from __future__ import annotations

import argparse
import importlib
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

from c2inet.files import write_atomic, write_text_atomic
from sim.generators.crowd import CrowdKnobs, _place

ROOT = Path(__file__).resolve().parent.parent
DEPS = ROOT / ".cache" / "bench-deps"
OUT = ROOT / "sim" / "scenarios" / "data" / "orca"
FIXTURE = ROOT / "tests" / "sim" / "data" / "rvo2_velocities.npz"
STEP, RECORD, FRAMES = 0.01, 0.4, 20  # s per RVO2 step, s per kept frame, frames per scene
NEIGHBOUR_DIST, MAX_NEIGHBOURS, HORIZON, MAX_SPEED, SLOW_WITHIN = 10.0, 10, 2.0, 1.0, 1.0
SEED = 20111  # van den Berg et al. 2011


def pyrvo():
    """The pyrvo module, installed into ``.cache/bench-deps`` on first use."""
    sys.path.insert(0, str(DEPS))
    try:
        return importlib.import_module("pyrvo")
    except ImportError:
        command = [sys.executable, "-m", "pip", "install", "-q", "--no-deps"]
        subprocess.run([*command, "--target", str(DEPS), "pyrvo"], check=True)
        importlib.invalidate_caches()
        return importlib.import_module("pyrvo")


def preferred(position, goal) -> tuple[float, float]:
    """TrajNet++'s preferred velocity: unit speed towards the goal, slowing within 1 m of it."""
    dx, dy = goal[0] - position[0], goal[1] - position[1]
    distance = math.hypot(dx, dy)
    scale = 1.0 / distance if distance > SLOW_WITHIN else 1.0
    return dx * scale, dy * scale


def orca_scene(rvo, radius: float, starts: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """One scene simulated by RVO2, positions (frames, agents, 2)."""
    sim = rvo.RVOSimulator(
        STEP, NEIGHBOUR_DIST, MAX_NEIGHBOURS, HORIZON, HORIZON, radius, MAX_SPEED
    )
    for start, goal in zip(starts, goals, strict=True):
        agent = sim.add_agent((float(start[0]), float(start[1])))
        sim.set_agent_velocity(agent, preferred(start, goal))  # moving from the first frame
    per_frame = round(RECORD / STEP)
    frames = [starts.copy()]
    for step in range((FRAMES - 1) * per_frame):
        for agent, goal in enumerate(goals):
            p = sim.get_agent_position(agent)
            sim.set_agent_pref_velocity(agent, preferred((p.x, p.y), goal))
        sim.do_step()
        if (step + 1) % per_frame == 0:
            points = [sim.get_agent_position(agent) for agent in range(len(goals))]
            frames.append(np.array([[p.x, p.y] for p in points]))
    return np.stack(frames)


def write_split(path: Path, scenes: list[np.ndarray]) -> None:
    """ETH-UCY text: ``frame agent x y``, each scene its own block of frames and agent ids."""
    lines = []
    for k, scene in enumerate(scenes):
        for t in range(scene.shape[0]):
            for a in range(scene.shape[1]):
                x, y = scene[t, a]
                lines.append(f"{k * (FRAMES + 5) + t}\t{k * scene.shape[1] + a}\t{x:.4f}\t{y:.4f}")
    write_text_atomic(path, "\n".join(lines) + "\n")


def write_fixture(rvo, cases: int = 60) -> None:
    """Random crowds, some overlapping, and the velocities one RVO2 step gives them."""
    rng = np.random.default_rng(SEED)
    arrays: dict[str, list[np.ndarray]] = {"state": [], "preferred": [], "velocity": []}
    settings = []
    for _ in range(cases):
        n = int(rng.integers(2, 25))
        radius, horizon = rng.uniform(0.1, 0.6), rng.uniform(0.5, 3.0)
        position = rng.uniform(-1, 1, (n, 2)) * (1.5 + n / 5)
        state = np.concatenate([position, rng.normal(0, 1, (n, 2))], axis=1)
        wish = rng.normal(0, 1, (n, 2))
        sim = rvo.RVOSimulator(0.1, NEIGHBOUR_DIST, MAX_NEIGHBOURS, horizon, horizon, radius, 1.5)
        for row, w in zip(state, wish, strict=True):
            agent = sim.add_agent((float(row[0]), float(row[1])))
            sim.set_agent_velocity(agent, (float(row[2]), float(row[3])))
            sim.set_agent_pref_velocity(agent, (float(w[0]), float(w[1])))
        sim.do_step()
        chosen = [sim.get_agent_velocity(agent) for agent in range(n)]
        arrays["state"].append(state)
        arrays["preferred"].append(wish)
        arrays["velocity"].append(np.array([[v.x, v.y] for v in chosen]))
        settings.append((n, radius, horizon))
    flat = {key: np.concatenate(value) for key, value in arrays.items()}
    flat["cases"] = np.array(settings)  # agents, radius, horizon; step 0.1 s, max speed 1.5
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)

    def save(tmp: Path) -> None:
        with tmp.open("wb") as f:  # a file object: given a path, numpy would append ".npz"
            np.savez_compressed(f, **flat)

    write_atomic(FIXTURE, save)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--radii", default="0.1,0.2,0.3,0.4,0.5,0.6")
    p.add_argument("--scenes", default="300,50,100", help="train,val,test scenes per radius")
    args = p.parse_args()
    rvo = pyrvo()
    write_fixture(rvo)
    print(f"wrote {FIXTURE.relative_to(ROOT)}")
    sizes = [int(s) for s in args.scenes.split(",")]
    for radius_id, text in enumerate(args.radii.split(",")):
        radius = float(text)
        knobs = CrowdKnobs(radius=radius)
        for split_id, (split, count) in enumerate(
            zip(("train", "val", "test"), sizes, strict=True)
        ):
            scenes = []
            for k in range(count):
                seed = np.random.SeedSequence(SEED, spawn_key=(radius_id, split_id, k))
                starts, goals = _place(knobs, np.random.default_rng(seed))
                scenes.append(orca_scene(rvo, radius, starts, goals))
            path = OUT / f"radius_{text}_{split}.txt"
            write_split(path, scenes)
            print(f"wrote {path.relative_to(ROOT)} ({count} scenes)")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
