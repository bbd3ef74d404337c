"""``--logger wandb[=online]``: a W&B run per job, offline unless told otherwise."""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Any

from c2inet.errors import InputError
from viz.loggers.base import Logger, register, scalars

WANDB_MODES = ("offline", "online")


@register
class WandbLogger(Logger):
    """A W&B run per job, offline by default (``wandb/`` in the job's folder, no account needed;
    ``wandb sync`` uploads it later) or online with ``wandb=online`` and a login: the project is
    the run folder's parent (the scenario, for default folders), the group the run folder, the
    name the job; the configuration as the run's config, every number at its step."""

    name = "wandb"
    title = "a W&B run per job, offline (no account) or online with wandb=online"
    value = "online"  # W&B's server, not offline
    values = WANDB_MODES

    def __init__(self, folder: Path, epochs: int, tasks: list[str], run_folder=None, **options):
        try:
            import wandb
        except ImportError:
            raise InputError(
                "--logger wandb: W&B is not installed (pip install '.[wandb]')"
            ) from None
        run_folder = Path(run_folder or folder).resolve()
        self.epochs, self.tasks = epochs, tasks
        shutil.rmtree(folder / "wandb", ignore_errors=True)  # a resumed job logs everything again
        (folder / "wandb").mkdir(parents=True)
        settings = wandb.Settings(
            mode=options.get("uri") or "offline",
            silent=True,
            console="off",  # the job's own output stays the job's
            x_disable_stats=True,  # no system metrics sampled beside training
            x_disable_meta=True,
            save_code=False,
            disable_git=True,
        )
        self.run = wandb.init(
            dir=folder,
            project=re.sub(r"[/\\#?%:]", "_", run_folder.parent.name)[:128],
            group=run_folder.name,
            name=folder.resolve().relative_to(run_folder).as_posix(),
            config=options.get("params") or {},
            settings=settings,
            reinit="create_new",
        )

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        steps: dict[int, dict[str, float]] = {}
        for step, name, value in scalars(event, data, self.epochs, self.tasks):
            steps.setdefault(step, {})[name] = value
        for step, values in sorted(steps.items()):
            self.run.log(values, step=step)

    def close(self) -> None:
        self.run.finish()
