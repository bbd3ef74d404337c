"""Pymunk crowds: agents are discs in zero gravity steered by a vectorised numpy controller.

Every control step the controller sets each agent's velocity: a relaxation towards its preferred
velocity (towards its goal, perturbed by Ornstein-Uhlenbeck behavioural noise of standard
deviation ``noise`` m/s), plus anticipatory avoidance by the time-to-collision power law of
Karamouzas, Skinner and Guy (PRL 2014) computed for the disc radii. Pymunk then moves the discs
and resolves any contact that remains. Positions are recorded every ``dt`` seconds.

Many scenes are simulated in one Pymunk space, far apart, so that one numpy call steers all of
them; each scene still draws its start, speeds and noise from its own child seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pymunk
import pymunk.batch
from scipy.spatial import cKDTree

from sim.data import SPLITS, Domain, Scene
from sim.errors import InputError
from sim.generators import Generator, child_seed
from sim.options import check_range
from sim.stats import motion_stats, proximity_stats

LAYOUTS = ("circle_crossing", "corridor", "crossing")
SCENE_SPACING = 1000.0  # m between simulated scenes sharing one space: they never interact
BATCH_SCENES = 32  # scenes per Pymunk space
OVERLAP_TOLERANCE = 0.02  # fraction of 2r by which centres may approach before a pair "overlaps"

# Controller constants (Karamouzas et al. 2014 values, metres and seconds).
RELAXATION = 0.5  # s, time to reach the preferred velocity
TTC_K = 1.5  # avoidance strength
TTC_TAU0 = 3.0  # s, horizon beyond which interactions fade
SENSING = 3.0  # m, neighbours farther than this (plus the radii) are ignored
MAX_FORCE = 20.0  # m/s^2 cap on the avoidance acceleration
GRAZE = 0.05  # m: avoidance aims this far inside the contact distance, so agents pass as close
# as ORCA agents do (the paper data has minimum separation exactly 2r); Pymunk holds the contact
SLOW_DOWN = 0.5  # m from the goal within which agents slow to a stop


@dataclass(frozen=True)
class CrowdKnobs:
    """Knobs of a crowd domain; ranges are checked on construction."""

    layout: str = "circle_crossing"
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
    def num_agents(self) -> int:
        return max(1, round(self.density * self.area)) if self.density > 0 else self.agents


def _place(knobs: CrowdKnobs, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Start positions and goals of one scene, without overlaps (rejection sampling)."""
    n, gap = knobs.num_agents, 2 * knobs.radius + 0.1
    starts, goals = np.zeros((n, 2)), np.zeros((n, 2))
    placed = 0
    for _ in range(200 * n):
        if placed == n:
            break
        if knobs.layout == "circle_crossing":
            if n == 2 and placed == 1:  # the paper's synthetic scenes: starts 126 to 180 deg apart
                first = math.atan2(starts[0, 1], starts[0, 0])
                angle = first + math.pi + rng.uniform(-0.3 * math.pi, 0.3 * math.pi)
            else:
                angle = rng.uniform(-math.pi, math.pi)
            distance = rng.uniform(knobs.inner_radius, knobs.outer_radius)
            start = distance * np.array([math.cos(angle), math.sin(angle)])
            goal = -start
        else:
            along = rng.uniform(-knobs.length / 2, knobs.length / 2)
            across = rng.uniform(-knobs.width / 2 + knobs.radius, knobs.width / 2 - knobs.radius)
            forward = 1.0 if rng.random() < 0.5 else -1.0
            if knobs.layout == "corridor":
                start = np.array([along, across])
                goal = np.array([forward * 1e4, across])
            else:  # crossing: half the agents walk along x, half along y, from the near arm
                along = -abs(along)
                start = np.array([along, across]) if forward > 0 else np.array([across, along])
                goal = start + (np.array([1e4, 0.0]) if forward > 0 else np.array([0.0, 1e4]))
        if placed and np.min(np.linalg.norm(starts[:placed] - start, axis=1)) < gap:
            continue
        starts[placed], goals[placed] = start, goal
        placed += 1
    if placed < n:
        raise InputError(
            f"could not place {n} agents in layout {knobs.layout} (impossible density)"
        )
    return starts, goals


