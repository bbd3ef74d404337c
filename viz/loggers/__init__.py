"""Loggers on the trainer's observer hook: what a job measures, as a CSV file, TensorBoard
events, an MLflow run or a W&B run, beside the recording; one module a logger, found by the
registry (``viz.loggers.base``), so a new one is one file (or another package's entry point of
the group ``viz.loggers``).

All log the same numbers at the same global step (task * epochs + epoch): per epoch the
training losses and the validation ADE of every seen task, per task the error-matrix row and the
diagnostics (lists averaged over the tasks seen); TensorBoard, MLflow and W&B also the job's
configuration as hyper-parameters.
"""

from viz.loggers.base import (
    REGISTRY,
    ROW_METRICS,
    Logger,
    check_spec,
    diagnostic_scalars,
    epoch_step,
    flat_params,
    log_outputs,
    make_loggers,
    prepare_tracking,
    register,
    scalars,
    task_step,
)
from viz.loggers.csv_log import CSVLogger
from viz.loggers.mlflow_log import MLFLOW_PATIENCE, MLflowLogger
from viz.loggers.tensorboard_log import TensorBoardLogger
from viz.loggers.wandb_log import WANDB_MODES, WandbLogger

__all__ = [
    "MLFLOW_PATIENCE",
    "REGISTRY",
    "ROW_METRICS",
    "WANDB_MODES",
    "CSVLogger",
    "Logger",
    "MLflowLogger",
    "TensorBoardLogger",
    "WandbLogger",
    "check_spec",
    "diagnostic_scalars",
    "epoch_step",
    "flat_params",
    "log_outputs",
    "make_loggers",
    "prepare_tracking",
    "register",
    "scalars",
    "task_step",
]
