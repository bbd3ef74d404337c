"""Real data through the files generator: parsing, validation errors, the vendored ETH-UCY."""

import hashlib
import os
from pathlib import Path

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.domains import build_domain
from sim.families import SCENARIOS_DIR
from sim.generators import files
from sim.generators.files import read_trajectory_file
from sim.scenario import parse_scenario

DATA = SCENARIOS_DIR / "data"


def write(tmp_path, text, name="t.txt"):
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


def test_reads_tabs_spaces_crlf_and_float_frames(tmp_path):
    path = write(tmp_path, "10.0\t1\t0.0\t1.0\r\n20 1 0.5 1.0\r\n20.0  2  3.0 4.0\r\n\r\n")
    (scene,) = read_trajectory_file(path)
    assert scene.positions.shape == (2, 2, 2)
    np.testing.assert_array_equal(scene.agent_ids, [1, 2])
    np.testing.assert_array_equal(scene.positions[:, 0], [[0.0, 1.0], [0.5, 1.0]])
    assert np.isnan(scene.positions[0, 1]).all() and np.array_equal(
        scene.positions[1, 1], [3.0, 4.0]
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("10 1 0 0\n20 1 0\n", ":2: expected 4 columns"),
        ("10 1 0 0\n20 1 x 0\n", ":2: non-numeric"),
        ("10 1 0 0\n20 1 nan 0\n", ":2: non-finite"),
        ("10 1 0 0\n20 1 0 0\n40 1 0 0\n", ":3: agent 1 breaks its uniform frame step"),
        ("10 1 0 0\n10 1 1 1\n", "breaks its uniform frame step"),
        ("", "no trajectory rows"),
        ("10 1 1e308 0\n20 1 0 0\n", ":1: coordinate beyond 1e\\+06 m"),
        ("10 1.5 0 0\n10 1.7 1 1\n", ":1: agent id '1.5' is not a whole number"),
        (
            "10 1 0 0\n20 1 x" + "y" * 500 + " 0\n",
            r":2: non-numeric value in .*\(5\d\d characters\)",
        ),
    ],
)
def test_broken_files_name_the_file_and_line(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=message) as error:
        read_trajectory_file(path)
    assert str(path) in str(error.value)


def test_vendored_data_matches_its_checksums():
    for line in (DATA / "SHA256SUMS").read_text().splitlines():
        digest, name = line.split(maxsplit=1)
        assert hashlib.sha256((DATA / name).read_bytes()).hexdigest() == digest, name


def test_eth_ucy_tasks_train_on_train_files_and_test_on_val_files():
    (spec,) = parse_scenario("eth_ucy_eth")
    domain = build_domain(spec, root_seed=0)
    counts = [len(domain.scenes[s]) for s in ("train", "val", "test")]
    assert counts[0] >= 1 and counts[1] == 0 and counts[2] >= 1  # a scene per group of tracks
    train, test = domain.windows("train", min_agents=2), domain.windows("test", min_agents=2)
    assert len(train) >= 40 and len(test) >= 30
    # biwi_eth: train frames end before val frames start, so no window is in both
    frames = {s: sum(x.num_frames for x in domain.scenes[s]) for s in ("train", "test")}
    assert frames["train"] > frames["test"]
    assert 0.5 < domain.stats["mean_speed"] < 4.0  # the known fast ETH time base, in m/s


@pytest.mark.parametrize("kind", ["folder", "fifo", "device"])
def test_file_patterns_match_regular_files_only(tmp_path, kind):
    """A folder cannot be read, a FIFO blocks forever, /dev/zero never ends."""
    target = {"folder": tmp_path / "scene.txt", "fifo": tmp_path / "scene.txt"}.get(kind)
    if kind == "folder":
        target.mkdir()
    elif kind == "fifo":
        os.mkfifo(target)
    pattern = str(target) if target else "/dev/zero"
    (tmp_path / "mine.toml").write_text(
        f'generator = "files"\n[values.a]\ntrain = ["{pattern}"]\ntest = ["{pattern}"]\n'
    )
    with pytest.raises(InputError, match="no regular file"):
        build_domain(parse_scenario("mine_a", [tmp_path])[0], 0)


def test_leave_one_out_never_trains_on_the_held_out_recordings():
    """sgan's protocol: each held-out scene's recordings appear in its test split alone."""
    for spec in parse_scenario("eth_ucy_loo_eth,hotel,univ,zara1,zara2"):
        files = {split: spec.knobs[split] for split in ("train", "val", "test")}
        held_out = {Path(p).stem for p in files["test"]}
        seen = {Path(p).stem.rsplit("_", 1)[0] for split in ("train", "val") for p in files[split]}
        assert held_out and not held_out & seen, spec.name


