"""Pymunk crowds: agents are discs in zero gravity, steered through forces by a compiled controller.

Every control step the controller (``crowd_controller``) chooses each agent's velocity from its
preferred velocity (towards its goal, perturbed by Ornstein-Uhlenbeck behavioural noise of
standard deviation ``noise`` m/s): by optimal reciprocal collision avoidance (``orca``, van den
Berg et al. 2011, as RVO2 computes it) or by a relaxation plus the time-to-collision power law of
Karamouzas, Skinner and Guy (``ttc``, PRL 2014), then speculative contacts. Pymunk then moves the
discs and resolves any contact that remains. Agents start at their preferred velocity
(``start = "moving"``, as in ORCA data) or at rest. Positions are recorded every ``dt`` seconds.

Many scenes are simulated in one Pymunk space, far apart, so that one controller call steers all
of them; each scene still draws its start, speeds and noise from its own child seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pymunk
import pymunk.batch
from numba import njit

from c2inet.errors import InputError
from c2inet.jit import options as jit_options
from c2inet.options import check_range
from sim.data import SPLITS, Domain, Scene
from sim.generators.base import Generator, child_seed
from sim.generators.crowd_controller import Controller
from sim.stats import motion_stats, proximity_stats

LAYOUTS = ("circle_crossing", "corridor", "crossing")
CONTROLLERS = ("ttc", "orca")
STARTS = ("rest", "moving")
PLACEMENT_BLOCKS = 50  # blocks of candidate starts to draw before the layout is called too full
SCENE_GAP = 10.0  # m between the farthest reaches of two scenes sharing one space (> sensing)
BATCH_SCENES = 32  # scenes per Pymunk space
KICK_BLOCK = 250  # control steps of noise increments drawn at a time, to bound memory
ORCA_SKIN = 0.005  # fraction of the radius by which ORCA's Pymunk discs are smaller (see simulate)
OVERLAP_TOLERANCE = 0.02  # fraction of 2r by which centres may approach before a pair "overlaps"


@dataclass(frozen=True)
class CrowdKnobs:
    """Knobs of a crowd domain; ranges are checked on construction."""

    layout: str = "circle_crossing"
    controller: str = "ttc"  # "orca": optimal reciprocal collision avoidance (as RVO2)
    start: str = "rest"  # "moving": agents start at their preferred velocity
    horizon: float = 2.0  # s, ORCA's time horizon (collisions avoided this far ahead)
    agents: int = 2
    density: float = 0.0  # agents per m^2 of the layout's area; > 0 overrides ``agents``
    radius: float = 0.2  # m; the minimum centre distance of two agents is 2 * radius
    noise: float = 0.0  # m/s, std of the OU perturbation of the preferred velocity
    noise_tau: float = 1.0  # s, correlation time of that perturbation
    speed: float = 1.0  # m/s, mean preferred speed
    speed_spread: float = 0.0  # m/s, std of the preferred speed across agents
    obs_noise: float = 0.0  # m, std of Gaussian noise added to recorded positions
    frames: int = 20  # recorded frames per scene
    dt: float = 0.4  # s between recorded frames
    control_dt: float = 0.1  # s between controller updates (and Pymunk steps)
    inner_radius: float = 4.0  # circle_crossing: agents start between these distances
    outer_radius: float = 5.0  # from the centre and walk to the opposite side
    length: float = 20.0  # corridor / crossing: length of the walkways, m
    width: float = 4.0  # corridor / crossing: width of the walkways, m

    def __post_init__(self):
        if self.layout not in LAYOUTS:
            raise InputError(f"layout={self.layout!r} is unknown (known: {', '.join(LAYOUTS)})")
        for name, value, known in (
            ("controller", self.controller, CONTROLLERS),
            ("start", self.start, STARTS),
        ):
            if value not in known:
                raise InputError(f"{name}={value!r} is unknown (known: {', '.join(known)})")
        check_range("horizon", self.horizon, 0, 60, open_low=True)
        check_range("agents", self.agents, 1, 5000)
        check_range("density", self.density, 0, 10)
        check_range("radius", self.radius, 0, 1, open_low=True)
        check_range("noise", self.noise, 0, 5)
        check_range("noise_tau", self.noise_tau, 0, 100, open_low=True)
        check_range("speed", self.speed, 0, 5, open_low=True)
        check_range("speed_spread", self.speed_spread, 0, self.speed / 2)
        check_range("obs_noise", self.obs_noise, 0, 2)
        check_range("frames", self.frames, 2, 100_000)
        check_range("dt", self.dt, 0, 5, open_low=True)
        check_range("control_dt", self.control_dt, 0, 0.1, open_low=True)
        steps = self.dt / self.control_dt
        if abs(steps - round(steps)) > 1e-9:
            raise InputError(f"dt={self.dt:g} is not a multiple of control_dt={self.control_dt:g}")
        check_range("inner_radius", self.inner_radius, 0.5, 1000)
        check_range("outer_radius", self.outer_radius, self.inner_radius, 1000)
        check_range("length", self.length, 2, 10_000)
        check_range("width", self.width, 4 * self.radius, self.length)
        packed = self.num_agents * math.pi * (self.radius + 0.05) ** 2
        if packed > 0.4 * self.start_area:
            raise InputError(
                f"{self.num_agents} agents of radius {self.radius:g} m do not fit the "
                f"{self.layout} start area of {self.start_area:.1f} m^2 (impossible density)"
            )

    @property
    def area(self) -> float:
        """The scene area that ``density`` refers to, m^2."""
        if self.layout == "circle_crossing":
            return math.pi * self.outer_radius**2
        if self.layout == "corridor":
            return self.length * self.width
        return 2 * self.length * self.width - self.width**2

    @property
    def start_area(self) -> float:
        if self.layout == "circle_crossing":
            return math.pi * (self.outer_radius**2 - self.inner_radius**2)
        if self.layout == "corridor":
            return self.length * (self.width - 2 * self.radius)
        return self.length * self.width  # two arms, each half its length

    @property
    def walk_extent(self) -> float:
        """How far from the scene centre an agent can get (m): its start, plus top speed walking."""
        start = self.outer_radius if self.layout == "circle_crossing" else self.length / 2
        return start + 2 * self.speed * (self.frames - 1) * self.dt + 1.0

    @property
    def scene_spacing(self) -> float:
        """Distance (m) between scenes simulated in one Pymunk space, so that they never meet."""
        return 2 * self.walk_extent + SCENE_GAP

    @property
    def num_agents(self) -> int:
        return max(1, round(self.density * self.area)) if self.density > 0 else self.agents


def _place(knobs: CrowdKnobs, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Start positions and goals of one scene, without overlaps (rejection sampling).

    Candidates are drawn in blocks and each is kept if it is clear of all kept before it, which
    is sequential rejection sampling with the draws made in bulk.
    """
    n, gap = knobs.num_agents, 2 * knobs.radius + 0.1
    if knobs.layout == "circle_crossing" and n == 2:  # the paper's scenes: 126 to 180 deg apart
        first = rng.uniform(-math.pi, math.pi)
        second = first + math.pi + rng.uniform(-0.3 * math.pi, 0.3 * math.pi)
        starts = _on_ring(knobs, rng, np.array([first, second]))
        return starts, -starts
    starts, goals = np.empty((0, 2)), np.empty((0, 2))
    for _ in range(PLACEMENT_BLOCKS):
        new_starts, new_goals = _candidates(knobs, rng, 4 * n)
        starts, goals = np.concatenate([starts, new_starts]), np.concatenate([goals, new_goals])
        kept = spaced_subset(starts, gap, n)
        starts, goals = starts[kept], goals[kept]
        if len(kept) == n:
            return starts, goals
    raise InputError(f"could not place {n} agents in layout {knobs.layout} (impossible density)")


