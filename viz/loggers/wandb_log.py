"""``--logger wandb[=online]``: a W&B run per job, offline unless told otherwise."""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Any

from c2inet.errors import InputError
from viz.loggers.base import Logger, failure, register, scalars

WANDB_MODES = ("offline", "online")


@register
class WandbLogger(Logger):
    """A W&B run per job, offline by default (``wandb/`` in the job's folder, no account needed;
    ``wandb sync`` uploads it later) or online with ``wandb=online`` and a login: the project is
    the group folder's parent (the scenario, for default folders), the group the group folder
    (the run's, or the sweep's or benchmark's it belongs to, so their runs compare side by
    side), the name the job; the configuration as the run's config, every number at its step.
    Each run folder's report, figures and recording are the artifact of one more run,
    ``.../report``, its figures logged as images."""

    name = "wandb"
    title = "a W&B run per job, offline (no account) or online with wandb=online"
    value = "online"  # W&B's server, not offline
    values = WANDB_MODES

    def __init__(self, folder: Path, epochs: int, tasks: list[str], run_folder=None, **options):
        run_folder = Path(run_folder or folder).resolve()
        group = Path(options.get("group") or run_folder).resolve()
        self.epochs, self.tasks = epochs, tasks
        folder = folder.resolve()
        self.run = _start(
            folder, _name(folder, group), group, options.get("uri"), options.get("params")
        )

    @classmethod
    def log_outputs(cls, run_folder: Path, group: Path, value: str | None, files: list[Path]):
        """The run's files as one artifact of its ``report`` run, its figures as images."""
        import wandb

        name = _name(run_folder / "report", group)  # a name, not a folder
        run = _start(run_folder, name, group, value, None, job_type="report")
        artifact = wandb.Artifact(re.sub(r"[^\w.-]", "_", run.name)[:120], type="report")
        for path in files:
            artifact.add_file(str(path), path.relative_to(run_folder).as_posix())
        run.log_artifact(artifact)
        images = {f"figures/{p.stem}": wandb.Image(str(p)) for p in files if p.suffix == ".png"}
        if images:
            run.log(images)
        run.finish()

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        steps: dict[int, dict[str, float]] = {}
        for step, name, value in scalars(event, data, self.epochs, self.tasks):
            steps.setdefault(step, {})[name] = value
        for step, values in sorted(steps.items()):
            self.run.log(values, step=step)

    def close(self) -> None:
        self.run.finish()


def _name(folder: Path, group: Path) -> str:
    """A folder's name in its group: its path below the group's folder."""
    return folder.relative_to(group).as_posix() if folder.is_relative_to(group) else folder.name


def _start(
    folder: Path, name: str, group: Path, mode: str | None, params, job_type: str | None = None
):
    """A W&B run called ``name`` in ``folder/wandb`` (started afresh: a resumed job logs
    everything again), of ``group``."""
    try:
        import wandb
    except ImportError:
        raise InputError("--logger wandb: W&B is not installed (pip install '.[wandb]')") from None
    shutil.rmtree(folder / "wandb", ignore_errors=True)
    (folder / "wandb").mkdir(parents=True)
    settings = wandb.Settings(
        mode=mode or "offline",
        silent=True,
        console="off",  # the job's own output stays the job's
        x_disable_stats=True,  # no system metrics sampled beside training
        x_disable_meta=True,
        save_code=False,
        disable_git=True,
    )
    try:
        return wandb.init(
            dir=folder,
            project=re.sub(r"[/\\#?%:]", "_", group.parent.name)[:128],
            group=group.name,
            name=name,
            job_type=job_type,
            config=params or {},
            settings=settings,
            reinit="create_new",
        )
    except Exception as error:  # no key, no network, a refused login: W&B's own errors
        raise InputError(
            f"--logger wandb={mode or 'offline'}: W&B cannot start a run ({failure(error)}); "
            "log in (wandb login, or WANDB_API_KEY) or use --logger wandb"
        ) from None
