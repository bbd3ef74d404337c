"""The formats the field exchanges, each on a small fixture written in it: raw Stanford Drone
annotations, TrajNet++ ndjson, and SocialVAE's converted SDD text, through the files family."""

import json
from pathlib import Path

import numpy as np
import pytest

from c2inet.errors import InputError
from sim.domains import build_domain
from sim.generators.files import read_trajectory_file
from sim.generators.formats import trajnet_scenes
from sim.scenario import parse_scenario

SCALE = 0.04  # metres per pixel of the fixture's video


def sdd_annotations(frames: int = 300) -> str:
    """Raw SDD lines at 30 fps: pedestrian 0 walking 1 px a frame east, a biker, and pedestrian
    2 walking north whose box is lost from frame 120 to 179."""
    lines = []
    for f in range(frames):
        lines.append(f'0 {100 + f} 200 {110 + f} 220 {f} 0 0 0 "Pedestrian"')
        lines.append(f'1 {300 + 3 * f} 50 {310 + 3 * f} 70 {f} 0 0 1 "Biker"')
        lost = int(120 <= f < 180)
        lines.append(f'2 400 {500 - f} 410 {520 - f} {f} {lost} 0 0 "Pedestrian"')
    return "\n".join(lines) + "\n"


def test_raw_sdd_keeps_pedestrian_box_centres_at_2_5_fps_in_metres(tmp_path):
    path = tmp_path / "annotations.txt"
    path.write_text(sdd_annotations())
    read = {"format": "sdd", "scale": SCALE, "every": 12}
    with pytest.raises(InputError, match="agent 2 breaks its uniform frame step 12"):
        read_trajectory_file(path, **read)  # the lost boxes leave a gap
    (scene,) = read_trajectory_file(path, split_gaps=True, **read)
    assert scene.num_frames == 25  # frames 0, 12, ..., 288
    assert 1 not in scene.agent_ids  # the biker
    assert sorted(scene.agent_ids.tolist())[:2] == [0, 2] and len(scene.agent_ids) == 3
    walker = scene.positions[:, scene.agent_ids.tolist().index(0)]
    np.testing.assert_allclose(walker[0], [105 * SCALE, 210 * SCALE])
    np.testing.assert_allclose(np.diff(walker, axis=0), [[12 * SCALE, 0]] * 24)  # 1.2 m/s
    second = scene.positions[:, 2]  # pedestrian 2 after the lost boxes: a new track
    assert np.isnan(second[:15]).all() and np.isfinite(second[15:]).all()  # from frame 180


def test_raw_sdd_through_a_family_gives_windows_and_walking_speeds(tmp_path):
    (tmp_path / "video0.txt").write_text(sdd_annotations(600))
    (tmp_path / "sdd_mine.toml").write_text(
        'generator = "files"\n[knobs]\nformat = "sdd"\nevery = 12\nsplit_gaps = true\n'
        '[values.a]\ntrain = ["video0.txt"]\ntest = ["video0.txt"]\nscale = 0.04\n'
    )
    domain = build_domain(parse_scenario("sdd_mine_a", [tmp_path])[0], 0)
    windows = domain.windows("train")
    # pedestrian 0: 50 frames, 31 windows; pedestrian 2: frames 0-108 (10) and 180-588 (35)
    assert len(windows.positions) == 31 + 0 + 16
    assert domain.stats["mean_speed"] == pytest.approx(1.2, rel=1e-6)  # both walk 1.2 m/s


def test_socialvae_sdd_text_is_eth_ucy_columns_with_windows_renamed(tmp_path):
    """SocialVAE's converted SDD: ``frame agent x y`` in metres at frame step 12, an agent
    re-numbered in each 20-frame window; read as ETH-UCY text, every window kept."""
    lines = [
        f"{12 * t + 240 * w} {28 + w:.1f} {40 - 0.6 * (20 * w + t):.6f} 16.0"
        for w in range(2)
        for t in range(20)
    ]
    path = tmp_path / "coupa_0.txt"
    path.write_text("\n".join(lines) + "\n")
    scenes = read_trajectory_file(path)
    assert [s.agent_ids.tolist() for s in scenes] == [[28], [29]]
    assert all(s.num_frames == 20 for s in scenes)
    np.testing.assert_allclose(np.diff(scenes[1].positions[:, 0, 0]), -0.6)


