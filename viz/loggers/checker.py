"""The logger checker: what every logger, built-in or a plugin, must do with a job's events
(``tests/viz/test_loggers.py`` runs it over every registered one)."""

from __future__ import annotations

from pathlib import Path

from c2inet.registry import PLUGIN_NAME
from viz.loggers.base import Logger

EVENTS = (  # one task of two epochs, as the trainer sends them
    ("epoch_end", {"task": 0, "epoch": 0, "nll": 1.5, "val_ade/a": 0.4}),
    ("epoch_end", {"task": 0, "epoch": 1, "nll": 1.2, "val_ade/a": 0.3}),
    (
        "task_end",
        {
            "task": 0,
            "row": {"ade": [0.3, 0.5], "fde": [0.6, 0.9], "ade_k1": [0.35, 0.55], "fde_k1": [0.7]},
            "diagnostics": {"kl_c": [0.5, 0.7], "kl_c_binding": 1.0},
        },
    ),
)


class LoggerCheckError(AssertionError):
    """A logger that breaks its contract."""


def check_logger(cls: type[Logger], folder: Path) -> list[Path]:
    """Run ``cls`` through one job's events in a run under ``folder``: it has a plain name and a
    one-line title, prepares, logs and closes without error, and leaves files of its own in the
    job's folder or the run's; returns them."""
    if not PLUGIN_NAME.fullmatch(cls.name or "") or not cls.title.strip():
        raise LoggerCheckError(f"logger {cls!r}: needs a plain name and a one-line title")
    run = folder / "run"
    job = run / "jobs" / "finetune" / "seed_0"
    job.mkdir(parents=True)
    cls.prepare(run.resolve(), None)
    logger = cls(job, 2, ["a", "b"], run_folder=run, params={"train.lr": 0.003}, uri=None)
    for event, data in EVENTS:
        logger(event, data)
    logger.close()
    written = [p for p in run.rglob("*") if p.is_file()]
    if not written:
        raise LoggerCheckError(f"logger {cls.name!r}: logged a job and wrote nothing")
    return written