def blocks(scenes: int, agents: int = 2, frames: int = 20, spacing: int = 1000) -> str:
    """A file of ``scenes`` recordings, each its own block of frame ids."""
    rng = np.random.default_rng(0)
    lines = []
    for scene in range(scenes):
        for a in range(agents):
            start, velocity = rng.uniform(-5, 5, 2), rng.normal(0, 0.4, 2)
            for t in range(frames):
                x, y = start + velocity * t
                lines.append(f"{scene * spacing + 10 * t} {agents * scene + a} {x:.3f} {y:.3f}")
    return "\n".join(lines) + "\n"


def test_tracks_stay_sparse_a_scene_per_block(tmp_path):
    """500 two-agent recordings in one file: 500 small scenes, not one of every frame by every
    agent id (which for 5,000 asked for 69 GiB)."""
    scenes = read_trajectory_file(write(tmp_path, blocks(500)))
    assert len(scenes) == 500 and all(s.positions.shape == (20, 2, 2) for s in scenes)
    far = read_trajectory_file(write(tmp_path, "0 1 0 0\n10 1 0.4 0\n10000000 2 1 1\n"))
    assert [s.positions.shape for s in far] == [(2, 1, 2), (1, 1, 2)]  # a million frames apart


def test_long_scenes_are_cut_in_time_without_losing_or_doubling_a_window(tmp_path, monkeypatch):
    import sim.generators.files as files
    from c2inet.data import Windows
    from sim.data import cut_windows

    path = write(tmp_path, blocks(1, agents=6, frames=300))
    (whole,) = read_trajectory_file(path)
    monkeypatch.setattr(files, "MAX_CELLS", 6 * 90)
    pieces = read_trajectory_file(path)
    assert len(pieces) > 3 and max(p.num_frames for p in pieces) <= 90
    cut = Windows.concat([w for w in map(cut_windows, pieces) if w is not None])
    reference = cut_windows(whole)
    np.testing.assert_array_equal(cut.positions, reference.positions)
    np.testing.assert_array_equal(cut.scene_start, reference.scene_start)


def test_a_track_with_a_gap_is_an_error_or_two_tracks(tmp_path):
    text = "0 7 0 0\n10 7 1 0\n40 7 4 0\n50 7 5 0\n0 8 0 1\n10 8 1 1\n"
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=":3: agent 7 breaks .* split_gaps = true"):
        read_trajectory_file(path)
    first, later = read_trajectory_file(path, split_gaps=True)
    assert first.agent_ids.tolist() == [7, 8] and later.agent_ids.tolist() == [9]  # a new id
    np.testing.assert_array_equal(later.positions[:, 0], [[4, 0], [5, 0]])


def test_a_file_is_read_in_chunks_that_keep_its_line_numbers(tmp_path, monkeypatch):
    """Chunks of three lines: blank lines and a chunk of blanks only are counted, and an error
    in a later chunk names its own line."""
    monkeypatch.setattr(files, "CHUNK_LINES", 3)
    rows = [f"{10 * t} 1 {0.1 * t:.1f} 0\n" for t in range(8)]
    text = "".join(rows[:3]) + "\n\n\n\n" + "".join(rows[3:])
    (scene,) = read_trajectory_file(write(tmp_path, text))
    assert scene.positions.shape == (8, 1, 2)
    whole = files._rows(write(tmp_path, text, "a.txt"))
    assert whole[:, 4].tolist() == [1, 2, 3, 8, 9, 10, 11, 12]  # lines 4 to 7 are blank
    with pytest.raises(InputError, match=r"t.txt:11: non-numeric"):
        read_trajectory_file(write(tmp_path, text.replace("60 1 0.6", "60 1 x")))


def test_the_memory_budget_covers_recorded_files(tmp_path):
    (tmp_path / "scene.txt").write_text("".join(f"{t} 1 {t} 0\n" for t in range(40)))
    (tmp_path / "mine.toml").write_text(
        'generator = "files"\n[values.a]\ntrain = ["scene.txt"]\ntest = ["scene.txt"]\n'
    )
    spec = parse_scenario("mine_a", [tmp_path])[0]
    with pytest.raises(InputError, match=r"domain mine_a: generating it needs about .* memory"):
        build_domain(spec, 0, memory_budget=1e-6)  # a kilobyte
    assert build_domain(spec, 0, memory_budget=1.0).scenes["train"]
