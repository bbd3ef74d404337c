"""The compiled crowd controller: neighbour search, pair forces and speculative contacts."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from sim.generators.crowd import CrowdKnobs, simulate
from sim.generators.crowd_controller import Controller, neighbour_pairs, speculative_contacts


def as_set(pairs: np.ndarray) -> set[tuple[int, int]]:
    return {(min(a, b), max(a, b)) for a, b in pairs.tolist()}


@pytest.mark.parametrize("spread", [0.5, 6.0, 5000.0])  # one cell, many cells, past MAX_CELLS
def test_neighbour_pairs_match_a_kd_tree_within_each_scene(spread):
    rng = np.random.default_rng(0)
    scenes, size, cutoff = 3, 60, 1.5
    state = np.zeros((scenes * size, 4))
    state[:, :2] = rng.uniform(-spread, spread, (scenes * size, 2))
    state[:size, :2] = np.round(state[:size, :2])  # exact ties at the cutoff and on cell edges
    expected = set()
    for k in range(scenes):
        scene = state[k * size : (k + 1) * size, :2]
        found = cKDTree(scene).query_pairs(cutoff * (1 - 1e-12), output_type="ndarray")
        expected |= as_set(found + k * size)
    found = neighbour_pairs(state, size, cutoff)
    assert len(found) == len(expected)  # every pair once
    assert as_set(found) == expected


def packed_state(agents: int, rng) -> np.ndarray:
    state = np.zeros((agents, 4))
    state[:, :2] = rng.uniform(-1.0, 1.0, (agents, 2))
    state[:, 2:] = rng.normal(0, 0.5, (agents, 2))
    return state


@pytest.mark.parametrize("agents", [12, 60])  # 60 in 2 x 2 m overflows the room for near pairs
def test_interactions_conserve_momentum_and_only_slow_approaches(agents):
    """Pair forces and contacts are equal and opposite; noise-free agents walking exactly at their
    preferred velocity are steered only by their neighbours, so the accelerations sum to zero."""
    rng = np.random.default_rng(1)
    state = packed_state(agents, rng)
    speed = np.linalg.norm(state[:, 2:], axis=1)
    goal = state[:, :2] + 1e6 * state[:, 2:] / speed[:, None]  # preferred velocity = velocity
    controller = Controller(
        agents, contact=0.2, dt=0.1, max_speed=1e3, noise_decay=1.0, noise_kick=0
    )
    noise = np.zeros((agents, 2))
    accel = controller.steer(state, goal, speed, noise, np.ones((agents, 2)))
    assert np.abs(accel).max() > 1.0  # the crowd really pushes
    np.testing.assert_allclose(accel.sum(axis=0), 0.0, atol=1e-9)
    assert not noise.any()


def test_speculative_contacts_stop_a_line_of_three_at_contact():
    """The outer agents run at the middle one; after the sweeps they stop at contact."""
    contact, dt = 0.4, 0.1
    state = np.array([[-0.7, 0, 2.0, 0], [0.0, 0, 0, 0], [0.7, 0, -2.0, 0], [5.0, 0, 1.0, 0]])
    velocity = state[:, 2:].copy()
    pairs = neighbour_pairs(state, 4, 10.0)
    speculative_contacts(state, velocity, pairs, contact, dt)
    after_two_steps = state[:, :2] + dt * state[:, 2:] + dt * velocity
    gaps = np.linalg.norm(after_two_steps[[0, 1]] - after_two_steps[[1, 2]], axis=1)
    # They close to contact and stop there, up to what four Gauss-Seidel sweeps leave (Chipmunk
    # resolves the rest).
    assert np.all((gaps > 0.99 * contact) & (gaps < contact + 1e-6)), gaps
    np.testing.assert_allclose(velocity.sum(axis=0), state[:, 2:].sum(axis=0))  # momentum
    np.testing.assert_array_equal(velocity[3], state[3, 2:])  # moving away: untouched


def test_contacts_hold_when_more_pairs_are_near_than_the_first_pass_has_room_for():
    """A 6 x 6 block at rest (630 near pairs, room for 304) beside two agents about to collide."""
    grid = np.stack(np.meshgrid(np.arange(6), np.arange(6)), -1).reshape(-1, 2) * 0.25
    state = np.zeros((38, 4))
    state[:36, :2] = grid
    state[36:] = [[-0.375, -1.0, 3.0, 0.0], [0.375, -1.0, -3.0, 0.0]]
    goal = state[:, :2] + [1.0, 0.0]
    controller = Controller(38, contact=0.2, dt=0.1, max_speed=1e3, noise_decay=1.0, noise_kick=0)
    accel = controller.steer(state, goal, np.zeros(38), np.zeros((38, 2)), np.zeros((38, 2)))
    velocity = state[:, 2:] + 0.1 * accel
    # After this step they will be 0.15 m apart, inside contact: they must not close any more.
    assert velocity[36, 0] - velocity[37, 0] <= 1e-9


def test_ou_noise_advances_in_place():
    state = np.zeros((1, 4))
    controller = Controller(1, contact=0.4, dt=0.1, max_speed=2, noise_decay=0.5, noise_kick=2)
    noise = np.array([[1.0, -1.0]])
    controller.steer(state, np.array([[10.0, 0.0]]), np.ones(1), noise, np.array([[0.25, 0.5]]))
    np.testing.assert_allclose(noise, [[0.5 + 0.5, -0.5 + 1.0]])


def test_a_hundred_agents_crossing_one_ring_never_overlap():
    """The benchmark's densest case: every agent heads through the centre at once and jams."""
    knobs = CrowdKnobs(agents=100, radius=0.2, frames=51, inner_radius=10.5, outer_radius=11.5)
    (positions,) = simulate(knobs, [np.random.SeedSequence(0)])
    closest = min(cKDTree(frame).query(frame, k=2)[0][:, 1].min() for frame in positions)
    assert closest >= 0.98 * 2 * knobs.radius
    assert closest <= 1.05 * 2 * knobs.radius  # the jam really presses them together
