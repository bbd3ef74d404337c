"""The crowd controller: one compiled pass per control step that steers every agent.

Each agent has a preferred velocity (towards its goal, perturbed by Ornstein-Uhlenbeck
behavioural noise). The ``ttc`` controller relaxes towards it and adds the time-to-collision
power law of Karamouzas, Skinner and Guy (PRL 2014) computed for the disc radii; the ``orca``
controller takes the velocity closest to it that ORCA allows (``sim.generators.orca``, as RVO2).
The ``ttc`` velocities are then slowed by speculative contacts so that no pair closes past contact
within the next step. Neighbours come from a uniform cell grid per scene (ORCA's from a k-d tree,
as RVO2's). The kernels are compiled with Numba because this per-pair work is the generator's
inner loop: written as numpy array calls it cost four times Chipmunk's step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from c2inet.jit import options
from sim.generators.orca import orca_velocities

CACHED = options()  # cached where a cache can be written (c2inet.jit)

# Karamouzas et al. 2014 values, metres and seconds.
RELAXATION = 0.5  # s, time to reach the preferred velocity
TTC_K = 1.5  # avoidance strength
TTC_TAU0 = 3.0  # s, horizon beyond which interactions fade
SENSING = 3.0  # m, neighbours farther than this (plus the radii) are ignored
MAX_FORCE = 20.0  # m/s^2 cap on the avoidance acceleration
GRAZE = 0.05  # m: avoidance aims this far inside the contact distance, so agents pass as close
# as ORCA agents do (the paper data has minimum separation exactly 2r); Pymunk holds the contact
SLOW_DOWN = 0.5  # m from the goal within which agents slow to a stop
CONTACT_SWEEPS = 4  # Gauss-Seidel sweeps over the speculative contacts
HOLD_SWEEPS = 32  # and at most over ORCA's pairs (a dense jam needs many; most steps need none)
MAX_CELLS = 256  # per axis and scene; cells grow beyond the sensing range past this
ORCA_RANGE = 10.0  # m, RVO2's neighbour distance in the TrajNet++ ORCA settings
ORCA_NEIGHBOURS = 10  # RVO2's maximum number of neighbours there
NEAR_PER_AGENT = 8  # room for this many pairs close to contact per agent, else a second pass


@dataclass(frozen=True)
class Controller:
    """Constants of one simulation. Agents ``[k * scene_size, (k + 1) * scene_size)`` form scene
    k, and scenes never interact; ``contact`` is the centre distance at which two discs touch."""

    scene_size: int
    contact: float  # m
    dt: float  # s, control step
    max_speed: float  # m/s
    noise_decay: float  # OU: factor on the noise velocity per step
    noise_kick: float  # OU: scale of the standard normal increment per step
    kind: str = "ttc"  # "ttc" (time-to-collision forces) or "orca" (velocity obstacles)
    horizon: float = 2.0  # s, ORCA's time horizon
    lane: float = math.inf  # m: ORCA keeps centres this close to y = 0 (walls beyond)

    def steer(self, state, goal, speed, noise, kicks) -> np.ndarray:
        """Accelerations (per unit mass) that take every agent to its steered velocity in one
        step. ``state`` rows are (x, y, vx, vy); ``noise``, the agents' OU velocity, is advanced
        in place by the standard normal ``kicks``."""
        # Plain scalars, not this object: Numba dispatches on a record type far more slowly.
        constants = self.contact, self.dt, self.max_speed, self.noise_decay, self.noise_kick
        if self.kind == "ttc":
            return _steer(state, goal, speed, noise, kicks, self.scene_size, *constants)
        ahead = state.copy()  # where this step takes every agent: ORCA plans from there
        ahead[:, :2] += self.dt * state[:, 2:]
        neighbours = orca_neighbours(ahead[:, :2])
        orca = (*constants, self.horizon, self.lane)
        return _steer_orca(
            state, ahead, goal, speed, noise, kicks, neighbours, self.scene_size, orca
        )


def orca_neighbours(positions: np.ndarray) -> np.ndarray:
    """Each agent's ``ORCA_NEIGHBOURS`` nearest others within ``ORCA_RANGE``, nearest first, as
    RVO2 picks them (padding: ``len(positions)``). Scenes lie farther apart than that range, so
    no agent sees another scene."""
    k = min(ORCA_NEIGHBOURS + 1, len(positions))
    _, index = cKDTree(positions).query(positions, k=k, distance_upper_bound=ORCA_RANGE)
    return index.reshape(len(positions), k)


@njit(**CACHED)
def _steer(state, goal, speed, noise, kicks, scene_size, contact, dt, max_speed, decay, kick):
    """``Controller.steer`` with the time-to-collision controller, compiled."""
    # Pairs that can touch by the end of the next step: contact plus two steps of closing.
    reach = contact + 4 * max_speed * dt
    near = np.empty((NEAR_PER_AGENT * len(state), 2), np.int64)
    accel = np.zeros((len(state), 2))
    aim = max(contact - GRAZE, contact / 2)
    count = _visit_pairs(state, scene_size, SENSING + contact, reach, near, accel, aim)
    near = near[:count] if count <= len(near) else neighbour_pairs(state, scene_size, reach)
    preferred = _preferred(state, goal, speed, noise, kicks, decay, kick)
    velocity = np.empty((len(state), 2))
    for i in range(len(state)):
        velocity[i, 0] = state[i, 2] + dt * (
            (preferred[i, 0] - state[i, 2]) / RELAXATION + accel[i, 0]
        )
        velocity[i, 1] = state[i, 3] + dt * (
            (preferred[i, 1] - state[i, 3]) / RELAXATION + accel[i, 1]
        )
        top = math.sqrt(velocity[i, 0] ** 2 + velocity[i, 1] ** 2)
        if top > max_speed:
            velocity[i] *= max_speed / top
    speculative_contacts(state, velocity, near, contact, dt)
    return _accelerations(state, velocity, dt)


@njit(**CACHED)
def _steer_orca(state, ahead, goal, speed, noise, kicks, neighbours, scene_size, constants):
    """``Controller.steer`` with ORCA, compiled. ORCA sees each agent ``ahead``, where its
    current velocity takes it within this step, because Chipmunk moves a body before it applies
    the force set now: the chosen velocity starts to act from there, as in RVO2. Where ORCA's
    program has no solution (dense crowds), ``hold_apart`` keeps the pairs it would leave
    overlapping apart, and it keeps agents off the corridor's walls, which ORCA does not see."""
    contact, dt, max_speed, decay, kick, horizon, lane = constants
    preferred = _preferred(state, goal, speed, noise, kicks, decay, kick)
    limit = np.empty(len(state))
    for i in range(len(state)):
        wish = math.sqrt(preferred[i, 0] ** 2 + preferred[i, 1] ** 2)
        limit[i] = min(max_speed, max(speed[i], wish))  # never faster than the agent wishes
    velocity = orca_velocities(ahead, preferred, limit, neighbours, contact, horizon, dt)
    near = neighbour_pairs(ahead, scene_size, contact + 2 * max_speed * dt)
    hold_apart(ahead, velocity, near, contact, dt, lane)
    return _accelerations(state, velocity, dt)


