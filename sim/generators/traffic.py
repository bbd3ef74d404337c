"""Vehicle trajectories from highway-env, every vehicle driven by IDM/MOBIL, headless.

One episode per seed: the controlled vehicle is replaced by an ``IDMVehicle``, the road is
stepped directly at ``sim_hz`` and every vehicle's state is read from ``road.vehicles`` at every
output frame (never from ``vehicle.history``, which keeps only 30 states). Vehicles get stable
ids from the exporter the first time they are seen. Each episode is cut into scenes of 8 + 12
frames every ``stride`` frames, keeping the vehicles present in all 20 frames within ``radius``
metres of the centre vehicle at the last observed frame, so long roads stay tractable. The split
sizes of a traffic family count episodes; each gives several scenes.

Episodes run in worker processes (``workers``), one pool shared by every domain the process
generates; every episode has its own seed, so the result is the same for any number of workers.
"""

from __future__ import annotations

import atexit
import multiprocessing
import signal
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from c2inet.errors import InputError
from c2inet.options import check_range
from sim.data import OBS_LEN, PRED_LEN, SPLITS, Domain, Scene, window_members
from sim.generators.base import Generator, child_seed
from sim.stats import motion_stats, proximity_stats

ENVS = {"highway": "highway-v0", "merge": "merge-generic-v1", "roundabout": "roundabout-generic-v1"}


@dataclass(frozen=True)
class TrafficKnobs:
    """Knobs of a traffic domain; ranges are checked on construction."""

    road: str = "highway"  # highway | merge | roundabout
    lanes: int = 4  # highway only
    vehicles: int = 20  # other vehicles on the road
    vehicles_density: float = 1.0  # highway-env's spacing factor (merge/roundabout: scales count)
    obs_noise: float = 0.0  # m, std of Gaussian noise on recorded positions
    idm_spread: float = 0.0  # relative std of per-vehicle IDM parameters (behaviour, not sensing)
    seconds: float = 30.0  # recorded episode length
    warmup: float = 2.0  # s simulated before recording starts
    dt: float = 0.4  # s between recorded frames
    sim_hz: int = 10  # simulation steps per second
    stride: int = 5  # frames between scene starts
    radius: float = 100.0  # m around the centre vehicle kept in a scene

    def __post_init__(self):
        if self.road not in ENVS:
            raise InputError(f"road={self.road!r} is unknown (known: {', '.join(ENVS)})")
        check_range("lanes", self.lanes, 1, 8)
        check_range("vehicles", self.vehicles, 1, 200)
        check_range("vehicles_density", self.vehicles_density, 0, 5, open_low=True)
        check_range("obs_noise", self.obs_noise, 0, 5)
        check_range("idm_spread", self.idm_spread, 0, 0.5)
        check_range("seconds", self.seconds, (OBS_LEN + PRED_LEN) * self.dt, 3600)
        check_range("warmup", self.warmup, 0, 60)
        check_range("dt", self.dt, 0, 2, open_low=True)
        check_range("sim_hz", self.sim_hz, 1, 100)
        steps = self.dt * self.sim_hz
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise InputError(
                f"dt={self.dt:g} is not a whole number of simulation steps at {self.sim_hz} Hz"
            )
        check_range("stride", self.stride, 1, 1000)
        check_range("radius", self.radius, 1, 10_000)

    @property
    def frames(self) -> int:
        return round(self.seconds / self.dt) + 1


@dataclass
class Episode:
    """Raw states of one episode: NaN where a vehicle is absent."""

    positions: np.ndarray  # (frames, vehicles, 2)
    speeds: np.ndarray  # (frames, vehicles)
    lanes: np.ndarray  # (frames, vehicles) lane id, -1 where absent
    crashed: np.ndarray  # (vehicles,) crashed at any time
    lanes_count: int


def _make_env(knobs: TrafficKnobs):
    import gymnasium as gym
    import highway_env  # noqa: F401  (registers the environments)

    config: dict[str, Any] = {
        "simulation_frequency": knobs.sim_hz,
        "vehicles_count": knobs.vehicles,
        "vehicles_density": knobs.vehicles_density,
        "duration": knobs.seconds + knobs.warmup + 1,
    }
    if knobs.road == "highway":
        config["lanes_count"] = knobs.lanes
    else:  # these roads ignore the density factor: scale the number of vehicles instead
        config["vehicles_count"] = max(1, round(knobs.vehicles * knobs.vehicles_density))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make(ENVS[knobs.road], render_mode=None)
    env.unwrapped.configure(config)
    return env


