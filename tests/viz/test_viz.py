"""The Rerun recording and figures of a --quick run, live streaming, and the web viewer server."""

import contextlib
import importlib.util
import io
import os
import shutil
import subprocess
import sys
import time
import urllib.request
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from sim.experiment.curriculum import SAMPLE_SCENES
from sim.run import main
from viz.blueprint import curve_views, extent, scale_bar
from viz.colours import faint, method_colour, task_shade
from viz.serve import command, free_port, launch, stop, wait_for_port

RERUN = str(Path(sys.executable).with_name("rerun"))
TASKS = ("crowd_noise_0.1", "crowd_noise_0.2")


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    """Rerun's CLI writes analytics settings under the config folder: keep them in a temp dir."""
    return {**os.environ, "XDG_CONFIG_HOME": str(tmp_path_factory.mktemp("xdg"))}


def quick_run(out: Path, *extra: str) -> subprocess.CompletedProcess:
    """A quick run of ``python -m sim.run``, in this process: its exit code and output."""
    argv = ["--scenario", "crowd_noise_0.1,0.2", "--quick", "--out", str(out)]
    argv += ["--methods", "c2inet-online,finetune,cv", "--cache", str(out.parent / "cache")]
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main([*argv, *extra])
    return subprocess.CompletedProcess(argv, code, stdout.getvalue(), stderr.getvalue())


def rows_per_entity(path: Path) -> Counter:
    rows: Counter = Counter()
    for chunk in RrdReader(str(path)).stream():
        rows[chunk.entity_path] += chunk.num_rows
    return rows


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    result = quick_run(out)
    assert result.returncode == 0, result.stderr
    return out


def test_recording_holds_scenes_rollouts_curves_and_queue(recorded):
    rows = rows_per_entity(recorded / "recording.rrd")
    for task in TASKS:
        assert rows[f"/tasks/{task}"] == 1  # knobs and statistics as properties
        for k in range(SAMPLE_SCENES):
            scene = f"/tasks/{task}/scenes/{k}"
            assert rows[f"{scene}/truth/agents"] == 20  # one batched row per frame
            assert rows[f"{scene}/truth/history"] == 1 and rows[f"{scene}/truth/future"] == 1
            for method in ("c2inet-online", "finetune", "cv"):
                assert rows[f"{scene}/{method}/predictions"] == 2  # one per checkpoint (task)
                assert rows[f"{scene}/{method}/best"] == 2
        assert rows[f"/rollouts/{task}/truth/agents"] == 50
        # 31 windows per checkpoint, and the method's colour (static)
        assert rows[f"/rollouts/{task}/finetune/predictions"] == 2 * 31 + 1
    # per series: a row per point, and the method's colour (static)
    assert rows["/curves/finetune/val_ade/crowd_noise_0.1"] == 4 + 1  # 2 epochs x 2 tasks
    assert rows["/curves/finetune/val_ade/crowd_noise_0.2"] == 2 + 1
    assert rows["/curves/finetune/matrix/ade/crowd_noise_0.2"] == 2 + 1
    for rule in ("c_prior", "c_responsible"):  # the other test-time rules for C, beside
        assert rows[f"/curves/c2inet-online/matrix/ade_{rule}/crowd_noise_0.2"] == 2 + 1
    assert not any("/finetune/matrix/ade_c_" in path for path in rows)
    assert rows["/curves/c2inet-online/kl_c"] == 4 + 1
    assert rows["/queue/c2inet-online/components"] == 2
    # the confounder's diagnostics, one row per task; the baselines' have no C part
    assert rows["/diagnostics/c2inet-online/mi_xc"] == 2 + 1
    assert rows["/diagnostics/c2inet-online/c_effect"] == 2 + 1
    assert rows["/diagnostics/finetune/probe_context"] == 1 + 1  # None after the first task
    assert "/diagnostics/finetune/mi_xc" not in rows
    assert rows["/run_card"] == 1
    assert not any("/cv/" in path and "val_ade" in path for path in rows)  # cv does not train


def chunks_of(path: Path, entity: str) -> list:
    return [c for c in RrdReader(str(path)).stream() if c.entity_path == entity]