@njit(**CACHED)
def _preferred(state, goal, speed, noise, kicks, decay, kick) -> np.ndarray:
    """Preferred velocities: towards the goal at the agent's speed (slowing within
    ``SLOW_DOWN`` of it) plus its OU noise, which the standard normal ``kicks`` advance in place."""
    preferred = np.empty((len(state), 2))
    for i in range(len(state)):
        noise[i, 0] = decay * noise[i, 0] + kick * kicks[i, 0]
        noise[i, 1] = decay * noise[i, 1] + kick * kicks[i, 1]
        dx, dy = goal[i, 0] - state[i, 0], goal[i, 1] - state[i, 1]
        distance = math.sqrt(dx * dx + dy * dy)
        scale = speed[i] / max(distance, 1e-9) * min(1.0, distance / SLOW_DOWN)
        preferred[i, 0], preferred[i, 1] = dx * scale + noise[i, 0], dy * scale + noise[i, 1]
    return preferred


@njit(**CACHED)
def _accelerations(state, velocity, dt) -> np.ndarray:
    """Accelerations that take every agent from its velocity in ``state`` to ``velocity`` in
    one step."""
    accel = np.empty((len(state), 2))
    for i in range(len(state)):
        accel[i, 0] = (velocity[i, 0] - state[i, 2]) / dt
        accel[i, 1] = (velocity[i, 1] - state[i, 3]) / dt
    return accel