def _candidates(knobs: CrowdKnobs, rng: np.random.Generator, count: int):
    """``count`` independent draws of a start position and its goal in the knobs' layout."""
    if knobs.layout == "circle_crossing":  # walk to the opposite side
        starts = _on_ring(knobs, rng, rng.uniform(-math.pi, math.pi, count))
        return starts, -starts
    along = rng.uniform(-knobs.length / 2, knobs.length / 2, count)
    edge = knobs.width / 2 - knobs.radius
    across = rng.uniform(-edge, edge, count)
    forward = rng.random(count) < 0.5
    if knobs.layout == "corridor":  # two opposing flows along x
        starts = np.stack([along, across], axis=1)
        goals = np.stack([np.where(forward, 1e4, -1e4), across], axis=1)
        return starts, goals
    # crossing: half the agents walk along x, half along y, each from its arm's near half
    along = -np.abs(along)
    starts = np.where(forward[:, None], np.stack([along, across], 1), np.stack([across, along], 1))
    goals = starts + np.where(forward[:, None], [1e4, 0.0], [0.0, 1e4])
    return starts, goals


def _on_ring(knobs: CrowdKnobs, rng: np.random.Generator, angles: np.ndarray) -> np.ndarray:
    """Circle-crossing starts at these angles, between the inner and outer radius."""
    distance = rng.uniform(knobs.inner_radius, knobs.outer_radius, (len(angles), 1))
    return distance * np.stack([np.cos(angles), np.sin(angles)], axis=1)


