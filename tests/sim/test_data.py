"""The data model: windows, splits, the Parquet cache and the exports."""

import contextlib
import io
import json
import subprocess

import numpy as np
import pytest

from c2inet.data import Windows
from sim.data import Scene, cut_windows
from sim.domains import build_domain, domain_hash
from sim.io import read_parquet
from sim.scenario import parse_scenario


def test_windows_keep_only_agents_present_in_all_frames():
    positions = np.arange(25 * 3 * 2, dtype=float).reshape(25, 3, 2)
    positions[3, 1] = np.nan  # agent 1 missing at frame 3
    windows = cut_windows(Scene(positions, np.array([7, 8, 9])), stride=1, min_agents=1)
    assert len(windows) == 6  # starts 0..5
    counts = windows.agents_per_scene
    np.testing.assert_array_equal(counts, [2, 2, 2, 2, 3, 3])
    np.testing.assert_array_equal(windows.positions[0], positions[0:20, 0])
    np.testing.assert_array_equal(windows.positions[-1], positions[5:25, 2])
    assert cut_windows(
        Scene(positions, np.arange(3)), stride=1, min_agents=3
    ).agents_per_scene.tolist() == [3, 3]


def test_windows_subset_and_concat_round_trip():
    w = Windows(np.random.rand(6, 20, 2).astype(np.float32), np.array([0, 2, 3, 6]))
    sub = w.subset(np.array([2, 0]))
    np.testing.assert_array_equal(sub.positions, w.positions[[3, 4, 5, 0, 1]])
    np.testing.assert_array_equal(sub.scene_start, [0, 3, 5])
    both = Windows.concat([w, sub])
    assert len(both) == 5 and both.scene_start[-1] == 11


def test_splits_are_disjoint_and_parquet_round_trips(tmp_path, family_dir):
    (spec,) = parse_scenario("tiny_noise_0.2", [family_dir])
    domain = build_domain(spec, 0, cache_dir=tmp_path)
    assert [len(domain.scenes[s]) for s in ("train", "val", "test")] == [6, 2, 3]
    firsts = [s.positions[0].tobytes() for split in domain.scenes.values() for s in split]
    assert len(set(firsts)) == len(firsts)  # every scene is its own simulation
    (cached,) = tmp_path.glob("*.parquet")
    again = read_parquet(cached)
    assert again.stats == domain.stats and again.hash == domain.hash
    for split in ("train", "val", "test"):
        for a, b in zip(domain.scenes[split], again.scenes[split], strict=True):
            np.testing.assert_array_equal(a.positions, b.positions)
    assert build_domain(spec, 0, cache_dir=tmp_path).hash == domain.hash  # read from the cache


def test_hash_changes_with_knobs_seed_and_sizes(family_dir):
    a, b = parse_scenario("tiny_noise_0.1,0.2", [family_dir])
    assert domain_hash(a, 0) != domain_hash(b, 0)
    assert domain_hash(a, 0) != domain_hash(a, 1)
    assert domain_hash(a, 0) == domain_hash(parse_scenario("tiny_noise_0.1", [family_dir])[0], 0)


def run_generate(*args: str) -> subprocess.CompletedProcess:
    """``python -m sim.generate ARGS``, run in this process (its imports paid once)."""
    from sim.generate import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(args))
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def test_generate_takes_data_settings_and_refuses_other_scopes(tmp_path, family_dir):
    common = ["--scenario", "tiny_noise_0.1", "--scenarios-dir", str(family_dir)]
    done = run_generate(*common, "--out", str(tmp_path / "a"), "--set", "data.agents=5")
    assert done.returncode == 0, done.stderr
    (domain,) = json.loads((tmp_path / "a" / "summary.json").read_text())["domains"]
    assert domain["knobs"]["agents"] == 5
    done = run_generate(*common, "--out", str(tmp_path / "b"), "--set", "train.lr=0.1")
    assert done.returncode == 2 and "generate takes only data.KNOB" in done.stderr