def _all_idm(env, rng: np.random.Generator, spread: float) -> None:
    """Replace the controlled vehicle by an IDM/MOBIL one; optionally spread IDM parameters."""
    from highway_env.vehicle.behavior import IDMVehicle

    unwrapped = env.unwrapped
    road = unwrapped.road
    for ego in list(unwrapped.controlled_vehicles):
        idm = IDMVehicle.create_from(ego)
        road.vehicles[road.vehicles.index(ego)] = idm
    unwrapped.controlled_vehicles = []
    if spread > 0:
        for vehicle in road.vehicles:
            for name in ("TIME_WANTED", "DISTANCE_WANTED", "COMFORT_ACC_MAX", "POLITENESS"):
                base = getattr(vehicle, name)
                setattr(
                    vehicle,
                    name,
                    base * float(np.clip(1 + spread * rng.standard_normal(), 0.3, 3.0)),
                )


def simulate_episode(knobs: TrafficKnobs, seed: np.random.SeedSequence) -> Episode:
    """Run one headless episode and record every vehicle at every output frame."""
    rng = np.random.default_rng(seed)
    env = _make_env(knobs)
    env.reset(seed=int(rng.integers(2**31)))
    _all_idm(env, rng, knobs.idm_spread)
    road = env.unwrapped.road
    per_frame = round(knobs.dt * knobs.sim_hz)
    for _ in range(round(knobs.warmup * knobs.sim_hz)):
        road.act()
        road.step(1 / knobs.sim_hz)
    frames, counter = knobs.frames, 0
    records: list[list[tuple[int, float, float, float, int]]] = []
    crashed: set[int] = set()
    lane_ids: dict[tuple, int] = {}
    for frame in range(frames):
        if frame:
            for _ in range(per_frame):
                road.act()
                road.step(1 / knobs.sim_hz)
        row = []
        for vehicle in road.vehicles:
            uid = getattr(vehicle, "_export_id", None)
            if uid is None:  # ids from a counter, never id(): Python reuses those
                uid = vehicle._export_id = counter
                counter += 1
            lane = lane_ids.setdefault(tuple(vehicle.lane_index), len(lane_ids))
            row.append((uid, *vehicle.position, vehicle.speed, lane))
            if vehicle.crashed:
                crashed.add(uid)
        records.append(row)
    env.close()
    positions = np.full((frames, counter, 2), np.nan)
    speeds = np.full((frames, counter), np.nan)
    lanes = np.full((frames, counter), -1, dtype=np.int64)
    for f, row in enumerate(records):
        data = np.array(row)
        ids = data[:, 0].astype(int)
        positions[f, ids] = data[:, 1:3]
        speeds[f, ids] = data[:, 3]
        lanes[f, ids] = data[:, 4].astype(int)
    if knobs.obs_noise > 0:
        positions = positions + rng.normal(0, knobs.obs_noise, positions.shape)
    hit = np.zeros(counter, dtype=bool)
    hit[list(crashed)] = True
    lanes_count = knobs.lanes if knobs.road == "highway" else 1
    return Episode(positions, speeds, lanes, hit, lanes_count)


def local_scenes(episode: Episode, knobs: TrafficKnobs) -> list[Scene]:
    """20-frame scenes every ``stride`` frames: vehicles present throughout, near the centre one."""
    whole = Scene(episode.positions, np.arange(episode.positions.shape[1], dtype=np.int64))
    scenes = []
    starts, members = window_members(whole, OBS_LEN + PRED_LEN, knobs.stride)
    for start, present in zip(starts, members, strict=True):
        full = np.nonzero(present)[0]
        last = episode.positions[start + OBS_LEN - 1, full]
        centre = last[np.argmin(np.linalg.norm(last - np.median(last, 0), axis=1))]
        keep = full[np.linalg.norm(last - centre, axis=1) <= knobs.radius]
        window = episode.positions[start : start + OBS_LEN + PRED_LEN, keep]
        scenes.append(Scene(window.copy(), keep.astype(np.int64)))
    return scenes