def test_each_method_has_its_own_colour_and_the_legend_names_them(recorded):
    path, seen = recorded / "recording.rrd", {}
    for index, method in enumerate(("c2inet-online", "finetune", "cv")):
        chunks = chunks_of(path, f"/tasks/{TASKS[0]}/scenes/0/{method}/best")
        packed = {
            int(v)
            for c in chunks
            for v in c.to_record_batch().column("LineStrips2D:colors").flatten().to_pylist()
        }
        red, green, blue = method_colour(index)
        assert packed == {(red << 24) | (green << 16) | (blue << 8) | 255}, method
        # drawn on the epoch timeline too, where the viewer opens with the curves
        assert all("epoch" in c.timeline_names for c in chunks if not c.is_static)
        seen[method] = packed
    assert len({min(v) for v in seen.values()}) == 3
    (legend,) = chunks_of(path, "/legend")
    text = str(legend.to_record_batch().column("TextDocument:text").to_pylist())
    assert all(m in text for m in seen) and "blue" in text


def test_every_curve_view_shows_recorded_curves_of_every_method(recorded):
    entities = set(rows_per_entity(recorded / "recording.rrd"))
    methods = ["c2inet-online", "finetune", "cv"]
    for name, filters in curve_views(methods):
        for method in ("c2inet-online", "finetune"):  # the methods that train
            mine = [f for f in filters if f.startswith(f"/curves/{method}/")]
            shown = {
                e
                for e in entities
                for f in mine
                if e == f or (f.endswith("/**") and e.startswith(f.removesuffix("**")))
            }
            assert shown, f"the {name!r} view shows nothing of {method}"


def values(path: Path, entity: str, column: str) -> list:
    """Every value of one component of an entity, flattened over the rows that have it."""
    batches = [c.to_record_batch() for c in chunks_of(path, entity)]
    return [
        v
        for b in batches
        if column in b.schema.names
        for v in b.column(column).flatten().to_pylist()
    ]


def packed(rgb) -> int:
    return (rgb[0] << 24) | (rgb[1] << 16) | (rgb[2] << 8) | 255


def test_truth_is_drawn_above_the_best_of_k_above_pale_thin_samples(recorded):
    path, scene = recorded / "recording.rrd", f"/tasks/{TASKS[0]}/scenes/0"
    order = {
        part: set(values(path, f"{scene}/{part}", "LineStrips2D:draw_order"))
        for part in ("truth/future", "truth/history", "finetune/best", "finetune/predictions")
    }
    assert order["truth/future"] == order["truth/history"] == {30.0}
    assert order["finetune/best"] == {20.0} and order["finetune/predictions"] == {10.0}
    pale = set(values(path, f"{scene}/finetune/predictions", "LineStrips2D:colors"))
    assert pale == {packed(faint(method_colour(1)))}
    assert all(r < 0 for r in values(path, f"{scene}/finetune/predictions", "LineStrips2D:radii"))


def test_rollout_truth_is_on_every_timeline_and_task_curves_have_their_own_shades(recorded):
    path = recorded / "recording.rrd"
    for task in TASKS:
        (paths,) = chunks_of(path, f"/rollouts/{task}/truth/paths")
        strips = paths.to_record_batch().column("LineStrips2D:strips")[0].as_py()
        assert paths.is_static and len(strips) >= 2 and all(len(s) >= 2 for s in strips)
    shades = [
        values(path, f"/curves/finetune/val_ade/{task}", "SeriesLines:colors") for task in TASKS
    ]
    assert shades == [[packed(task_shade(method_colour(1), i, 2))] for i in range(2)]
    assert shades[0] != shades[1]