def test_generate_reads_a_config_files_data_settings_as_run_does(tmp_path):
    """Issue 64's case: a file with ``agents = 3`` and small splits under ``[settings.data]``
    generates 3 agents and those splits (it had generated 10 and 300/50/100); the flags win
    over the file, and its learner's scopes are named as not generate's."""
    config = tmp_path / "gen.toml"
    config.write_text(
        'scenario = "crowd_noise_0.1"\n[settings.data]\nagents = 3\n"splits.train" = 4\n'
        '"splits.val" = 2\n"splits.test" = 3\n[settings.train]\nlr = 0.001\n'
    )
    done = run_generate("--config", str(config), "--out", str(tmp_path / "a"))
    assert done.returncode == 0, done.stderr
    (domain,) = json.loads((tmp_path / "a" / "summary.json").read_text())["domains"]
    assert domain["knobs"]["agents"] == 3
    assert domain["splits"] == {"train": 4, "val": 2, "test": 3}
    assert "generate takes its data settings, not train" in done.stderr
    out = str(tmp_path / "b")
    done = run_generate("--config", str(config), "--out", out, "--set", "data.agents=4")
    (domain,) = json.loads((tmp_path / "b" / "summary.json").read_text())["domains"]
    assert domain["knobs"]["agents"] == 4 and domain["splits"]["train"] == 4


@pytest.mark.parametrize("fmt", ["parquet", "npz"])
def test_generate_never_overwrites_silently_and_replaces_only_its_own_files(
    tmp_path, family_dir, fmt, capsys
):
    from sim.generate import main

    out = tmp_path / "out"
    common = ["--scenarios-dir", str(family_dir), "--out", str(out), "--format", fmt]
    assert main(["--scenario", "tiny_noise_0.1,0.2", *common]) == 0
    (out / "notes.txt").write_text("mine")
    assert main(["--scenario", "tiny_noise_0.3", *common]) == 2
    assert "not empty; add --overwrite" in capsys.readouterr().err
    assert main(["--scenario", "tiny_noise_0.3", *common, "--overwrite"]) == 0
    left = sorted(p.name for p in out.iterdir())
    assert left == sorted(
        [
            ".c2i-generated.json",
            "notes.txt",
            "summary.json",
            "tiny_noise_0.3" + (".parquet" if fmt == "parquet" else ""),
        ]
    )
    # a summary naming a user's folder as a domain deletes nothing: only the marker's files go,
    # each only while its bytes are the ones written
    (out / "src").mkdir()
    (out / "src" / "code.py").write_text("mine")
    (out / "summary.json").write_text('{"format": "npz", "domains": [{"name": "src"}]}')
    assert main(["--scenario", "tiny_noise_0.3", *common, "--overwrite"]) == 0
    assert (out / "src" / "code.py").read_text() == "mine"
    assert (out / "summary.json").is_file()  # edited by a user: kept, then written anew
    (out / ".c2i-generated.json").write_text('{"files": {"../outside": "x", "src/code.py": "0"}}')
    assert main(["--scenario", "tiny_noise_0.3", *common, "--overwrite"]) == 0
    assert (out / "src" / "code.py").read_text() == "mine"
    (out / ".c2i-generated.json").unlink()
    assert main(["--scenario", "tiny_noise_0.3", *common, "--overwrite"]) == 2
    assert "holds no output of sim.generate" in capsys.readouterr().err
    assert (out / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("fmt", ["parquet", "ethucy", "npz"])
def test_generate_is_byte_identical_for_a_seed_and_differs_for_another(tmp_path, family_dir, fmt):
    outs = []
    for name, seed in (("a", "1"), ("b", "1"), ("c", "2")):
        result = run_generate(
            "--scenario",
            "tiny_noise_0.1,0.4",
            "--scenarios-dir",
            str(family_dir),
            "--out",
            str(tmp_path / name),
            "--format",
            fmt,
            "--seed",
            seed,
        )
        assert result.returncode == 0, result.stderr
        outs.append(
            {
                p.relative_to(tmp_path / name): p.read_bytes()
                for p in (tmp_path / name).rglob("*")
                if p.is_file()
            }
        )
    assert outs[0] == outs[1]
    assert outs[0].keys() == outs[2].keys()
    data_files = [k for k in outs[0] if k.name != "summary.json"]
    assert data_files and all(outs[0][k] != outs[2][k] for k in data_files)


def test_summary_json_contract(tmp_path, family_dir):
    result = run_generate(
        "--scenario",
        "tiny_noise_0.1..0.3",
        "--scenarios-dir",
        str(family_dir),
        "--out",
        str(tmp_path / "out"),
    )
    assert result.returncode == 0, result.stderr
    assert "tiny_noise_0.3" in result.stdout and "heading_change" in result.stdout
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["scenario"] == "tiny_noise_0.1..0.3" and summary["seed"] == 0
    assert [d["name"] for d in summary["domains"]] == [
        "tiny_noise_0.1",
        "tiny_noise_0.2",
        "tiny_noise_0.3",
    ]
    for domain in summary["domains"]:
        assert domain["family"] == "tiny_noise" and domain["splits"] == {
            "train": 6,
            "val": 2,
            "test": 3,
        }
        assert set(domain["stats"]) >= {
            "mean_speed",
            "min_separation",
            "heading_change",
            "density",
            "overlaps",
        }
        assert isinstance(domain["stats"]["overlaps"], int) and len(domain["hash"]) == 16
        assert domain["knobs"]["agents"] == 6


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "crowd_noise_0.6..0.1", "--out", "x"], "reversed"),
        (["--scenario", "nope_1", "--out", "x"], "unknown family"),
        (["--scenario", "crowd_noise_0.1", "--out", "x", "--format", "csv"], "invalid choice"),
        (["--scenario", "crowd_noise_0.1"], "--out"),
    ],
)
def test_bad_input_gives_one_error_line_and_exit_2(tmp_path, args, message):
    result = run_generate(*args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0]
    assert not (tmp_path / "x").exists()