@njit(**CACHED)
def neighbour_pairs(state: np.ndarray, scene_size: int, cutoff: float) -> np.ndarray:
    """Pairs of agents of the same scene whose centres are closer than ``cutoff``, shape (m, 2).

    Counts them in a first pass over the cell grid and stores them in a second, so that no array
    has to grow while the pairs are found.
    """
    no_accel = np.empty((0, 2))
    count = _visit_pairs(state, scene_size, 0.0, cutoff, np.empty((0, 2), np.int64), no_accel, 0.0)
    pairs = np.empty((count, 2), np.int64)
    _visit_pairs(state, scene_size, 0.0, cutoff, pairs, no_accel, 0.0)
    return pairs


@njit(**CACHED)
def _visit_pairs(state, scene_size, sensing, keep, pairs, accel, aim) -> int:
    """Visit the pairs of same-scene agents and return how many are closer than ``keep``.

    Stores those in ``pairs`` as far as it holds them, and adds the time-to-collision avoidance
    of the pairs closer than ``sensing`` (for discs that touch at centre distance ``aim``) to
    ``accel`` unless that is empty. Each scene is sorted into square cells at least as wide as
    both distances (a counting sort); each cell is then paired with itself and with four of its
    eight neighbours, the other four pairing with it.
    """
    cutoff = max(sensing, keep)
    found = 0
    for first in range(0, len(state), scene_size):
        last = min(first + scene_size, len(state))
        x0, y0 = state[first:last, 0].min(), state[first:last, 1].min()
        width, height = state[first:last, 0].max() - x0, state[first:last, 1].max() - y0
        size = max(cutoff, width / MAX_CELLS, height / MAX_CELLS)
        nx, ny = int(width / size) + 1, int(height / size) + 1
        cell = np.empty(last - first, np.int64)
        start = np.zeros(nx * ny + 1, np.int64)
        for a in range(first, last):
            cx = min(int((state[a, 0] - x0) / size), nx - 1)
            cy = min(int((state[a, 1] - y0) / size), ny - 1)
            cell[a - first] = cx * ny + cy
            start[cell[a - first] + 1] += 1
        start = np.cumsum(start)
        members = np.empty(last - first, np.int64)
        fill = start[:-1].copy()
        for a in range(first, last):
            members[fill[cell[a - first]]] = a
            fill[cell[a - first]] += 1
        # Work on a copy in cell order, so that the innermost loop reads contiguous rows.
        local = state[members]
        local_accel = np.zeros((len(local) if len(accel) else 0, 2))
        for here in range(nx * ny):
            cx, cy = here // ny, here % ny
            for ox, oy in ((0, 0), (1, -1), (1, 0), (1, 1), (0, 1)):
                if not (0 <= cx + ox < nx and 0 <= cy + oy < ny):
                    continue
                there = (cx + ox) * ny + cy + oy
                for slot in range(start[here], start[here + 1]):
                    # Within one cell, each pair once; across cells, every member of the other.
                    begin = slot + 1 if there == here else start[there]
                    for other in range(begin, start[there + 1]):
                        dx = local[slot, 0] - local[other, 0]
                        dy = local[slot, 1] - local[other, 1]
                        distance2 = dx * dx + dy * dy
                        if distance2 < keep * keep:
                            if found < len(pairs):
                                pairs[found, 0], pairs[found, 1] = members[slot], members[other]
                            found += 1
                        if distance2 < sensing * sensing and len(accel):
                            _avoid(local, local_accel, slot, other, aim)
        for k in range(len(local_accel)):
            accel[members[k], 0] += local_accel[k, 0]
            accel[members[k], 1] += local_accel[k, 1]
    return found


