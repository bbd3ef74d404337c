"""Traffic domains from highway-env: the exporter, realised density, workers, errors."""

from dataclasses import asdict

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.domains import build_domain
from sim.families import SCENARIOS_DIR, Splits
from sim.generators.traffic import (
    TrafficKnobs,
    close_pool,
    local_scenes,
    run_episodes,
    shared_pool,
    simulate_episode,
)
from sim.scenario import parse_scenario


def shortened(tmp_path, family: str, **knobs) -> str:
    """A copy of a shipped family with shorter episodes, so tests stay quick; returns its name."""
    text = (SCENARIOS_DIR / f"{family}.toml").read_text()
    for key, value in knobs.items():
        text = "\n".join(
            f"{key} = {value}" if line.startswith(f"{key} =") else line
            for line in text.splitlines()
        )
    (tmp_path / f"short_{family}.toml").write_text(text)
    return f"short_{family}"


def test_every_vehicle_is_recorded_with_a_stable_id_at_every_frame():
    knobs = TrafficKnobs(vehicles=8, seconds=10.0)
    episode = simulate_episode(knobs, np.random.SeedSequence(4))
    frames = knobs.frames
    assert episode.positions.shape[0] == frames == 26
    present = ~np.isnan(episode.positions[..., 0])
    assert present[0].sum() == 9  # 8 others plus the former ego, now on IDM
    # a vehicle id keeps its vehicle: frame-to-frame moves are road-speed sized, never jumps
    step = np.linalg.norm(np.diff(episode.positions, axis=0), axis=-1)
    assert np.nanmax(step) < 40 * knobs.dt and np.nanmin(step) > 0
    assert np.all(episode.speeds[present] > 0)


def test_same_seed_same_episode():
    knobs = TrafficKnobs(vehicles=6, seconds=8.0)
    a, b = (simulate_episode(knobs, np.random.SeedSequence(9)) for _ in range(2))
    np.testing.assert_array_equal(a.positions, b.positions)


def test_local_scenes_keep_present_vehicles_near_the_centre():
    knobs = TrafficKnobs(vehicles=15, seconds=16.0, radius=30.0, stride=4)
    episode = simulate_episode(knobs, np.random.SeedSequence(1))
    scenes = local_scenes(episode, knobs)
    assert len(scenes) == (knobs.frames - 20) // 4 + 1
    for scene in scenes:
        assert scene.positions.shape[0] == 20 and not np.isnan(scene.positions).any()
        last = scene.positions[7]
        assert np.min(np.max(np.linalg.norm(last[:, None] - last[None], axis=-1), axis=1)) <= 30.0


def test_realised_density_rises_across_the_density_curriculum(tmp_path):
    family = shortened(tmp_path, "highway_density", seconds=12.0)
    stats = [
        build_domain(spec, 0, splits=Splits(1, 0, 1)).stats
        for spec in parse_scenario(f"{family}_0.5..2.0:0.5", [tmp_path])
    ]
    density = [s["vehicles_per_km_lane"] for s in stats]
    assert all(b > a for a, b in zip(density, density[1:], strict=False)), density
    assert all(s["crashes"] >= 0 and s["mean_headway"] > 0 for s in stats)
    assert stats[0]["mean_headway"] > stats[-1]["mean_headway"]


def test_results_are_identical_for_any_number_of_workers(tmp_path):
    family = shortened(tmp_path, "highway_noise", seconds=9.0, vehicles=6)
    (spec,) = parse_scenario(f"{family}_0.5", [tmp_path])
    one = build_domain(spec, 3, splits=Splits(2, 0, 1), workers=1)
    two = build_domain(spec, 3, splits=Splits(2, 0, 1), workers=2)
    for split in ("train", "test"):
        for a, b in zip(one.scenes[split], two.scenes[split], strict=True):
            np.testing.assert_array_equal(a.positions, b.positions)
    assert one.stats == two.stats


def test_one_worker_pool_serves_every_domain_and_stops_cleanly():
    knobs = asdict(TrafficKnobs(vehicles=4, seconds=8.0, warmup=0.0))
    seeds = [np.random.SeedSequence(7, spawn_key=(k,)) for k in range(3)]
    first = run_episodes(knobs, seeds, workers=2)
    pool = shared_pool(2)
    workers = set(pool._processes)  # the worker processes' ids
    again = run_episodes(knobs, seeds, workers=2)  # the next domain: the same processes
    assert shared_pool(2) is pool and set(pool._processes) == workers and len(workers) == 2
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a.positions, b.positions)
    close_pool()
    assert shared_pool(2) is not pool  # a closed pool is replaced, never reused
    close_pool()


def test_observation_noise_moves_positions_not_behaviour():
    clean = simulate_episode(TrafficKnobs(vehicles=5, seconds=8.0), np.random.SeedSequence(2))
    noisy = simulate_episode(
        TrafficKnobs(vehicles=5, seconds=8.0, obs_noise=0.5), np.random.SeedSequence(2)
    )
    difference = (noisy.positions - clean.positions)[~np.isnan(clean.positions)]
    assert abs(difference.std() - 0.5) < 0.1
    np.testing.assert_array_equal(noisy.speeds, clean.speeds)


@pytest.mark.parametrize(
    ("scenario", "message"),
    [
        ("highway_density_-1", "out of range"),
        ("highway_noise_-0.2", "out of range"),
        ("merge_density_0", "out of range"),
    ],
)
def test_bad_traffic_knobs_are_input_errors(scenario, message):
    with pytest.raises(InputError, match=message):
        parse_scenario(scenario)


def test_zero_lanes_in_a_family_file_is_an_input_error(tmp_path):
    (tmp_path / "roads.toml").write_text(
        'generator = "traffic"\nknob = "vehicles_density"\n[knobs]\nlanes = 0\n'
    )
    with pytest.raises(InputError, match="lanes=0 is out of range"):
        parse_scenario("roads_1.0", [tmp_path])