def trajnet_file(tmp_path, lines):
    path = tmp_path / "biwi_hotel.ndjson"
    path.write_text("\n".join(json.dumps(line) for line in lines) + "\n")
    return path


def trajnet_fixture(tmp_path):
    """Agents 1 to 3 at frames 0, 10, ..., 300; two scenes of 21 frames: primaries 2 and 1."""
    tracks = [
        {"track": {"f": 10 * t, "p": p, "x": 0.1 * t + p, "y": -p}}
        for t in range(31)
        for p in (1, 2, 3)
        if not (p == 3 and t > 15)  # agent 3 leaves after frame 150
    ]
    scenes = [
        {"scene": {"id": 0, "p": 2, "s": 0, "e": 200, "fps": 2.5, "tag": 1}},
        {"scene": {"id": 1, "p": 1, "s": 100, "e": 300}},
    ]
    return trajnet_file(tmp_path, scenes + tracks)


def test_trajnetpp_scenes_keep_their_frames_and_their_primary_first(tmp_path):
    first, second = trajnet_scenes(trajnet_fixture(tmp_path))
    assert first.num_frames == second.num_frames == 21
    assert first.agent_ids.tolist() == [2, 1, 3] and second.agent_ids.tolist() == [1, 2, 3]
    np.testing.assert_allclose(first.positions[0, 0], [2.0, -2.0])
    np.testing.assert_allclose(second.positions[20, 0], [4.0, -1.0])  # agent 1 at frame 300
    assert np.isfinite(second.positions[:6, 2]).all() and np.isnan(second.positions[6:, 2]).all()
    thinned, _ = trajnet_scenes(trajnet_fixture(tmp_path), every=20)  # frames 0, 20, ..., 200
    np.testing.assert_array_equal(thinned.positions, first.positions[::2])


def test_trajnetpp_family_windows_every_scene(tmp_path):
    trajnet_fixture(tmp_path)
    (tmp_path / "tnpp.toml").write_text(
        'generator = "files"\n[knobs]\nformat = "trajnetpp"\n'
        '[values.a]\ntrain = ["biwi_hotel.ndjson"]\ntest = ["biwi_hotel.ndjson"]\n'
    )
    domain = build_domain(parse_scenario("tnpp_a", [tmp_path])[0], 0)
    assert len(domain.scenes["train"]) == 2
    assert domain.stats["mean_speed"] == pytest.approx(0.25)  # 0.1 m a frame of 0.4 s


def test_the_builtin_trajnetpp_family_reads_its_groups_from_the_data_root(tmp_path, monkeypatch):
    """trajnetpp_students trains on students001 and tests on students003 of the data root."""
    real = tmp_path / "trajnetpp" / "train" / "real_data"
    real.mkdir(parents=True)
    trajnet_fixture(real).rename(real / "crowds_students001.ndjson")
    trajnet_fixture(real).rename(real / "crowds_students003.ndjson")
    monkeypatch.setenv("C2I_DATA_ROOT", str(tmp_path))
    (spec,) = parse_scenario("trajnetpp_students")
    assert [Path(p).name for p in spec.knobs["test"]] == ["crowds_students003.ndjson"]
    domain = build_domain(spec, 0)
    assert len(domain.scenes["train"]) == len(domain.scenes["test"]) == 2
    assert domain.stats["mean_speed"] == pytest.approx(0.25)