@njit(**CACHED, inline="always")
def _avoid(state: np.ndarray, accel: np.ndarray, i: int, j: int, aim: float) -> None:
    """Add the time-to-collision power-law accelerations of agents i and j (Karamouzas 2014)."""
    x0, x1 = state[i, 0] - state[j, 0], state[i, 1] - state[j, 1]
    v0, v1 = state[i, 2] - state[j, 2], state[i, 3] - state[j, 3]
    a = v0 * v0 + v1 * v1
    b = x0 * v0 + x1 * v1
    c = x0 * x0 + x1 * x1 - aim * aim
    discriminant = b * b - a * c
    if b >= 0 or discriminant <= 0 or a <= 1e-12:
        return  # not approaching, or never that close
    root = math.sqrt(discriminant)
    tau = max(c / (-b + root), 1e-3)  # time to contact: the smaller root, computed stably
    rate = 1 / tau
    magnitude = TTC_K * math.exp(-tau / TTC_TAU0) * rate * rate / a * (2 * rate + 1 / TTC_TAU0)
    # The force pushes along the relative position at the moment of contact.
    along = magnitude / root
    f0 = along * (a * x0 - b * v0) - magnitude * v0
    f1 = along * (a * x1 - b * v1) - magnitude * v1
    norm2 = f0 * f0 + f1 * f1
    if norm2 > MAX_FORCE * MAX_FORCE:
        cap = MAX_FORCE / math.sqrt(norm2)
        f0, f1 = f0 * cap, f1 * cap
    accel[i, 0] += f0
    accel[i, 1] += f1
    accel[j, 0] -= f0
    accel[j, 1] -= f1


@njit(**CACHED)
def hold_apart(ahead, velocity, pairs, contact, dt, lane) -> None:
    """Change velocities, in place, so that no pair ends the step from ``ahead`` closer than
    ``contact`` (each agent of a pair takes half of the missing distance) and no centre ends it
    farther than ``lane`` from y = 0 (the corridor's walls), in Gauss-Seidel sweeps.

    Unlike speculative contacts, which bound the approach speed along the pair's current
    direction, this looks at where the step ends, so pairs that pass each other at exactly
    contact distance (as ORCA lets them) keep their velocities.
    """
    for _ in range(HOLD_SWEEPS):
        moved = False
        for p in range(len(pairs)):
            i, j = pairs[p, 0], pairs[p, 1]
            x0 = ahead[j, 0] + dt * velocity[j, 0] - ahead[i, 0] - dt * velocity[i, 0]
            x1 = ahead[j, 1] + dt * velocity[j, 1] - ahead[i, 1] - dt * velocity[i, 1]
            distance = math.sqrt(x0 * x0 + x1 * x1)
            missing = contact - distance
            if missing > 1e-9 * contact and distance > 0.0:
                push = 0.5 * missing / (dt * distance)
                velocity[i, 0] -= push * x0
                velocity[i, 1] -= push * x1
                velocity[j, 0] += push * x0
                velocity[j, 1] += push * x1
                moved = True
        for i in range(len(ahead)):
            y = ahead[i, 1] + dt * velocity[i, 1]
            if abs(y) > lane:
                velocity[i, 1] = (math.copysign(lane, y) - ahead[i, 1]) / dt
                moved = True
        if not moved:
            return


@njit(**CACHED)
def speculative_contacts(state, velocity, pairs, contact, dt) -> None:
    """Slow approaching pairs, in place, so that no pair closes past contact within the next step.

    Chipmunk first moves the bodies with their current velocity, and the velocity set now acts one
    step later; it detects contacts only after moving them, so a fast approach would first overlap
    and then be pushed apart. Gauss-Seidel sweeps over the pairs (each agent takes half of a
    pair's excess approach speed) prevent that in advance.
    """
    for _ in range(CONTACT_SWEEPS):
        moved = False
        for p in range(len(pairs)):
            i, j = pairs[p, 0], pairs[p, 1]
            x0 = state[j, 0] + dt * state[j, 2] - state[i, 0] - dt * state[i, 2]
            x1 = state[j, 1] + dt * state[j, 3] - state[i, 1] - dt * state[i, 3]
            distance = max(math.sqrt(x0 * x0 + x1 * x1), 1e-9)
            n0, n1 = x0 / distance, x1 / distance
            closing = (velocity[i, 0] - velocity[j, 0]) * n0 + (
                velocity[i, 1] - velocity[j, 1]
            ) * n1
            excess = closing - max(distance - contact, 0.0) / dt
            if excess > 1e-9:
                velocity[i, 0] -= 0.5 * excess * n0
                velocity[i, 1] -= 0.5 * excess * n1
                velocity[j, 0] += 0.5 * excess * n0
                velocity[j, 1] += 0.5 * excess * n1
                moved = True
        if not moved:
            return
