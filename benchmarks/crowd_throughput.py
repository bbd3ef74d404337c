"""Crowd generator throughput against JuPedSim and RVO2 on the same circle-crossing starts.

Prints, per crowd size, simulated agent-seconds per wall-second and the number of overlapping
agent pairs over all recorded frames (every 0.4 s) for: this testbed's Pymunk generator with each
controller (time-to-collision, ORCA) on one scene and on a batch of scenes (as ``sim.generate``
runs it), JuPedSim's collision-free speed model, and ORCA in RVO2 itself through pyrvo, each the
best of ``--repeats`` runs on one core. Then whole domains, generated as a run makes them
(simulation, realised statistics, Parquet), against the simulation of the same scenes alone:
target at least 80 % of the simulator's rate. The controllers' one-off Numba compilation (or
cache load) is timed apart, before the tables. The comparison simulators install with
``--no-deps`` into ``.cache/bench-deps`` (about 85 MB, never part of the core install); pass
``--no-install`` to skip them when they are missing.

    python benchmarks/crowd_throughput.py [--sizes 6,20,100,500] [--seconds 20] [--repeats 3]
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from sim.domains import build_domain, domain_seed
from sim.generators import child_seed
from sim.generators.crowd import BATCH_SCENES, CrowdKnobs, _place, simulate
from sim.io import write_parquet
from sim.scenario import parse_scenario

DEPS = Path(__file__).resolve().parent.parent / ".cache" / "bench-deps"
RADIUS, SPEED, DT_RECORD = 0.2, 1.0, 0.4


DOMAINS = ("crowd_radius_0.3", "crowd_noise_0.3", "crowd_density_0.3")  # ORCA, TTC, TTC dense


def knobs_for(agents: int, seconds: float, controller: str = "ttc") -> CrowdKnobs:
    """Circle crossing whose start ring grows with the crowd so that the agents fit."""
    ring = max(4.5, 0.11 * agents)
    return CrowdKnobs(
        controller=controller,
        start="moving" if controller == "orca" else "rest",
        agents=agents,
        radius=RADIUS,
        speed=SPEED,
        frames=round(seconds / DT_RECORD) + 1,
        inner_radius=ring - 0.5,
        outer_radius=ring + 0.5,
    )


def overlaps(frames: np.ndarray) -> int:
    """Agent pairs closer than 98 % of 2r, summed over recorded frames (frames, agents, 2)."""
    contact = 2 * RADIUS * 0.98
    return sum(len(cKDTree(f).query_pairs(contact, output_type="ndarray")) for f in frames)


def run_pymunk(knobs: CrowdKnobs, scenes: int) -> tuple[float, int]:
    seeds = [np.random.SeedSequence(0, spawn_key=(k,)) for k in range(scenes)]
    start = time.perf_counter()
    out = simulate(knobs, seeds)
    wall = time.perf_counter() - start
    return wall, sum(overlaps(o) for o in out)


def whole_domain(name: str) -> tuple[float, float, int]:
    """(wall of the domain as a run makes it, wall of its simulation alone, agent-seconds)."""
    (spec,) = parse_scenario(name)
    knobs = CrowdKnobs(**spec.knobs)
    splits = spec.family.splits
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        domain = build_domain(spec, root_seed=0)
        write_parquet(domain, Path(folder) / "domain.parquet")
    whole = time.perf_counter() - start
    seed = domain_seed(0, spec)  # the domain's own scenes
    start = time.perf_counter()
    scenes = 0
    for split_id, split in enumerate(("train", "val", "test")):
        seeds = [child_seed(seed, split_id, k) for k in range(getattr(splits, split))]
        for first in range(0, len(seeds), BATCH_SCENES):
            simulate(knobs, seeds[first : first + BATCH_SCENES])
        scenes += len(seeds)
    alone = time.perf_counter() - start
    agent_seconds = scenes * knobs.num_agents * (knobs.frames - 1) * knobs.dt
    return whole, alone, agent_seconds


def run_orca(knobs: CrowdKnobs, starts: np.ndarray, goals: np.ndarray) -> tuple[float, int]:
    import pyrvo

    dt = 0.1
    sim = pyrvo.RVOSimulator(dt, 10.0, 10, knobs.horizon, knobs.horizon, RADIUS, SPEED)
    for p, g in zip(starts, goals, strict=True):
        agent = sim.add_agent((float(p[0]), float(p[1])))
        heading = (g - p) / np.linalg.norm(g - p) * SPEED
        sim.set_agent_velocity(agent, (float(heading[0]), float(heading[1])))
    steps = round((knobs.frames - 1) * DT_RECORD / dt)
    frames = [starts.copy()]
    start = time.perf_counter()
    for step in range(steps):
        for i, g in enumerate(goals):
            p = sim.get_agent_position(i)
            dx, dy = g[0] - p.x, g[1] - p.y
            d = math.hypot(dx, dy)
            scale = SPEED * min(1.0, d / 0.5) / max(d, 1e-9)
            sim.set_agent_pref_velocity(i, (dx * scale, dy * scale))
        sim.do_step()
        if (step + 1) % round(DT_RECORD / dt) == 0:
            frames.append(
                np.array(
                    [
                        [sim.get_agent_position(i).x, sim.get_agent_position(i).y]
                        for i in range(len(goals))
                    ]
                )
            )
    wall = time.perf_counter() - start
    return wall, overlaps(np.stack(frames))


def run_jupedsim(
    knobs: CrowdKnobs, starts: np.ndarray, goals: np.ndarray
) -> tuple[float, int, float]:
    import jupedsim as jps
    from shapely import Polygon

    size = knobs.outer_radius + 5
    area = Polygon([(-size, -size), (size, -size), (size, size), (-size, size)])
    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(), geometry=area, dt=0.01)
    for p, g in zip(starts, goals, strict=True):
        exit_id = sim.add_exit_stage(
            Polygon(
                [
                    (g[0] - 0.3, g[1] - 0.3),
                    (g[0] + 0.3, g[1] - 0.3),
                    (g[0] + 0.3, g[1] + 0.3),
                    (g[0] - 0.3, g[1] + 0.3),
                ]
            )
        )
        journey = sim.add_journey(jps.JourneyDescription([exit_id]))
        sim.add_agent(
            jps.CollisionFreeSpeedModelAgentParameters(
                journey_id=journey,
                stage_id=exit_id,
                position=tuple(p),
                radius=RADIUS,
                desired_speed=SPEED,
            )
        )
    per_record = round(DT_RECORD / 0.01)
    frames, agent_seconds = [], 0.0
    start = time.perf_counter()
    for _ in range(knobs.frames - 1):
        agent_seconds += sim.agent_count() * DT_RECORD
        sim.iterate(per_record)
        positions = np.array([a.position for a in sim.agents()])
        if len(positions) > 1:
            frames.append(positions)
    wall = time.perf_counter() - start
    return wall, sum(overlaps(f[None]) for f in frames), agent_seconds


def ensure_deps(install: bool) -> bool:
    sys.path.insert(0, str(DEPS))
    try:
        importlib.import_module("jupedsim")
        importlib.import_module("pyrvo")
        return True
    except ImportError:
        if not install:
            return False
    print(f"installing jupedsim and pyrvo (--no-deps) into {DEPS} ...", file=sys.stderr)
    command = [
        sys.executable,
        "-m",
        "pip",
        "install",
        "-q",
        "--no-deps",
        "--target",
        str(DEPS),
        "jupedsim",
        "pyrvo",
        "shapely",
        "deprecated",
        "wrapt",
    ]
    if subprocess.run(command, check=False).returncode != 0:
        return False
    importlib.invalidate_caches()
    try:
        importlib.import_module("jupedsim")
        importlib.import_module("pyrvo")
        return True
    except ImportError:
        return False


def best_of(repeats: int, run, *args) -> tuple:
    """The result of the fastest of ``repeats`` calls of ``run`` (its first value is the wall)."""
    return min((run(*args) for _ in range(repeats)), key=lambda result: result[0])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default="6,20,100,500")
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-install", action="store_true")
    args = p.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core for every simulator
    others = ensure_deps(not args.no_install)
    if not others:
        print("JuPedSim / pyrvo unavailable: comparing the Pymunk generator only", file=sys.stderr)
    start = time.perf_counter()
    for controller in ("ttc", "orca"):
        run_pymunk(knobs_for(6, 1.0, controller), 1)
    print(f"controller compilation or cache load: {time.perf_counter() - start:.2f} s (once)")
    header = f"{'agents':>6}  {'simulator':<26}{'agent-s/s':>12}{'overlaps':>10}{'vs first':>14}"
    print(header)
    print("-" * len(header))
    for n in (int(s) for s in args.sizes.split(",")):
        knobs = knobs_for(n, args.seconds)
        agent_seconds = n * args.seconds
        rows = []
        batch = max(1, min(BATCH_SCENES, 2000 // n))
        for controller in ("ttc", "orca"):
            mine = replace(knobs, controller=controller, start=knobs_for(n, 1, controller).start)
            wall, bad = best_of(args.repeats, run_pymunk, mine, 1)
            rows.append((f"pymunk {controller}, one scene", agent_seconds / wall, bad))
            wall, bad = best_of(args.repeats, run_pymunk, mine, batch)
            rows.append((f"pymunk {controller}, {batch} scenes", batch * agent_seconds / wall, bad))
        if others:
            starts, goals = _place(
                knobs, np.random.default_rng(np.random.SeedSequence(0, spawn_key=(0,)))
            )
            wall, bad, jps_seconds = best_of(args.repeats, run_jupedsim, knobs, starts, goals)
            rows.append(("JuPedSim (collision-free)", jps_seconds / wall, bad))
            wall, bad = best_of(args.repeats, run_orca, knobs, starts, goals)
            rows.append(("RVO2 ORCA (pyrvo)", agent_seconds / wall, bad))
        base = rows[0][1]
        for name, rate, bad in rows:
            print(f"{n:>6}  {name:<26}{rate:>12,.0f}{bad:>10}{rate / base:>13.2f}x")
    print()
    header = f"{'whole domain':<20}{'domain agent-s/s':>18}{'simulator alone':>17}{'ratio':>8}"
    print(header)
    print("-" * len(header))
    for name in DOMAINS:
        whole, alone, agent_seconds = min(
            (whole_domain(name) for _ in range(args.repeats)), key=lambda r: r[0]
        )
        ratio = alone / whole
        print(
            f"{name:<20}{agent_seconds / whole:>18,.0f}{agent_seconds / alone:>17,.0f}{ratio:>8.0%}"
        )


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