def traffic_stats(episodes: list[Episode], dt: float) -> dict[str, float]:
    """Vehicles per km per lane, mean headway (m), lane changes per vehicle-minute, crashes."""
    densities, headways, changes, minutes, crashes = [], [], 0, 0.0, 0
    for ep in episodes:
        for frame in range(ep.positions.shape[0]):
            here = ~np.isnan(ep.positions[frame, :, 0])
            x = ep.positions[frame, here, 0]
            if len(x) > 1:
                extent_km = max(np.ptp(x), 1.0) / 1000
                densities.append(len(x) / extent_km / ep.lanes_count)
            lanes = ep.lanes[frame, here]
            for lane in np.unique(lanes):
                xs = np.sort(x[lanes == lane])
                headways.extend(np.diff(xs))
        both = (ep.lanes[1:] >= 0) & (ep.lanes[:-1] >= 0)
        changes += int(((ep.lanes[1:] != ep.lanes[:-1]) & both).sum())
        minutes += both.sum() * dt / 60
        crashes += int(ep.crashed.sum())
    return {
        "vehicles_per_km_lane": float(np.mean(densities)) if densities else 0.0,
        "mean_headway": float(np.mean(headways)) if headways else 0.0,
        "lane_changes_per_vehicle_minute": float(changes / minutes) if minutes else 0.0,
        "crashes": crashes,
    }


def _episode_job(args: tuple[dict[str, Any], np.random.SeedSequence]) -> Episode:
    knobs, seed = args
    return simulate_episode(TrafficKnobs(**knobs), seed)


def run_episodes(
    knobs: dict[str, Any], seeds: list[np.random.SeedSequence], workers: int
) -> list[Episode]:
    """Episodes in order, in ``workers`` processes (1: in this process)."""
    jobs = [(knobs, s) for s in seeds]
    if workers <= 1 or len(jobs) <= 1:
        return [_episode_job(j) for j in jobs]
    pool = shared_pool(workers)
    try:
        return list(pool.map(_episode_job, jobs))
    except BaseException:  # Ctrl-C or a failed episode: drop the queued ones with the pool
        close_pool()
        raise


_POOL: dict[int, ProcessPoolExecutor] = {}  # at most one, by its number of workers


def shared_pool(workers: int) -> ProcessPoolExecutor:
    """The process's pool of ``workers`` episode workers, started once and kept for every
    later domain: starting a worker (a fresh interpreter importing highway-env) costs seconds,
    as much as a domain's episodes on it."""
    if workers not in _POOL:
        close_pool()
        context = multiprocessing.get_context("spawn")  # highway-env mutates class state
        _POOL[workers] = ProcessPoolExecutor(workers, context, _start_worker)
    return _POOL[workers]


def close_pool() -> None:
    """Stop the shared pool's workers, dropping the episodes still queued."""
    for pool in _POOL.values():
        pool.shutdown(wait=True, cancel_futures=True)
    _POOL.clear()


atexit.register(close_pool)


def _start_worker() -> None:
    """Workers ignore Ctrl-C (the driver stops the run) and import highway-env up front."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _make_env(TrafficKnobs()).close()


class TrafficGenerator(Generator):
    """highway-env roads with every vehicle on IDM/MOBIL; see the module docstring."""

    name = "traffic"
    version = 1
    Knobs = TrafficKnobs
    quick_splits = (2, 1, 1)  # episodes

    def rollout(self, knobs: dict[str, Any], seed, frames: int) -> Scene:
        options = TrafficKnobs(**{**knobs, "seconds": max(knobs["seconds"], frames * knobs["dt"])})
        episode = simulate_episode(options, seed)
        ids = np.arange(episode.positions.shape[1], dtype=np.int64)
        return Scene(episode.positions[:frames], ids)

    def generate(
        self, name, family, knobs: dict[str, Any], splits, seed, workers: int = 1
    ) -> Domain:
        options = TrafficKnobs(**knobs)
        seeds = {
            split: [child_seed(seed, split_id, k) for k in range(getattr(splits, split))]
            for split_id, split in enumerate(SPLITS)
        }
        flat = [s for split in SPLITS for s in seeds[split]]
        episodes = run_episodes(knobs, flat, workers)
        scenes: dict[str, list[Scene]] = {}
        first = 0
        for split in SPLITS:
            mine = episodes[first : first + len(seeds[split])]
            first += len(seeds[split])
            scenes[split] = [scene for ep in mine for scene in local_scenes(ep, options)]
        everything = [Scene(ep.positions, np.arange(ep.positions.shape[1])) for ep in episodes]
        stats = motion_stats(everything, options.dt)
        stats.update(proximity_stats(everything))
        stats.update(traffic_stats(episodes, options.dt))
        stats["density"] = stats["vehicles_per_km_lane"]
        stats["overlaps"] = stats["crashes"]
        return Domain(name, family, self.name, knobs, options.dt, scenes, stats)
