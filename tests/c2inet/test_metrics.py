"""Metrics against hand-computed cases."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from c2inet.data import Windows
from c2inet.evaluation import VARIANT_METRICS, evaluate
from c2inet.metrics import (
    average_seen,
    backward_transfer,
    best_of_k,
    displacement_errors,
    evaluate_predictions,
    forgetting_final,
    forgetting_worst,
)
from c2inet.report import summarise, summarise_diagnostics, table_rows


def test_displacement_errors_by_hand():
    truth = np.zeros((2, 1, 2))  # two future steps, one agent at the origin
    pred = np.array([[[[3.0, 4.0]], [[0.0, 1.0]]]])  # distances 5 then 1
    ade, fde = displacement_errors(pred, truth)
    assert ade.tolist() == [[3.0]] and fde.tolist() == [[1.0]]


def test_joint_and_per_agent_minimum_differ():
    # one scene, two agents, two samples: sample 0 is good for agent 0, sample 1 for agent 1
    errors = np.array([[1.0, 4.0], [3.0, 1.5]])
    scene_start = np.array([0, 2])
    assert best_of_k(errors, scene_start, "agent").tolist() == [1.0, 1.5]  # mean 1.25
    # joint: sums 5.0 and 4.5, so sample 1 for the whole scene
    assert best_of_k(errors, scene_start, "joint").tolist() == [3.0, 1.5]  # mean 2.25


def test_joint_minimum_is_taken_per_scene():
    errors = np.array([[1.0, 1.0, 9.0], [2.0, 2.0, 1.0]])
    joint = best_of_k(errors, np.array([0, 2, 3]), "joint")
    assert joint.tolist() == [1.0, 1.0, 1.0]
    with pytest.raises(ValueError):
        best_of_k(errors, np.array([0, 3]), "scene")


def test_evaluate_predictions_labels_every_aggregation():
    truth = np.zeros((1, 2, 2))
    pred = np.array([[[[1.0, 0.0], [4.0, 0.0]]], [[[3.0, 0.0], [1.5, 0.0]]]])  # (K=2, T=1, N=2, 2)
    scores = evaluate_predictions(pred, truth, np.array([0, 2]), point=pred.mean(axis=0))
    assert scores["ade"] == pytest.approx(2.25) and scores["ade_agent"] == pytest.approx(1.25)
    assert scores["ade_draw"] == pytest.approx(2.5) and scores["fde"] == pytest.approx(2.25)
    assert scores["ade_k1"] == pytest.approx((2.0 + 2.75) / 2)  # the mean of the two samples
    assert "ade_k1" not in evaluate_predictions(pred, truth, np.array([0, 2]))


class NoisyOracle(torch.nn.Module):
    """The true future plus symmetric Gaussian noise: its samples scatter around the truth."""

    def predict(self, batch, samples: int) -> torch.Tensor:
        truth = batch.fut
        return truth + 0.5 * torch.randn(samples, *truth.shape)


def test_the_point_prediction_beats_one_draw_when_the_noise_is_symmetric():
    windows = Windows(np.random.default_rng(0).normal(size=(40, 20, 2)), np.arange(0, 41, 2))
    for k in (1, 5, 20):  # fewer than 16 samples: the point prediction draws its own 16
        scores = evaluate(NoisyOracle(), windows, k, seed=3)
        assert scores["ade_k1"] < 0.5 * scores["ade_draw"]
    assert evaluate(NoisyOracle(), windows, 20, 3) == evaluate(NoisyOracle(), windows, 20, 3)


def test_continual_scores_by_hand():
    r = np.array([[1.0, 5.0, 5.0], [2.0, 1.0, 5.0], [1.5, 3.0, 2.0]])
    np.testing.assert_allclose(average_seen(r), [1.0, 1.5, (1.5 + 3.0 + 2.0) / 3])
    np.testing.assert_allclose(forgetting_worst(r), [2.0 - 1.0, 3.0 - 1.0])
    np.testing.assert_allclose(forgetting_final(r), [1.5 - 1.0, 3.0 - 1.0])
    assert backward_transfer(r) == pytest.approx(((1.5 - 1.0) + (3.0 - 1.0)) / 2)
    assert backward_transfer(r[:1, :1]) == 0.0


def test_summary_averages_seeds_and_names_each_variant():
    first = {m: np.array([[1.0, 3.0], [2.0, 1.0]]) for m in VARIANT_METRICS}
    second = {m: v + 1.0 for m, v in first.items()}
    for run in (first, second):
        run.update({f"{m}_c_posterior": run[m] / 2 for m in VARIANT_METRICS})
    out = summarise([first, second], [[{}, {}], [{}, {}]])
    assert out["variants"] == ["c_posterior"]
    assert out["avg_seen_ade"] == [1.5, 2.0] and out["avg_seen_ade_std"] == [0.5, 0.5]
    assert out["avg_seen_ade_c_posterior"] == [0.75, 1.0]
    assert out["forgetting_final_ade"] == 1.0 and out["forgetting_final_ade_c_posterior"] == 0.5
    assert out["final_ade_per_seed"] == [1.5, 2.5]  # what the paired comparison reads
    assert out["forgetting_final_ade_per_seed"] == [1.0, 1.0]
    rows = table_rows({"m": out}, ["a", "b"])
    assert [r[0] for r in rows[1:]] == ["m", "m, c from posterior"]
    # beside constant velocity (final average 1.8): the row that ends above it says so
    cv = {**out, "variants": [], "avg_seen_ade": [1.0, 1.8]}
    rows = table_rows({"m": out, "cv": cv}, ["a", "b"])
    assert [r[0] for r in rows[1:]] == ["m (worse than cv)", "m, c from posterior", "cv"]


def test_diagnostics_average_over_seeds_and_keep_the_first_queue():
    seed0 = [{"mi_xc": 1.0, "kl_c": [1.0, 3.0], "probe_c": None, "queue": {"size": 3}}]
    seed1 = [{"mi_xc": 2.0, "kl_c": [2.0, 5.0], "probe_c": None, "queue": {"size": 4}}]
    (merged,) = summarise_diagnostics([seed0, seed1])
    assert merged["mi_xc"] == 1.5 and merged["kl_c"] == [1.5, 4.0]
    assert merged["probe_c"] is None and merged["queue"] == {"size": 3}


def test_collisions_count_agents_whose_paths_meet_predicted_or_true():
    """Two agents walking head-on through each other between two frames collide (the check
    reads the midpoints between frames); agents a metre apart do not; a lone agent is not
    counted; the primary agent (each scene's first) is scored apart."""
    from c2inet.metrics import collisions

    t = np.arange(12, dtype=float)[:, None]
    meeting = np.stack([np.hstack([t - 5.5, 0 * t]), np.hstack([5.5 - t, 0 * t])], axis=1)
    apart = np.stack([np.hstack([t, 0 * t]), np.hstack([t, 0 * t + 1.0])], axis=1)
    lone = np.hstack([t, 0 * t + 9.0])[:, None]
    point = np.concatenate([meeting, apart, lone], axis=1)  # (12, 5, 2): scenes of 2, 2 and 1
    starts = np.array([0, 2, 4, 5])
    rates = collisions(point, point, starts)
    assert rates["col_pred"] == rates["col_truth"] == 0.5  # 2 of the 4 agents with a neighbour
    assert rates["col_pred_primary"] == 0.5  # 1 of the 2 scenes' primary agents
    truth = point.copy()
    truth[:, 1] += [0.0, 3.0]  # the second truly walked 3 m aside; the first did not
    rates = collisions(point, truth, starts)
    assert (rates["col_pred"], rates["col_truth"], rates["col_truth_primary"]) == (0.5, 0.25, 0.0)
    truth[:, 0] -= [0.0, 3.0]  # and the first 3 m the other way: no prediction meets a truth
    assert collisions(point, truth, starts)["col_truth"] == 0.0
    assert set(collisions(lone, lone, np.array([0, 1])).values()) == {0.0}


def test_collisions_at_the_bodies_contact_distance_where_the_data_knows_it():
    """Agents passing 0.3 m apart miss at TrajNet++'s 0.2 m and touch as discs of radius 0.2 m:
    the windows' ``contact`` adds the bodies' rates; windows without one add none; the contact
    survives subsets, augmentation and checkpoints, and concatenation where the parts share it."""
    from c2inet.augment import augment_scenes
    from c2inet.metrics import evaluate_predictions

    t = np.arange(12, dtype=float)[:, None]
    passing = np.stack([np.hstack([t, 0 * t]), np.hstack([t, 0 * t + 0.3])], axis=1)
    starts = np.array([0, 2])
    truth, pred = passing, passing[None]
    plain = evaluate_predictions(pred, truth, starts, passing)
    assert plain["col_pred"] == 0.0 and "col_pred_body" not in plain
    body = evaluate_predictions(pred, truth, starts, passing, contact=0.4)
    assert body["col_pred_body"] == body["col_truth_body"] == 1.0 and body["col_pred"] == 0.0
    windows = Windows(np.zeros((4, 20, 2), np.float32), np.array([0, 2, 4]), contact=0.5)
    turned = augment_scenes(windows, np.random.default_rng(0), "rotate")
    assert windows.subset(np.array([1])).contact == turned.contact == 0.5
    assert Windows.from_state(windows.state_dict()).contact == 0.5
    assert Windows.concat([windows, replace(windows, contact=None)]).contact is None


def test_collisions_are_trajnetpps_own_on_a_fixture():
    """Col-I and Col-II of each scene's primary agent equal what TrajNet++'s own function
    (trajnetplusplustools.metrics.collision) says of the same paths, scene by scene, on scenes
    whose agents pass at 0 to 0.5 m (its 0.2 m threshold, inclusive, and its midpoints)."""
    metrics = pytest.importorskip("trajnetplusplustools.metrics")
    from trajnetplusplustools.data import TrackRow

    from c2inet.metrics import collisions

    def rows(path, agent):
        return [TrackRow(f, agent, float(x), float(y)) for f, (x, y) in enumerate(path, 8)]

    rng = np.random.default_rng(3)
    for _ in range(60):
        agents = int(rng.integers(2, 5))
        t = np.arange(12)[:, None, None]
        start = rng.uniform(-2, 2, (1, agents, 2))
        velocity = rng.normal(0, 0.4, (1, agents, 2))
        point = start + velocity * t + rng.normal(0, 0.05, (12, agents, 2))
        truth = point + rng.normal(0, 0.3, point.shape)
        ours = collisions(point, truth, np.array([0, agents]))
        primary = rows(point[:, 0], 0)
        col_i = any(metrics.collision(primary, rows(point[:, j], j)) for j in range(1, agents))
        col_ii = any(metrics.collision(primary, rows(truth[:, j], j)) for j in range(1, agents))
        assert (ours["col_pred_primary"], ours["col_truth_primary"]) == (col_i, col_ii)