@njit(**jit_options())
def spaced_subset(points: np.ndarray, gap: float, limit: int) -> np.ndarray:
    """Indices of the first ``limit`` points, in order, that are ``gap`` clear of those before."""
    chosen = np.empty(limit, np.int64)
    count = 0
    for p in range(len(points)):
        clear = True
        for q in chosen[:count]:
            dx, dy = points[p, 0] - points[q, 0], points[p, 1] - points[q, 1]
            if dx * dx + dy * dy < gap * gap:
                clear = False
                break
        if clear:
            chosen[count] = p
            count += 1
            if count == limit:
                break
    return chosen[:count]


def _controller(knobs: CrowdKnobs) -> Controller:
    """The steering of one scene's agents (ORCA or social forces) with the knobs' noise."""
    decay = math.exp(-knobs.control_dt / knobs.noise_tau)
    return Controller(
        scene_size=knobs.num_agents,
        contact=2 * knobs.radius,
        dt=knobs.control_dt,
        max_speed=2 * knobs.speed,
        noise_decay=decay,
        noise_kick=knobs.noise * math.sqrt(1 - decay**2),
        kind=knobs.controller,
        horizon=knobs.horizon,
        lane=knobs.width / 2 - knobs.radius if knobs.layout == "corridor" else math.inf,
    )


def _space(
    knobs: CrowdKnobs, start: np.ndarray, initial: np.ndarray, scene_x: np.ndarray
) -> pymunk.Space:
    """A Pymunk space of every scene's discs at ``start`` moving at ``initial``, and each
    corridor scene's walls (scene k at x = ``scene_x[k]``)."""
    # ORCA lets agents pass at exactly contact distance; discs a hair smaller keep Chipmunk from
    # treating every such pass as a collision, so it resolves only real overlaps.
    skin = ORCA_SKIN if knobs.controller == "orca" else 0.0
    space = pymunk.Space()
    space.collision_slop = min(0.01, 0.05 * knobs.radius)  # the default 0.1 is for pixels
    space.use_spatial_hash(4 * knobs.radius, 4 * len(start))  # 3x faster than the default tree
    for p, v in zip(start, initial, strict=True):
        body = pymunk.Body(1.0, float("inf"))
        body.position = tuple(p)
        body.velocity = tuple(v)
        shape = pymunk.Circle(body, knobs.radius * (1 - skin))
        shape.friction = 0.0
        space.add(body, shape)
    if knobs.layout == "corridor":
        for x0 in scene_x:
            for side in (-1, 1):
                y = side * (knobs.width / 2 + 0.05)
                ends = (x0 - knobs.walk_extent, y), (x0 + knobs.walk_extent, y)
                space.add(pymunk.Segment(space.static_body, *ends, 0.05))
    return space