def _avoidance(pos: np.ndarray, vel: np.ndarray, contact: float, pairs: np.ndarray) -> np.ndarray:
    """Time-to-collision power-law accelerations for the given neighbour pairs (Karamouzas 2014)."""
    force = np.zeros_like(pos)
    if len(pairs) == 0:
        return force
    i, j = pairs[:, 0], pairs[:, 1]
    x = pos[i] - pos[j]
    v = vel[i] - vel[j]
    a = np.einsum("pk,pk->p", v, v)
    b = np.einsum("pk,pk->p", x, v)
    c = np.einsum("pk,pk->p", x, x) - contact**2
    discriminant = b * b - a * c
    approaching = (b < 0) & (discriminant > 0) & (a > 1e-12)
    if not approaching.any():
        return force
    x, v, a, b, c, d = (arr[approaching] for arr in (x, v, a, b, c, discriminant))
    i, j = i[approaching], j[approaching]
    root = np.sqrt(d)
    tau = np.maximum((c / (-b + root)), 1e-3)  # the smaller root, computed stably
    magnitude = TTC_K * np.exp(-tau / TTC_TAU0) / (a * tau**2) * (2 / tau + 1 / TTC_TAU0)
    direction = v - (a[:, None] * x - b[:, None] * v) / root[:, None]
    f = -magnitude[:, None] * direction
    norm = np.linalg.norm(f, axis=1, keepdims=True)
    f *= np.minimum(1.0, MAX_FORCE / np.maximum(norm, 1e-12))
    for axis in range(2):
        force[:, axis] += np.bincount(i, f[:, axis], len(pos)) - np.bincount(
            j, f[:, axis], len(pos)
        )
    return force


def _speculative_contacts(
    pos: np.ndarray, vel: np.ndarray, contact: float, pairs: np.ndarray, dt: float
) -> np.ndarray:
    """Slow approaching pairs so that no pair closes more than its gap within one step.

    Chipmunk detects contacts after it has moved the bodies, so a fast approach would first
    overlap and only then be pushed apart; this one Jacobi pass of speculative contacts (each
    agent takes half of the excess approach speed) prevents most of that in advance.
    """
    if len(pairs) == 0:
        return vel
    i, j = pairs[:, 0], pairs[:, 1]
    x = pos[j] - pos[i]
    distance = np.maximum(np.sqrt(x[:, 0] ** 2 + x[:, 1] ** 2), 1e-9)
    normal = x / distance[:, None]
    closing = np.einsum("pk,pk->p", vel[i] - vel[j], normal)  # > 0: i and j approach
    allowed = np.maximum(distance - contact, 0.0) / dt
    excess = np.maximum(closing - allowed, 0.0)
    if not excess.any():
        return vel
    push = 0.5 * excess[:, None] * normal
    out = vel.copy()
    for axis in range(2):
        out[:, axis] -= np.bincount(i, push[:, axis], len(vel))
        out[:, axis] += np.bincount(j, push[:, axis], len(vel))
    return out


