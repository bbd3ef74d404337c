"""Continual learning on your own arrays: two domains of people walking, straight then turning.

Any (agents, 8 + 12, 2) array of positions in metres, grouped by scene, is a ``Windows``; a
``Task`` holds the train, validation and test windows of one domain. Run it from anywhere:

    python examples/own_arrays.py
"""

import numpy as np

from c2inet import ContinualTrainer, ModelConfig, Task, TrainConfig, Windows, get_method


def walkers(turn: float, scenes: int, seed: int) -> Windows:
    """Scenes of 3 people at 1 m/s (0.4 s frames) whose heading changes by ``turn`` per frame."""
    rng = np.random.default_rng(seed)
    agents = 3 * scenes
    heading = rng.uniform(-np.pi, np.pi, (agents, 1)) + turn * np.arange(20)
    steps = 0.4 * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    positions = rng.uniform(-10, 10, (agents, 1, 2)) + np.cumsum(steps, axis=1)
    scene_start = np.arange(0, agents + 1, 3)  # agents of scene s: scene_start[s]:[s + 1]
    return Windows(positions.astype(np.float32), scene_start)


tasks = [
    Task(name, walkers(turn, 40, 0), walkers(turn, 5, 1), walkers(turn, 10, 2))
    for name, turn in (("straight", 0.0), ("turning", 0.15))
]
for name in ("finetune", "c2inet-online"):
    method = get_method(name)(ModelConfig())
    result = ContinualTrainer(method, tasks, TrainConfig(epochs=4, k=5)).run()
    ade = result.matrices["ade"]
    print(f"{name:14s} ADE on 'straight' after each task: {ade[0, 0]:.3f} -> {ade[1, 0]:.3f} m")