def simulate(knobs: CrowdKnobs, seeds: list[np.random.SeedSequence]) -> list[np.ndarray]:
    """Simulate one scene per seed together; returns positions (frames, agents, 2) per scene."""
    n, scenes = knobs.num_agents, len(seeds)
    substeps = round(knobs.dt / knobs.control_dt)
    steps = (knobs.frames - 1) * substeps
    rngs = [np.random.default_rng(s) for s in seeds]
    placed = [_place(knobs, rng) for rng in rngs]
    offsets = np.zeros((scenes * n, 2))
    offsets[:, 0] = np.repeat(np.arange(scenes) * knobs.scene_spacing, n)
    start = np.concatenate([p[0] for p in placed]) + offsets
    goal = np.concatenate([p[1] for p in placed]) + offsets
    speed = np.concatenate(
        [np.clip(rng.normal(knobs.speed, knobs.speed_spread, n), 0.1, None) for rng in rngs]
    )
    noise = np.concatenate([knobs.noise * rng.standard_normal((n, 2)) for rng in rngs])
    controller = _controller(knobs)
    if knobs.start == "moving":  # at the preferred speed, straight for the goal
        heading = goal - start
        initial = heading * (speed / np.maximum(np.linalg.norm(heading, axis=1), 1e-9))[:, None]
    else:
        initial = np.zeros_like(start)
    space = _space(knobs, start, initial, offsets[::n, 0])
    fields = pymunk.batch.BodyFields.POSITION | pymunk.batch.BodyFields.VELOCITY
    reader, writer = pymunk.batch.Buffer(), pymunk.batch.Buffer()
    rows = len(space.bodies)  # dynamic bodies come first; a static body may add one more row
    pymunk.batch.get_space_bodies(space, fields, reader)
    command = np.zeros((len(np.frombuffer(reader.float_buf())) // 4, 2))
    recorded = np.empty((knobs.frames, scenes * n, 2))
    recorded[0] = start
    for step in range(steps):
        if step % KICK_BLOCK == 0:  # OU increments, per scene from that scene's own seed
            block = min(KICK_BLOCK, steps - step)
            kicks = np.concatenate([rng.standard_normal((block, n, 2)) for rng in rngs], axis=1)
        reader.clear()
        pymunk.batch.get_space_bodies(space, fields, reader)
        state = np.frombuffer(reader.float_buf()).reshape(-1, 4)[:rows]
        # Steer through forces, not velocities: Chipmunk integrates positions with the velocity
        # its contact solver left, so a velocity set directly would push discs into each other.
        command[:rows] = controller.steer(state, goal, speed, noise, kicks[step % KICK_BLOCK])
        writer.set_float_buf(command.ravel())
        pymunk.batch.set_space_bodies(space, pymunk.batch.BodyFields.FORCE, writer)
        space.step(knobs.control_dt)
        if (step + 1) % substeps == 0:
            reader.clear()
            pymunk.batch.get_space_bodies(space, pymunk.batch.BodyFields.POSITION, reader)
            recorded[(step + 1) // substeps] = np.frombuffer(reader.float_buf()).reshape(-1, 2)[
                :rows
            ]
    recorded -= offsets
    return [recorded[:, k * n : (k + 1) * n].copy() for k in range(scenes)]


class CrowdGenerator(Generator):
    """Pymunk crowd scenes in three layouts; see the module docstring."""

    name = "crowd"
    version = 2
    Knobs = CrowdKnobs

    def rollout(self, knobs: dict[str, Any], seed, frames: int) -> Scene:
        options = CrowdKnobs(**{**knobs, "frames": max(frames, knobs["frames"])})
        (positions,) = simulate(options, [seed])
        return Scene(observed(positions, options, seed), np.arange(options.num_agents))

    @classmethod
    def contact(cls, knobs: dict[str, Any]) -> float | None:
        """Two discs touch at twice the radius."""
        return 2 * CrowdKnobs(**knobs).radius

    @classmethod
    def memory_bytes(cls, knobs: dict[str, Any], splits) -> int:
        """Positions of every scene, float64, about four times over (windows, Parquet, stats)."""
        options = CrowdKnobs(**knobs)
        scenes = sum(getattr(splits, split) for split in SPLITS)
        return 4 * scenes * options.frames * options.num_agents * 2 * 8

    def generate(self, name, family, knobs: dict[str, Any], splits, seed, workers=1) -> Domain:
        options = CrowdKnobs(**knobs)
        scenes: dict[str, list[Scene]] = {}
        for split_id, split in enumerate(SPLITS):
            count = getattr(splits, split)
            scene_seeds = [child_seed(seed, split_id, k) for k in range(count)]
            out: list[Scene] = []
            for first in range(0, count, BATCH_SCENES):
                batch = scene_seeds[first : first + BATCH_SCENES]
                for scene_seed, positions in zip(batch, simulate(options, batch), strict=True):
                    positions = observed(positions, options, scene_seed)
                    out.append(Scene(positions, np.arange(options.num_agents, dtype=np.int64)))
            scenes[split] = out
        everything = [s for split in SPLITS for s in scenes[split]]
        stats = motion_stats(everything, options.dt)
        stats.update(proximity_stats(everything, 2 * options.radius * (1 - OVERLAP_TOLERANCE)))
        stats["density"] = realised_density(everything, options)
        return Domain(name, family, self.name, knobs, options.dt, scenes, stats)


def observed(positions: np.ndarray, knobs: CrowdKnobs, seed) -> np.ndarray:
    """The recorded positions: with ``obs_noise``, Gaussian noise from the scene's own seed."""
    if knobs.obs_noise == 0:
        return positions
    rng = np.random.default_rng(seed.spawn(1)[0])
    return positions + rng.normal(0, knobs.obs_noise, positions.shape)


def realised_density(scenes: list[Scene], knobs: CrowdKnobs) -> float:
    """Mean number of agents per m^2 inside the layout's area over all recorded frames."""
    inside = 0
    frames = 0
    for scene in scenes:
        x, y = scene.positions[..., 0], scene.positions[..., 1]
        if knobs.layout == "circle_crossing":
            mask = x**2 + y**2 <= knobs.outer_radius**2
        else:
            in_x = (np.abs(x) <= knobs.length / 2) & (np.abs(y) <= knobs.width / 2)
            in_y = (np.abs(y) <= knobs.length / 2) & (np.abs(x) <= knobs.width / 2)
            mask = in_x if knobs.layout == "corridor" else in_x | in_y
        inside += int(mask.sum())
        frames += scene.num_frames
    return inside / frames / knobs.area if frames else 0.0