def simulate(knobs: CrowdKnobs, seeds: list[np.random.SeedSequence]) -> list[np.ndarray]:
    """Simulate one scene per seed together; returns positions (frames, agents, 2) per scene."""
    n, scenes = knobs.num_agents, len(seeds)
    substeps = round(knobs.dt / knobs.control_dt)
    steps = (knobs.frames - 1) * substeps
    rngs = [np.random.default_rng(s) for s in seeds]
    placed = [_place(knobs, rng) for rng in rngs]
    offsets = np.repeat(np.arange(scenes) * SCENE_SPACING, n)[:, None] * np.array([[1.0, 0.0]])
    start = np.concatenate([p[0] for p in placed]) + offsets
    goal = np.concatenate([p[1] for p in placed]) + offsets
    speed = np.concatenate(
        [np.clip(rng.normal(knobs.speed, knobs.speed_spread, n), 0.1, None) for rng in rngs]
    )
    # OU noise: its Gaussian increments, drawn per scene up front from that scene's own seed
    kicks = np.concatenate([rng.standard_normal((steps, n, 2)) for rng in rngs], axis=1)
    decay = math.exp(-knobs.control_dt / knobs.noise_tau)
    kick_scale = knobs.noise * math.sqrt(1 - decay**2)
    ou = np.concatenate([knobs.noise * rng.standard_normal((n, 2)) for rng in rngs])

    space = pymunk.Space()
    space.collision_slop = min(0.01, 0.05 * knobs.radius)  # the default 0.1 is for pixels
    for p in start:
        body = pymunk.Body(1.0, float("inf"))
        body.position = tuple(p)
        shape = pymunk.Circle(body, knobs.radius)
        shape.friction = 0.0
        space.add(body, shape)
    if knobs.layout == "corridor":
        for k in range(scenes):
            for side in (-1, 1):
                y = side * (knobs.width / 2 + 0.05)
                x0 = k * SCENE_SPACING
                wall = pymunk.Segment(space.static_body, (x0 - 400, y), (x0 + 400, y), 0.05)
                space.add(wall)

    fields = pymunk.batch.BodyFields.POSITION | pymunk.batch.BodyFields.VELOCITY
    reader, writer = pymunk.batch.Buffer(), pymunk.batch.Buffer()
    rows = len(space.bodies)  # dynamic bodies come first; a static body may add one more row
    pymunk.batch.get_space_bodies(space, fields, reader)
    command = np.zeros((len(np.frombuffer(reader.float_buf())) // 4, 2))
    contact = 2 * knobs.radius
    reach = 2 * 2 * knobs.speed * knobs.control_dt  # the most two agents can close in one step
    recorded = np.empty((knobs.frames, scenes * n, 2))
    recorded[0] = start
    for step in range(steps):
        reader.clear()
        pymunk.batch.get_space_bodies(space, fields, reader)
        state = np.frombuffer(reader.float_buf()).reshape(-1, 4)[:rows]
        pos, vel = state[:, :2], state[:, 2:]
        to_goal = goal - pos
        distance = np.linalg.norm(to_goal, axis=1, keepdims=True)
        ou = decay * ou + kick_scale * kicks[step]
        preferred = to_goal / np.maximum(distance, 1e-9) * speed[:, None]
        preferred = preferred * np.minimum(1.0, distance / SLOW_DOWN) + ou
        pairs = cKDTree(pos).query_pairs(SENSING + contact, output_type="ndarray")
        accel = (preferred - vel) / RELAXATION + _avoidance(
            pos, vel, max(contact - GRAZE, contact / 2), pairs
        )
        vel = vel + knobs.control_dt * accel
        top = np.linalg.norm(vel, axis=1, keepdims=True)
        vel *= np.minimum(1.0, 2 * knobs.speed / np.maximum(top, 1e-9))
        # Chipmunk first moves the bodies with their current velocity, and the velocity set
        # now acts one step later: check contacts from where the bodies will be by then.
        ahead = pos + knobs.control_dt * state[:, 2:]
        gap = ahead[pairs[:, 0]] - ahead[pairs[:, 1]]
        near = pairs[np.einsum("pk,pk->p", gap, gap) < (contact + reach) ** 2]
        vel = _speculative_contacts(ahead, vel, contact, near, knobs.control_dt)
        # Steer through forces, not velocities: Chipmunk integrates positions with the velocity
        # its contact solver left, so a velocity set directly would push discs into each other.
        command[:rows] = (vel - state[:, 2:]) / knobs.control_dt
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
    version = 1
    Knobs = CrowdKnobs

    def rollout(self, knobs: dict[str, Any], seed, frames: int) -> Scene:
        options = CrowdKnobs(**{**knobs, "frames": max(frames, knobs["frames"])})
        (positions,) = simulate(options, [seed])
        return Scene(positions, np.arange(options.num_agents, dtype=np.int64))

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
                    if options.obs_noise > 0:
                        rng = np.random.default_rng(scene_seed.spawn(1)[0])
                        positions = positions + rng.normal(0, options.obs_noise, positions.shape)
                    out.append(Scene(positions, np.arange(options.num_agents, dtype=np.int64)))
            scenes[split] = out
        everything = [s for split in SPLITS for s in scenes[split]]
        stats = motion_stats(everything, options.dt)
        stats.update(proximity_stats(everything, 2 * options.radius * (1 - OVERLAP_TOLERANCE)))
        stats["density"] = realised_density(everything, options)
        return Domain(name, family, self.name, knobs, options.dt, scenes, stats)


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
