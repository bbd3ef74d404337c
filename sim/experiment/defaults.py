"""What the commands need before any heavy import (torch, pyarrow, rerun): the default
methods of a run. ``--help`` and a mistyped option answer without loading the learner."""

DEFAULT_METHODS = ("c2inet-online", "finetune", "cv")
