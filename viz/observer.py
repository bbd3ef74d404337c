"""A trainer observer turning training events into recording calls (none in training code)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from c2inet.data import Windows
from c2inet.evaluation import sample_predictions
from c2inet.metrics import best_sample, displacement_errors
from viz.blueprint import extent
from viz.loggers import epoch_step, task_step
from viz.recording import RunRecorder


@dataclass
class Showcase:
    """What is drawn for one task: sample test scenes, and a rollout cut into windows."""

    task: str
    scenes: Windows  # the same sample scenes for every method and checkpoint
    rollout_windows: Windows | None = None
    rollout_frames: np.ndarray | None = None  # rollout frame of each window's last observation


@dataclass
class RecordingObserver:
    """Receives ``epoch_end`` and ``task_end`` events of one method's run."""

    recorder: RunRecorder
    method: str
    showcases: list[Showcase]
    k: int
    epochs: int  # per task: a task's results are drawn at the global epoch that ended it
    colour: tuple[int, int, int]
    rollout_k: int = 5
    seed: int = 0
    final_predictions: dict[str, np.ndarray] = field(default_factory=dict)  # task -> (K, A, T, 2)

    @property
    def tasks(self) -> list[str]:
        return [s.task for s in self.showcases]

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        if event == "epoch_end":
            epoch = epoch_step(data["task"], data["epoch"], self.epochs)
            record = {**data, "global_epoch": epoch}
            self.recorder.log_epoch(self.method, record, self.colour, self.tasks)
        elif event == "task_end":
            self._task_end(data)

    def _predict(self, model, windows: Windows, k: int) -> np.ndarray:
        """(K, agents, T, 2) absolute predictions, reproducible for the observer's seed."""
        return sample_predictions(model, windows, k, self.seed).transpose(0, 2, 1, 3)

    def _task_end(self, data: dict[str, Any]) -> None:
        model, trained = data["model"], data["task"]
        when = {"task": trained, "epoch": task_step(trained, self.epochs)}
        self.recorder.log_matrix_row(self.method, when, self.tasks, data["row"], self.colour)
        if data.get("diagnostics"):
            self.recorder.log_diagnostics(self.method, when, data["diagnostics"], self.colour)
        queue = getattr(model, "queue", None)
        if queue is not None:
            mixture = queue.mixture.detached()
            self.recorder.log_queue(
                self.method, when, mixture.means.cpu().numpy(), mixture.weights.cpu().numpy()
            )
        for show in self.showcases:
            windows = show.scenes
            pred = self._predict(model, windows, self.k)
            obs_len = windows.obs_len
            truth = windows.positions[:, obs_len:]
            ade, _ = displacement_errors(pred.transpose(0, 2, 1, 3), truth.transpose(1, 0, 2))
            best = best_sample(ade, windows.scene_start, "joint")
            for s in range(len(windows)):
                agents = slice(windows.scene_start[s], windows.scene_start[s + 1])
                self.recorder.log_scene_predictions(
                    show.task,
                    s,
                    self.method,
                    when,
                    windows.positions[agents, obs_len - 1],
                    pred[:, agents],
                    best[agents],
                    obs_len,
                    self.colour,
                )
            self.final_predictions[show.task] = pred
            if show.rollout_windows is not None:
                rollout = show.rollout_windows
                pred = self._predict(model, rollout, self.rollout_k)
                self.recorder.log_rollout_predictions(
                    show.task,
                    self.method,
                    when,
                    show.rollout_frames,
                    rollout.positions[:, rollout.obs_len - 1],
                    pred,
                    rollout.agents_per_scene,
                    self.colour,
                )


def log_truth(recorder: RunRecorder, showcases: list[Showcase], rollouts: dict[str, tuple]) -> None:
    """Ground truth of every showcase: the sample scenes, and each rollout frame by frame.

    ``rollouts``: task -> (positions (frames, agents, 2) with NaN where absent, agent ids).
    """
    for show in showcases:
        windows = show.scenes
        for s in range(len(windows)):
            agents = slice(windows.scene_start[s], windows.scene_start[s + 1])
            ids = np.arange(agents.stop - agents.start)
            recorder.log_scene_truth(show.task, s, windows.positions[agents], ids, windows.obs_len)
        if show.task in rollouts:
            recorder.log_rollout_truth(show.task, *rollouts[show.task])


def framing(showcases: list[Showcase], rollouts: dict[str, tuple]) -> dict[str, tuple]:
    """Where each scene view and rollout view opens (origin -> bounds): the truth's extent."""
    bounds = {}
    for show in showcases:
        windows = show.scenes
        for s in range(len(windows)):
            agents = slice(windows.scene_start[s], windows.scene_start[s + 1])
            bounds[f"/tasks/{show.task}/scenes/{s}"] = extent(windows.positions[agents])
        if show.task in rollouts:
            bounds[f"/rollouts/{show.task}"] = extent(rollouts[show.task][0])
    return bounds
