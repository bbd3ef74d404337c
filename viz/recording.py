"""A run as a Rerun recording: a thin mapping from windows, predictions and metrics to archetypes.

Timelines: ``frame`` (positions within a scene or rollout), ``task`` (the task the model has
trained through, so scrubbing it shows old tasks degrade or hold) and ``epoch`` (training curves,
counted across the whole curriculum). Entity paths:

- ``/run_card`` (TextDocument), ``/tasks/<task>`` (domain knobs and statistics as properties)
- ``/tasks/<task>/scenes/<k>/truth/{agents,history,future}`` and
  ``/tasks/<task>/scenes/<k>/<method>/{predictions,best}``
- ``/rollouts/<task>/truth/agents`` and ``/rollouts/<task>/<method>/predictions``
- ``/curves/<method>/...`` (Scalars), ``/queue/<method>/...`` (C2INet's prior queue)

Everything is logged batched: one archetype per entity per frame, never one entity per agent.
Draw order puts the truth above the best of K and both above the pale, thin K samples.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError
from c2inet.files import write_atomic
from c2inet.lazy import lazy_module
from viz.blueprint import Bounds, scale_bar
from viz.colours import FUTURE, OBSERVED, faint, legend_markdown, task_shade
from viz.live import spawn_viewer, viewer_url
from viz.loggers import diagnostic_scalars

# Rerun loads where a recording starts: a run with --no-record never pays for it
rr = lazy_module("rerun")
rrb = lazy_module("rerun.blueprint")

Colour = tuple[int, int, int]
SAMPLES, BEST, TRUTH, SCALE = 10.0, 20.0, 30.0, 40.0  # draw orders: higher is drawn above
SCALE_COLOUR = (110, 110, 110)  # a mid grey, read on the viewer's light and dark backgrounds


def _thin():
    """A sample line's width: one point on screen, whatever the scene's size."""
    return rr.Radius.ui_points(1.0)


def _strips(paths: np.ndarray) -> list[np.ndarray]:
    """(..., T, 2) -> a flat list of (T, 2) polylines."""
    return list(paths.reshape(-1, *paths.shape[-2:]))


def _finite_runs(track: np.ndarray) -> list[np.ndarray]:
    """The stretches of one agent's (frames, 2) track where it is present, as polylines."""
    present = np.isfinite(track).all(1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], present.astype(int), [0]])))
    return [track[a:b] for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a > 1]