def test_every_scene_and_rollout_view_opens_framed_on_its_truth(recorded):
    reader = RrdReader(str(recorded / "recording.rrd"))
    views = [
        c.to_record_batch().column("VisualBounds2D:range").to_pylist()[0][0]
        for c in reader.stream(store=reader.blueprints()[0])
        if c.entity_path.endswith("/VisualBounds2D")
    ]
    assert len(views) == len(TASKS) * (SAMPLE_SCENES + 1)  # the sample scenes and a rollout
    blueprint = list(reader.stream(store=reader.blueprints()[0]))
    legends = [
        c.to_record_batch().column("PlotLegend:visible").to_pylist()[0][0]
        for c in blueprint
        if c.entity_path.endswith("/PlotLegend")
    ]
    assert legends == [False] * len(curve_views(["m"]))  # none drawn over the curves
    columns = [
        c.to_record_batch().column("ContainerBlueprint:grid_columns").to_pylist()[0][0]
        for c in blueprint
        if "ContainerBlueprint:grid_columns" in c.to_record_batch().schema.names
    ]
    assert columns.count(3) == len(TASKS)  # each task's six panels in a 3 x 2 grid
    points = np.array([[0.0, 0.0], [4.0, 1.0], [np.nan, np.nan]])
    x0, x1, y0, y1 = extent(points, margin=0.25)
    assert (x0, x1) == (-1.0, 5.0) and (y0, y1) == (-2.5, 3.5)  # square, 0.25 of 4 m a side
    assert extent(np.full((3, 2), np.nan)) == (-1.0, 1.0, -1.0, 1.0)  # nothing to frame


def test_every_framed_view_has_a_scale_bar_in_metres(recorded):
    path = recorded / "recording.rrd"
    origins = [f"/tasks/{t}/scenes/{k}" for t in TASKS for k in range(SAMPLE_SCENES)]
    for origin in origins + [f"/rollouts/{t}" for t in TASKS]:
        (bar,) = chunks_of(path, f"{origin}/scale")
        batch = bar.to_record_batch()
        (label,) = batch.column("LineStrips2D:labels")[0].as_py()
        (strip,) = batch.column("LineStrips2D:strips")[0].as_py()
        length = float(label.removesuffix(" m"))
        assert bar.is_static and abs(strip[2][0] - strip[1][0] - length) < 1e-5
    length, corners = scale_bar((0.0, 7.0, -1.0, 6.0))
    assert length == 1.0 and corners[2, 0] - corners[1, 0] == 1.0  # round, under a quarter
    assert scale_bar((0.0, 30.0, 0.0, 30.0))[0] == 5.0
    assert scale_bar((0.0, 0.5, 0.0, 0.5))[0] == 0.1