def test_npz_export_has_the_papers_layout(tmp_path):
    result = run_generate(
        "--scenario", "crowd_radius_0.3", "--out", str(tmp_path), "--format", "npz"
    )
    assert result.returncode == 0, result.stderr
    raw = np.load(tmp_path / "crowd_radius_0.3" / "test.npz", allow_pickle=False)["raw"]
    assert raw.shape == (100, 2, 20, 2) and raw.dtype == np.float64


def test_a_damaged_cache_entry_is_never_used(family_dir, tmp_path, capsys):
    """Single-bit flips anywhere in a cached domain: each is detected (the domain is generated
    again, with a warning) or harmless; none is read as different data."""
    (spec,) = parse_scenario("tiny_noise_0.2", [family_dir])
    cache = tmp_path / "cache"
    original = build_domain(spec, 0, cache)
    (entry,) = cache.glob("*.parquet")
    intact = entry.read_bytes()
    rng = np.random.default_rng(0)
    warned = 0
    for bit in rng.choice(len(intact) * 8, 40, replace=False):
        damaged = bytearray(intact)
        damaged[bit // 8] ^= 1 << (bit % 8)
        entry.write_bytes(bytes(damaged))
        domain = build_domain(spec, 0, cache)
        for split in ("train", "test"):
            for a, b in zip(domain.scenes[split], original.scenes[split], strict=True):
                np.testing.assert_array_equal(a.positions, b.positions)
        if "generating it again" in capsys.readouterr().err:
            warned += 1
            assert entry.read_bytes() == intact  # made again, byte for byte
    assert warned >= 30  # most flips hit the data or its description
    entry.write_bytes(intact[: len(intact) // 2])  # truncated
    build_domain(spec, 0, cache)
    assert "generating it again" in capsys.readouterr().err


def test_proximity_statistics_agree_all_pairs_at_once_and_by_k_d_tree(monkeypatch):
    """The fast path (all pairs of all frames) gives the k-d tree's numbers, absences included."""
    import sim.stats as stats

    rng = np.random.default_rng(0)
    scenes = []
    for agents in (1, 2, 7, 30):
        positions = rng.uniform(0, 4, (25, agents, 2))
        positions[rng.random((25, agents)) < 0.2] = np.nan  # absent agents
        scenes.append(Scene(positions, np.arange(agents)))
    fast = stats.proximity_stats(scenes, contact=0.3)
    monkeypatch.setattr(stats, "DENSE_AGENTS", 0)
    assert stats.proximity_stats(scenes, contact=0.3) == fast and fast["overlaps"] > 0
