"""Traffic exporter throughput against a bare ``env.step`` loop, and its speed-up with workers.

Prints vehicle-frames per second (vehicles on the road times output frames, over wall time) of
(a) a bare highway-env loop calling ``env.step`` at the output rate (0.4 s) on the same
configuration, recording nothing, and (b) the exporter, which steps the road directly and records
every vehicle at every frame; then the wall time of whole domains, generated one after another as
a run makes them (episodes, scenes, statistics), with 1 and 2 workers, the 2 workers' pool
started once and shared by every domain (its start-up counted). Targets: the exporter costs at
most 10 % over bare stepping; 2 workers are at least 1.8 times as fast as 1 on 2 cores.

    python benchmarks/traffic_throughput.py [--vehicles 20,50] [--seconds 30] \
        [--domains highway_density_1.0,1.5,2.0]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from sim.domains import build_domain
from sim.generators.traffic import TrafficKnobs, _make_env, close_pool, simulate_episode
from sim.scenario import parse_scenario


def bare_loop(knobs: TrafficKnobs, seed: int) -> float:
    """Vehicle-frames per second of plain env.step calls (ego on its default policy)."""
    env = _make_env(knobs)
    env.unwrapped.configure({"policy_frequency": 1 / knobs.dt})
    env.reset(seed=seed)
    road = env.unwrapped.road
    count = 0
    start = time.perf_counter()
    for _ in range(knobs.frames - 1):
        env.step(1)  # IDLE
        count += len(road.vehicles)
    wall = time.perf_counter() - start
    env.close()
    return count / wall


def exporter(knobs: TrafficKnobs, seed: int) -> float:
    start = time.perf_counter()
    episode = simulate_episode(knobs, np.random.SeedSequence(seed))
    wall = time.perf_counter() - start
    return int((~np.isnan(episode.positions[1:, :, 0])).sum()) / wall


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vehicles", default="20,50")
    p.add_argument("--seconds", type=float, default=30.0)
    p.add_argument("--domains", default="highway_density_1.0,1.5,2.0")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    print(f"{'vehicles':>8}  {'bare env.step':>14}  {'exporter':>10}  {'exporter cost':>13}")
    for n in (int(v) for v in args.vehicles.split(",")):
        knobs = TrafficKnobs(vehicles=n, seconds=args.seconds, warmup=0.0)
        bare = np.median([bare_loop(knobs, s) for s in range(3)])
        ours = np.median([exporter(knobs, s) for s in range(3)])
        print(f"{n:>8}  {bare:>14,.0f}  {ours:>10,.0f}  {bare / ours - 1:>+12.0%}")
    specs = parse_scenario(args.domains)
    episodes = sum(sum(vars(spec.family.splits).values()) for spec in specs)
    walls = {}
    for workers in (1, 2):
        start = time.perf_counter()
        for spec in specs:
            build_domain(spec, root_seed=0, workers=workers)
        walls[workers] = time.perf_counter() - start
        close_pool()
    print(
        f"{len(specs)} domains, {episodes} episodes: 1 worker {walls[1]:.1f} s, 2 workers "
        f"{walls[2]:.1f} s, speed-up {walls[1] / walls[2]:.2f}x"
    )


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