@pytest.mark.parametrize(
    "line, message",
    [
        ("{not json", ":3: not a JSON line"),
        ('{"track": {"f": 0, "p": 1, "x": 1}}', ":3: record lacks the field 'y'"),
        ('{"person": {}}', ":3: expected a 'scene' or a 'track' record"),
        ('{"scene": {"id": 4, "p": 9, "s": 0, "e": 10}}', ":3: scene 4 lacks its agent 9"),
        ('{"track": {"f": 0, "p": 1, "x": NaN, "y": 0}}', ":3: non-finite value"),
        ('{"scene": {"id": 5, "p": 1, "s": 0, "e": 100000000}}', ":3: scene 5 spans frames 0"),
        ('{"scene": {"id": 5, "p": 1, "s": 0, "e": Infinity}}', ":3: .* must be finite integers"),
        ('{"scene": {"id": 5, "p": 1, "s": 0, "e": NaN}}', ":3: .* must be finite integers"),
        ('{"scene": {"id": 5, "p": 1, "s": 0, "e": 1' + "0" * 309 + "}}", ":3: malformed record"),
        ('{"track": {"f": 5, "p": 1, "x": 1e7, "y": 0}}', "a coordinate beyond 1e\\+06 m"),
        ('{"track": {"f": 0, "p": 1, "x": 2, "y": 0}}', "two track rows at one frame"),
        ('{"track": {"f": 5, "p": 1.5, "x": 2, "y": 0}}', "id is not an integer"),
    ],
)
def test_broken_trajnetpp_lines_are_named(tmp_path, line, message):
    path = tmp_path / "t.ndjson"
    path.write_text(
        '{"scene": {"id": 0, "p": 1, "s": 0, "e": 10}}\n'
        '{"track": {"f": 0, "p": 1, "x": 0, "y": 0}}\n' + line + "\n"
        '{"track": {"f": 10, "p": 1, "x": 1, "y": 0}}\n'
    )
    with pytest.raises(InputError, match=message):
        trajnet_scenes(path)


@pytest.mark.parametrize(
    "text, message",
    [
        ('0 1 2 3 4 0 0 0 "Pedestrian"\n', ":1: expected 10 columns"),
        ('0 1 2 3 x 0 0 0 0 "Pedestrian"\n', ":1: non-numeric value"),
        ('0 1 2 3 4 7 0 0 0 "Pedestrian"\n', "no rows left on frames that are multiples of 12"),
    ],
)
def test_broken_sdd_lines_are_named(tmp_path, text, message):
    path = tmp_path / "annotations.txt"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        read_trajectory_file(path, format="sdd", every=12)


def test_unknown_format_is_refused(tmp_path):
    (tmp_path / "bad.toml").write_text(
        'generator = "files"\n[knobs]\nformat = "waymo"\n[values.a]\ntrain = ["x"]\ntest = ["x"]\n'
    )
    with pytest.raises(InputError, match="format 'waymo': expected one of ethucy, sdd, trajnetpp"):
        parse_scenario("bad_a", [tmp_path])


def sdd_root(root: Path, monkeypatch, scales: str | None = None) -> None:
    """A data root whose sdd/ holds seven bookstore videos of annotations (and ``scales``, the
    text of an estimated_scales.yaml), named by $C2I_DATA_ROOT as --data-root would."""
    for video in range(7):
        annotations = root / "sdd" / "annotations" / "bookstore" / f"video{video}"
        annotations.mkdir(parents=True)
        (annotations / "annotations.txt").write_text(sdd_annotations(300))
    if scales is not None:
        (root / "sdd" / "estimated_scales.yaml").write_text(scales)
    monkeypatch.setenv("C2I_DATA_ROOT", str(root))


def test_the_builtin_sdd_px_family_reads_a_location_across_its_videos(tmp_path, monkeypatch):
    """sdd_px (the paper's Table 3 in pixels) in the data root: bookstore trains on videos 0
    to 5 (a wildcard in a folder name) and tests on video 6."""
    sdd_root(tmp_path, monkeypatch)
    (spec,) = parse_scenario("sdd_px_bookstore")
    assert [Path(p).parent.name for p in spec.knobs["train"]] == [f"video{i}" for i in range(6)]
    domain = build_domain(spec, 0)
    assert len(domain.scenes["train"]) == 6 and len(domain.scenes["test"]) == 1
    assert domain.stats["mean_speed"] == pytest.approx(12 / 0.4)  # pixels per second


