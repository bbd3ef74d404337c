"""Optimal reciprocal collision avoidance (van den Berg, Guy, Lin and Manocha, ISRR 2011).

Each agent takes the velocity closest to its preferred one that lies in every half-plane its
neighbours allow: a neighbour's velocity obstacle over the time horizon, shared half and half
(one small linear program per agent). This follows RVO2's ``Agent::computeNewVelocity`` for
agents without static obstacles, step for step, so that it gives RVO2's velocities (the test
``test_orca_matches_rvo2`` holds it to velocities RVO2 itself computed); it is compiled with
Numba, like the time-to-collision controller, because the crowd generator calls it for every
agent at every control step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from c2inet.jit import options

CACHED = options()  # cached where a cache can be written (c2inet.jit)

EPSILON = 1e-5  # RVO2's RVO_EPSILON: lines this close to parallel are treated as parallel


@njit(**CACHED)
def orca_velocities(
    state: np.ndarray,
    preferred: np.ndarray,
    max_speed: np.ndarray,
    neighbours: np.ndarray,
    contact: float,
    horizon: float,
    dt: float,
) -> np.ndarray:
    """New velocities (n, 2) of agents with ``state`` rows (x, y, vx, vy).

    ``neighbours[i]`` lists agent i's neighbours nearest first, padded with any index out of
    range; ``contact`` is the centre distance at which two agents touch, ``horizon`` the time
    over which collisions are avoided, and ``dt`` the step (for pairs already in contact).
    """
    n = len(state)
    out = np.empty((n, 2))
    lines = np.empty((neighbours.shape[1], 4))  # point x, point y, direction x, direction y
    for i in range(n):
        count = 0
        for j in neighbours[i]:
            if j < 0 or j >= n or j == i:
                continue
            _orca_line(state, i, j, contact, horizon, dt, lines[count])
            count += 1
        result = np.empty(2)
        used = lines[:count]
        failed = _program2(used, max_speed[i], preferred[i, 0], preferred[i, 1], False, result)
        if failed < count:
            _program3(used, failed, max_speed[i], result)
        out[i, 0], out[i, 1] = result[0], result[1]
    return out


@njit(**CACHED)
def _orca_line(state, i, j, contact, horizon, dt, line) -> None:
    """The half-plane of velocities that agent j leaves agent i (its share of the avoidance)."""
    px, py = state[j, 0] - state[i, 0], state[j, 1] - state[i, 1]
    vx, vy = state[i, 2] - state[j, 2], state[i, 3] - state[j, 3]
    distance2 = px * px + py * py
    contact2 = contact * contact
    if distance2 > contact2:
        inverse = 1.0 / horizon
        wx, wy = vx - inverse * px, vy - inverse * py  # from the cut-off circle's centre
        w2 = wx * wx + wy * wy
        dot = wx * px + wy * py
        if dot < 0.0 and dot * dot > contact2 * w2:  # closest to the cut-off circle
            w = math.sqrt(w2)
            ux, uy = wx / w, wy / w
            line[2], line[3] = uy, -ux
            scale = contact * inverse - w
            ux, uy = scale * ux, scale * uy
        else:  # closest to one of the two legs of the cone
            leg = math.sqrt(distance2 - contact2)
            if px * wy - py * wx > 0.0:  # left leg
                line[2] = (px * leg - py * contact) / distance2
                line[3] = (px * contact + py * leg) / distance2
            else:  # right leg
                line[2] = -(px * leg + py * contact) / distance2
                line[3] = -(-px * contact + py * leg) / distance2
            along = vx * line[2] + vy * line[3]
            ux, uy = along * line[2] - vx, along * line[3] - vy
    else:  # already in contact: separate within one step
        inverse = 1.0 / dt
        wx, wy = vx - inverse * px, vy - inverse * py
        w = math.sqrt(wx * wx + wy * wy)
        ux, uy = wx / w, wy / w
        line[2], line[3] = uy, -ux
        scale = contact * inverse - w
        ux, uy = scale * ux, scale * uy
    line[0] = state[i, 2] + 0.5 * ux
    line[1] = state[i, 3] + 0.5 * uy


@njit(**CACHED)
def _det(ax, ay, bx, by) -> float:
    return ax * by - ay * bx


@njit(**CACHED)
def _program1(lines, k, radius, opt_x, opt_y, direction_opt, result) -> bool:
    """Best point on line k within the speed disc and the lines before k; False if none."""
    px, py, dx, dy = lines[k, 0], lines[k, 1], lines[k, 2], lines[k, 3]
    dot = px * dx + py * dy
    discriminant = dot * dot + radius * radius - (px * px + py * py)
    if discriminant < 0.0:
        return False  # the speed disc misses the line
    root = math.sqrt(discriminant)
    left, right = -dot - root, -dot + root
    for m in range(k):
        denominator = _det(dx, dy, lines[m, 2], lines[m, 3])
        numerator = _det(lines[m, 2], lines[m, 3], px - lines[m, 0], py - lines[m, 1])
        if abs(denominator) <= EPSILON:  # parallel lines
            if numerator < 0.0:
                return False
            continue
        t = numerator / denominator
        if denominator >= 0.0:
            right = min(right, t)
        else:
            left = max(left, t)
        if left > right:
            return False
    if direction_opt:
        t = right if opt_x * dx + opt_y * dy > 0.0 else left
    else:
        t = min(max(dx * (opt_x - px) + dy * (opt_y - py), left), right)
    result[0], result[1] = px + t * dx, py + t * dy
    return True


@njit(**CACHED)
def _program2(lines, radius, opt_x, opt_y, direction_opt, result) -> int:
    """The velocity in the speed disc and every line closest to ``opt`` (or furthest along it
    with ``direction_opt``); returns the first line it fails on, or ``len(lines)``."""
    if direction_opt:
        result[0], result[1] = opt_x * radius, opt_y * radius
    elif opt_x * opt_x + opt_y * opt_y > radius * radius:
        norm = math.sqrt(opt_x * opt_x + opt_y * opt_y)
        result[0], result[1] = opt_x / norm * radius, opt_y / norm * radius
    else:
        result[0], result[1] = opt_x, opt_y
    for k in range(len(lines)):
        if _det(lines[k, 2], lines[k, 3], lines[k, 0] - result[0], lines[k, 1] - result[1]) > 0.0:
            keep_x, keep_y = result[0], result[1]
            if not _program1(lines, k, radius, opt_x, opt_y, direction_opt, result):
                result[0], result[1] = keep_x, keep_y
                return k
    return len(lines)


@njit(**CACHED)
def _program3(lines, begin, radius, result) -> None:
    """When the lines leave no velocity: the one that violates them least (in place)."""
    distance = 0.0
    projected = np.empty((len(lines), 4))
    for k in range(begin, len(lines)):
        px, py, dx, dy = lines[k, 0], lines[k, 1], lines[k, 2], lines[k, 3]
        if _det(dx, dy, px - result[0], py - result[1]) <= distance:
            continue
        count = 0
        for m in range(k):
            determinant = _det(dx, dy, lines[m, 2], lines[m, 3])
            if abs(determinant) <= EPSILON:
                if dx * lines[m, 2] + dy * lines[m, 3] > 0.0:
                    continue  # same direction
                projected[count, 0] = 0.5 * (px + lines[m, 0])
                projected[count, 1] = 0.5 * (py + lines[m, 1])
            else:
                t = _det(lines[m, 2], lines[m, 3], px - lines[m, 0], py - lines[m, 1]) / determinant
                projected[count, 0], projected[count, 1] = px + t * dx, py + t * dy
            ex, ey = lines[m, 2] - dx, lines[m, 3] - dy
            norm = math.sqrt(ex * ex + ey * ey)
            projected[count, 2], projected[count, 3] = ex / norm, ey / norm
            count += 1
        keep_x, keep_y = result[0], result[1]
        if _program2(projected[:count], radius, -dy, dx, True, result) < count:
            result[0], result[1] = keep_x, keep_y  # only numerical error can get here
        distance = _det(dx, dy, px - result[0], py - result[1])