def _from_last_observed(last_obs: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Predictions (K, agents, T, 2) prefixed with each agent's last observed position."""
    start = np.broadcast_to(last_obs[None, :, None], (*pred.shape[:2], 1, 2))
    return np.concatenate([start, pred], axis=2)


class RunRecorder:
    """Writes a run to one recording stream (a file, a live viewer, or both)."""

    def __init__(self, stream: rr.RecordingStream):
        self.rec = stream
        self.epoch = 0
        self._coloured: set[str] = set()  # time series whose colour is already logged

    @classmethod
    def create(
        cls,
        app_id: str,
        recording_id: str,
        path: Path | None,
        target: str | None,
        blueprint: rrb.Blueprint | None,
    ) -> RunRecorder:
        """A recorder saving to ``path`` (when given) and streaming to ``target``.

        ``target``: None, ``spawn`` (start a viewer) or ``connect`` / ``connect=URL``.
        """
        stream = rr.RecordingStream(app_id, recording_id=recording_id)
        sinks = []
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(path)))
        if target == "spawn":  # start a viewer on 127.0.0.1, then stream to it beside the file
            target = f"connect={spawn_viewer()}"
        if target is not None:
            sinks.append(rr.GrpcSink(viewer_url(target)))
        if sinks:
            stream.set_sinks(*sinks, default_blueprint=blueprint)
        return cls(stream)

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()

    def _time(self, **times: int) -> None:
        self.rec.reset_time()
        for timeline, value in times.items():
            self.rec.set_time(timeline, sequence=value)

    # --- static context -------------------------------------------------------------------
    def log_legend(self, methods: list[str], tasks: list[str] | None = None) -> None:
        self.rec.log(
            "legend",
            rr.TextDocument(legend_markdown(methods, tasks), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )

    def log_scale_bars(self, bounds: dict[str, Bounds]) -> None:
        """A metric scale bar in every framed view (origin -> its bounds), labelled in metres."""
        for origin, box in bounds.items():
            length, corners = scale_bar(box)
            self.rec.log(
                f"{origin.strip('/')}/scale",
                rr.LineStrips2D(
                    [corners],
                    colors=SCALE_COLOUR,
                    radii=rr.Radius.ui_points(2.0),
                    labels=f"{length:g} m",
                    show_labels=True,
                    draw_order=SCALE,
                ),
                static=True,
            )

    def log_run_card(self, markdown: str) -> None:
        self.rec.log(
            "run_card", rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN), static=True
        )

    def log_domain(self, task: str, knobs: dict[str, Any], stats: dict[str, Any]) -> None:
        values = {f"knob.{k}": str(v) for k, v in knobs.items()}
        values.update({f"stat.{k}": float(v) for k, v in stats.items()})
        self.rec.log(f"tasks/{task}", rr.AnyValues(**values), static=True)

    # --- scene playback -------------------------------------------------------------------
    def log_scene_truth(
        self, task: str, index: int, positions: np.ndarray, ids: np.ndarray, obs_len: int
    ) -> None:
        """Ground truth of one scene: agents moving on ``frame``, history and future as lines.

        positions: (agents, frames, 2).
        """
        base = f"tasks/{task}/scenes/{index}/truth"
        frames = positions.shape[1]
        labels = [str(i) for i in ids]
        self.rec.send_columns(
            f"{base}/agents",
            indexes=[rr.TimeColumn("frame", sequence=np.arange(frames))],
            columns=rr.Points2D.columns(
                positions=positions.transpose(1, 0, 2).reshape(-1, 2),
                labels=np.tile(labels, frames),
            ).partition(np.full(frames, len(ids))),
        )
        self.rec.log(
            f"{base}/history",
            rr.LineStrips2D(_strips(positions[:, :obs_len]), colors=OBSERVED, draw_order=TRUTH),
            static=True,
        )
        future = rr.LineStrips2D(
            _strips(positions[:, obs_len - 1 :]), colors=FUTURE, draw_order=TRUTH
        )
        self.rec.log(f"{base}/future", future, static=True)

    def log_scene_predictions(
        self,
        task: str,
        index: int,
        method: str,
        when: dict[str, int],
        last_obs: np.ndarray,
        pred: np.ndarray,
        best: np.ndarray,
        obs_len: int,
        colour: Colour,
    ) -> None:
        """K predicted futures of one scene at ``when`` (the ``task`` trained through and the
        ``epoch`` that ended it), in the method's colour.

        pred: (K, agents, T, 2), drawn from the last observed position; best: (agents,) sample
        index of the best of K (joint), drawn thick.
        """
        base = f"tasks/{task}/scenes/{index}/{method}"
        self._time(**when, frame=obs_len - 1)
        paths = _from_last_observed(last_obs, pred)
        samples = rr.LineStrips2D(
            _strips(paths), colors=faint(colour), radii=_thin(), draw_order=SAMPLES
        )
        self.rec.log(f"{base}/predictions", samples)
        chosen = paths[best, np.arange(paths.shape[1])]
        self.rec.log(
            f"{base}/best",
            rr.LineStrips2D(_strips(chosen), colors=colour, radii=0.04, draw_order=BEST),
        )

    # --- rollouts -------------------------------------------------------------------------
    def log_rollout_truth(self, task: str, positions: np.ndarray, ids: np.ndarray) -> None:
        """A longer episode, frame by frame; positions (frames, agents, 2), NaN where absent.
        Each agent's whole path is also drawn as static lines, so the truth is there on every
        timeline, the ``epoch`` one the viewer opens on included."""
        paths = [run for agent in positions.transpose(1, 0, 2) for run in _finite_runs(agent)]
        self.rec.log(
            f"rollouts/{task}/truth/paths",
            rr.LineStrips2D(paths, colors=FUTURE, radii=_thin(), draw_order=TRUTH),
            static=True,
        )
        present = ~np.isnan(positions[..., 0])
        counts = present.sum(1)
        labels = np.broadcast_to(np.asarray(ids).astype(str), present.shape)[present]
        self.rec.send_columns(
            f"rollouts/{task}/truth/agents",
            indexes=[rr.TimeColumn("frame", sequence=np.arange(len(positions)))],
            columns=rr.Points2D.columns(positions=positions[present], labels=labels).partition(
                counts
            ),
        )

    def log_rollout_predictions(
        self,
        task: str,
        method: str,
        when: dict[str, int],
        frames: np.ndarray,
        last_obs: np.ndarray,
        pred: np.ndarray,
        window_agents: np.ndarray,
        colour: Colour,
    ) -> None:
        """At each frame, K predictions from the 8 frames observed so far.

        frames: (W,) the rollout frame of each window's last observation; pred: (K, A, T, 2)
        for all windows' agents concatenated; window_agents: (W,) agents per window.
        """
        paths = _from_last_observed(last_obs, pred).transpose(1, 0, 2, 3)  # (A, K, T+1, 2)
        strips_per_window = window_agents * pred.shape[0]
        self.rec.send_columns(
            f"rollouts/{task}/{method}/predictions",
            indexes=[
                rr.TimeColumn("frame", sequence=frames),
                *(rr.TimeColumn(t, sequence=np.full(len(frames), v)) for t, v in when.items()),
            ],
            columns=rr.LineStrips2D.columns(strips=_strips(paths)).partition(strips_per_window),
        )
        self._colour_once(f"rollouts/{task}/{method}/predictions", rr.LineStrips2D, colour)

    # --- curves ---------------------------------------------------------------------------
    def _colour_once(self, path: str, archetype, colour: Colour) -> None:
        """Give entity ``path`` its method's colour, logged once as static data."""
        if path not in self._coloured:
            self.rec.log(path, archetype.from_fields(colors=colour), static=True)
            self._coloured.add(path)

    def _scalar(self, path: str, value: float, colour: Colour) -> None:
        """One point of a time series drawn in ``colour``."""
        self._colour_once(path, rr.SeriesLines, colour)
        self.rec.log(path, rr.Scalars(float(value)))

    def log_epoch(
        self, method: str, record: dict[str, Any], colour: Colour, tasks: list[str]
    ) -> None:
        """Training losses and validation ADE of every seen task, on the global ``epoch``; each
        task's curve in its own shade of the method's colour."""
        self._time(epoch=record["global_epoch"], task=record["task"])
        for key, value in record.items():
            if key not in ("task", "epoch", "global_epoch"):
                task = key.removeprefix("val_ade/")
                shade = task_shade(colour, tasks.index(task), len(tasks)) if task != key else colour
                self._scalar(f"curves/{method}/{key}", value, shade)

    def log_matrix_row(
        self,
        method: str,
        when: dict[str, int],
        tasks: list[str],
        row: dict[str, list[float]],
        colour: Colour,
    ) -> None:
        """Error on every task after training through one task, at ``when``; for the latent
        models also under their other test-time rules for C (``ade_c_prior`` ...)."""
        self._time(**when)
        rules = [m for m in row if m.startswith(("ade_c_", "ade_k1_c_"))]
        for j, name in enumerate(tasks):
            shade = task_shade(colour, j, len(tasks))
            for metric in ("ade", "fde", "ade_k1", *rules):
                self._scalar(f"curves/{method}/matrix/{metric}/{name}", row[metric][j], shade)

    def log_diagnostics(
        self, method: str, when: dict[str, int], diagnostics: dict, colour: Colour
    ) -> None:
        """The confounder's diagnostics after a task (``c2inet.diagnostics``), as scalars at
        ``when``; per-task lists are averaged over the tasks seen."""
        self._time(**when)
        for key, value in diagnostic_scalars(diagnostics):
            self._scalar(f"diagnostics/{method}/{key}", value, colour)

    def log_queue(
        self, method: str, when: dict[str, int], means: np.ndarray, weights: np.ndarray
    ) -> None:
        """The prior queue after a task: its size, weights, and component means in 2-D (PCA)."""
        self._time(**when)
        self.rec.log(f"curves/{method}/queue_size", rr.Scalars(float(len(weights))))
        centred = means - means.mean(0)
        if len(means) > 1 and means.shape[1] > 2:
            _, _, vt = np.linalg.svd(centred, full_matrices=False)
            flat = centred @ vt[:2].T
        else:
            flat = centred[:, :2] if means.shape[1] >= 2 else np.pad(centred, ((0, 0), (0, 1)))
        radii = 0.05 + 0.3 * np.sqrt(weights / weights.max())
        self.rec.log(
            f"queue/{method}/components",
            rr.Points2D(flat, radii=radii, labels=[f"{w:.2f}" for w in weights]),
        )
        self.rec.log(f"queue/{method}/weights", rr.BarChart(weights))


def merge_recordings(parts: list[Path], path: Path) -> None:
    """One recording file of ``parts`` (the run's and its jobs', same recording id), written
    atomically with Rerun's own ``rerun rrd merge``."""
    rerun = Path(sys.executable).with_name("rerun")

    def merge(tmp: Path) -> None:
        command = [str(rerun), "rrd", "merge", *map(str, parts), "-o", str(tmp)]
        done = subprocess.run(command, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise InputError(f"{path}: rerun rrd merge failed: {done.stderr.strip()[-500:]}")

    write_atomic(path, merge)