def test_the_builtin_sdd_family_gives_each_video_its_own_metres(tmp_path, monkeypatch):
    """sdd scales every video by its own entry of the scales file: video v at 0.01 (v + 1) m
    a pixel walks 30 (0.01 (v + 1)) m/s; one missing video is one line naming it."""
    videos = [f"  video{v}:\n    certainty: 1.0\n    scale: {0.01 * (v + 1)}\n" for v in range(7)]
    sdd_root(tmp_path, monkeypatch, "bookstore:\n" + "".join(videos))
    (spec,) = parse_scenario("sdd_bookstore")
    domain = build_domain(spec, 0)
    for v, scene in enumerate(domain.scenes["train"]):
        walker = scene.positions[:, scene.agent_ids.tolist().index(0)]
        np.testing.assert_allclose(np.diff(walker[:, 0]), 12 * 0.01 * (v + 1))
    assert spec.family.unit == "m"
    (tmp_path / "sdd" / "estimated_scales.yaml").write_text("bookstore:\n" + "".join(videos[:6]))
    with pytest.raises(InputError, match="no scale in .* for bookstore video6"):
        parse_scenario("sdd_bookstore")
    (tmp_path / "sdd" / "estimated_scales.yaml").write_text("bookstore: [video0, video1]\n")
    with pytest.raises(InputError, match="no scale in .* for bookstore video0"):
        parse_scenario("sdd_bookstore")  # a location that is a list, not a table
    (tmp_path / "sdd" / "estimated_scales.yaml").write_text("bookstore: [unclosed\n")
    with pytest.raises(InputError, match="cannot read the videos' scales"):
        parse_scenario("sdd_bookstore")