def test_recording_verifies_and_stays_small(recorded, env):
    result = subprocess.run(
        [RERUN, "rrd", "verify", str(recorded / "recording.rrd")],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert (recorded / "recording.rrd").stat().st_size < 50e6


def test_figures_are_written(recorded):
    names = sorted(p.name for p in (recorded / "figures").iterdir())
    assert names == sorted(
        [
            "average_seen.png",
            "predictions.png",
            *(
                f"{kind}_{m}.png"
                for kind in ("matrix", "per_task")
                for m in ("c2inet-online", "cv", "finetune")
            ),
        ]
    )
    for path in (recorded / "figures").iterdir():
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_live_stream_reaches_a_local_viewer_server(tmp_path, env):
    port = free_port()
    saved = tmp_path / "live.rrd"
    server = launch(
        [RERUN, "--bind", "127.0.0.1", "--port", str(port), "--save", str(saved)],
        env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        assert wait_for_port(port)
        result = quick_run(
            tmp_path / "run",
            "--no-record",
            "--rerun",
            f"connect=rerun+http://127.0.0.1:{port}/proxy",
        )
        assert result.returncode == 0, result.stderr
        time.sleep(1.0)
    finally:
        stop(server)
    assert not wait_for_port(port, 1.0)  # the server and its binary are gone
    assert not (tmp_path / "run" / "recording.rrd").exists()
    rows = rows_per_entity(saved)
    assert rows["/tasks/crowd_noise_0.2/scenes/0/finetune/predictions"] == 2
    assert rows["/curves/finetune/val_ade/crowd_noise_0.1"] == 4 + 1  # and its colour


def test_web_viewer_serves_on_loopback_only(recorded, env):
    cmd = command(recorded / "recording.rrd", free_port(), free_port())
    assert cmd[cmd.index("--bind") + 1] == "127.0.0.1"
    web_port = int(cmd[cmd.index("--web-viewer-port") + 1])
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "viz.serve",
            str(recorded / "recording.rrd"),
            "--web-port",
            str(web_port),
            "--grpc-port",
            cmd[cmd.index("--port") + 1],
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        line = server.stdout.readline()
        assert f"http://127.0.0.1:{web_port}/" in line
        page = None
        for _ in range(150):
            try:
                page = urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=1).read()
                break
            except OSError:
                time.sleep(0.2)
        assert page and b"<html" in page.lower()
    finally:
        server.terminate()  # viz.serve ends its viewer server on SIGTERM
        server.wait(timeout=20)
    assert not wait_for_port(web_port, 1.0)


def test_bad_rerun_option_is_rejected(tmp_path):
    result = quick_run(tmp_path, "--rerun", "broadcast")
    assert result.returncode == 2 and "--rerun" in result.stderr


@pytest.mark.skipif(
    shutil.which("chromium") is None or importlib.util.find_spec("playwright") is None,
    reason="needs Debian's chromium and pip install '.[screenshot]' (Playwright)",
)
def test_headless_chromium_renders_the_web_viewer(recorded, tmp_path):
    from matplotlib.image import imread

    from viz.screenshot import screenshot

    # a small viewport: SwiftShader draws each frame in software, 1600 by 900 took 58 s
    image = imread(screenshot(recorded / "recording.rrd", tmp_path / "viewer.png", "800,450"))
    assert image.shape[:2] == (450, 800)
    # a rendered viewer has panels, text and trajectories, not one background colour
    assert len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > 500  # blank: < 10


def test_every_registered_method_gets_a_colour_of_its_own():
    """``--methods all`` draws each method in its own colour, named in the legend."""
    from c2inet.methods.base import discover
    from viz.colours import colour_name, legend_markdown

    methods = sorted(discover())
    colours = {method_colour(i) for i in range(len(methods))}
    names = {colour_name(i) for i in range(len(methods))}
    assert len(colours) == len(names) == len(methods)
    assert all(c not in colours for c in ((150, 150, 150), (40, 170, 60)))  # truth's colours
    assert legend_markdown(methods).count("**") == 2 * len(methods)


def test_a_figure_drawn_inside_labelled_carries_the_note_and_one_outside_does_not(tmp_path):
    """Quick sizes are marked on the figure itself, so a figure passed on alone still says so."""
    from matplotlib.image import imread

    from viz import figures

    methods = {"finetune": {"avg_seen_ade": [0.2, 0.3], "avg_seen_ade_std": [0.0, 0.0]}}
    plain = figures.average_seen(methods, ["a", "b"], tmp_path / "plain.png")
    with figures.labelled("quick sizes: a smoke test, not a result"):
        noted = figures.average_seen(methods, ["a", "b"], tmp_path / "noted.png")
    red = [
        (img[..., 0] > 0.6) & (img[..., 1] < 0.8) & (img[..., 2] < 0.8)
        for img in (imread(plain), imread(noted))
    ]
    assert red[1].sum() > red[0].sum() + 500  # the note's red letters


def test_a_scripts_bad_input_is_one_line_and_exit_2(capsys, monkeypatch):
    """``viz.cli.run_script``, the entry of every script under scripts/ and benchmarks/: a
    missing file, a value it cannot read or an InputError is one ``error:`` line and exit 2;
    ``C2I_TRACEBACK=1`` lets the traceback through."""
    from c2inet.errors import InputError
    from viz.cli import run_script

    def missing():
        return open("/nonexistent/board/results.parquet")

    def bad_value():
        raise InputError("--seeds 0: expected 1 to 64")

    assert run_script(missing) == 2 and run_script(bad_value) == 2
    assert run_script(lambda: None) == 0 and run_script(lambda: 3) == 3
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "error: FileNotFoundError: [Errno 2] No such file or directory: "
        "'/nonexistent/board/results.parquet'",
        "error: --seeds 0: expected 1 to 64",
    ]
    monkeypatch.setenv("C2I_TRACEBACK", "1")
    with pytest.raises(FileNotFoundError):
        run_script(missing)
