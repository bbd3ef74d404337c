"""Joint training: each task trains on the union of all tasks seen so far.

The upper reference, not a continual method: it breaks the rule that old data is gone.
Hook: ``training_windows``. Example: ``--methods joint``
"""

from c2inet.data import Windows
from c2inet.methods.base import Method, TaskContext


class Joint(Method):
    """Training on the union of all tasks seen so far: the upper reference."""

    name = "joint"
    sees_old_tasks = True

    def training_windows(self, ctx: TaskContext) -> Windows:
        return Windows.concat([*ctx.seen_train, ctx.train])