def test_a_dataset_family_without_its_data_says_what_to_download(tmp_path, monkeypatch, capsys):
    from sim.run import main

    monkeypatch.setenv("C2I_DATA_ROOT", "")  # unset, and restored after (main sets it)
    with pytest.raises(InputError, match="reads the Stanford Drone .* from DATA_ROOT/sdd .give"):
        parse_scenario("sdd_px_bookstore")
    argv = ["--scenario", "trajnetpp_students", "--methods", "cv", "--quick", "--no-record"]
    assert main([*argv, "--data-root", str(tmp_path)]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and f"{tmp_path}/trajnetpp" in error and "ndjson" in error
    (tmp_path / "trajnetpp" / "train" / "real_data").mkdir(parents=True)
    assert main([*argv, "--data-root", str(tmp_path)]) == 2
    error = capsys.readouterr().err.strip()
    assert "crowds_students001.ndjson" in error and "releases" in error  # the file, the source
    assert main([*argv, "--data-root", str(tmp_path / "nowhere")]) == 2
    error = capsys.readouterr().err
    assert "--data-root" in error and "not a folder" in error


def test_a_pixel_familys_run_reports_pixels_and_a_mix_of_units_is_refused(
    tmp_path, capsys, monkeypatch
):
    from sim.experiment import ExperimentConfig
    from sim.run import main

    sdd_root(tmp_path, monkeypatch)
    out = tmp_path / "run"
    argv = ["--data-root", str(tmp_path), "--scenario", "sdd_px_bookstore", "--methods", "cv"]
    assert main([*argv, "--quick", "--no-record", "--out", str(out)]) == 0
    assert "ADE/FDE in pixels" in capsys.readouterr().out
    assert "ADE/FDE in pixels" in (out / "report.md").read_text()
    assert "metres" not in (out / "report.md").read_text()
    assert json.loads((out / "metrics.json").read_text())["unit"] == "px"
    with pytest.raises(InputError, match="mixes families in m and px"):
        ExperimentConfig("sdd_px_bookstore+crowd_noise_0.1", ("cv",))


def test_every_that_the_files_frame_step_does_not_divide_is_refused(tmp_path):
    """A file stepping 5 frames with every = 12 keeps frames 60 apart; read as 12 they would
    make every speed five times too high."""
    path = tmp_path / "five.txt"
    path.write_text("".join(f"{5 * t} 1 {0.1 * t} 0\n" for t in range(200)))
    with pytest.raises(InputError, match="every = 12 keeps frames 60 apart"):
        read_trajectory_file(path, every=12)
    assert len(read_trajectory_file(path, every=10)) == 1  # a multiple of 5: kept as it is


def sdd_trajnet_files(folder: Path, metres_per_unit: float = 1.0) -> None:
    """The TrajNet split of SDD in its text form: train/ and test/ files of frame agent x y,
    frames 12 apart (2.5 fps of SDD's 30), three walkers at 1.25 m/s in metres (times
    ``metres_per_unit``'s inverse: pixels at 1/50 m a pixel when it is 0.02)."""
    for split, scene in (("train", "bookstore_0"), ("train", "gates_1"), ("test", "coupa_0")):
        (folder / split).mkdir(parents=True, exist_ok=True)
        unit = metres_per_unit
        rows = [
            f"{12 * t} {agent} {(0.5 * t + 3 * agent) / unit:.4f} {agent / unit}"
            for t in range(30)
            for agent in range(3)
        ]
        (folder / split / f"{scene}.txt").write_text("\n".join(rows) + "\n")


def test_the_sdd_trajnet_family_reads_the_split_papers_use_in_metres(tmp_path, monkeypatch):
    """sdd_trajnet_all trains on train/*.txt and tests on test/*.txt in metres; --data-root
    may name the dataset's own folder; pixels are refused in one line; a folder of the other
    SDD layout is named as such."""
    from sim.run import main

    sdd_trajnet_files(tmp_path / "sdd_trajnet")
    monkeypatch.setenv("C2I_DATA_ROOT", str(tmp_path))
    (spec,) = parse_scenario("sdd_trajnet_all")
    domain = build_domain(spec, 0)
    assert len(domain.scenes["train"]) == 2 and len(domain.scenes["test"]) == 1
    assert domain.stats["mean_speed"] == pytest.approx(1.25)  # 0.5 m a step of 0.4 s
    monkeypatch.setenv("C2I_DATA_ROOT", str(tmp_path / "sdd_trajnet"))  # the folder itself
    (itself,) = parse_scenario("sdd_trajnet_all")
    assert itself.knobs["train"] == spec.knobs["train"]
    out = tmp_path / "run"
    argv = ["--scenario", "sdd_trajnet_all", "--methods", "finetune,cv", "--quick", "--no-record"]
    assert main([*argv, "--data-root", str(tmp_path / "sdd_trajnet"), "--out", str(out)]) == 0
    assert json.loads((out / "metrics.json").read_text())["unit"] == "m"

    pixels = tmp_path / "pixels"
    sdd_trajnet_files(pixels, metres_per_unit=0.02)
    monkeypatch.setenv("C2I_DATA_ROOT", str(pixels))
    with pytest.raises(InputError, match=r"62.5 units/s .* are its coordinates pixels\?"):
        build_domain(parse_scenario("sdd_trajnet_all")[0], 0)

    sdd_root(tmp_path / "raw", monkeypatch)  # raw annotations where the text was expected
    monkeypatch.setenv("C2I_DATA_ROOT", str(tmp_path / "raw" / "sdd"))
    with pytest.raises(InputError, match="holds what family sdd reads"):
        parse_scenario("sdd_trajnet_all")
    monkeypatch.setenv("C2I_DATA_ROOT", str(tmp_path / "sdd_trajnet"))
    with pytest.raises(InputError, match="holds what family sdd_trajnet reads"):
        parse_scenario("sdd_bookstore")


def test_a_recording_whose_people_sprint_is_warned_of(tmp_path, capsys):
    """A files family without ``max_speed`` whose agents move at 62.5 units/s (pixels read as
    metres) builds, with one warning naming the domain and the speed; raw SDD in pixels does not
    warn (it says it is pixels)."""
    sdd_trajnet_files(tmp_path / "px", metres_per_unit=0.02)
    (tmp_path / "fast.toml").write_text(
        'generator = "files"\n[knobs]\nsplit_gaps = true\n'
        '[values.a]\ntrain = ["px/train/*.txt"]\ntest = ["px/test/*.txt"]\n'
    )
    domain = build_domain(parse_scenario("fast_a", [tmp_path])[0], 0)
    assert domain.stats["mean_speed"] == pytest.approx(62.5)
    err = capsys.readouterr().err
    assert err.count("warning: domain fast_a: its agents move at 62.5 units/s") == 1
