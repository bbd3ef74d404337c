"""A method from outside the package, as a user's own package would ship one: found through
the ``c2inet.methods`` entry-point group (``tests/c2inet/test_methods.py``).

Its one hook, ``before_task``, halves the learning rate at every new task.
Example: ``--methods shrinking``, once a package declaring the entry point is installed
"""

from c2inet.methods.finetune import Finetune


class Shrinking(Finetune):
    """Fine-tuning whose learning rate halves at every new task (``before_task``)."""

    name = "shrinking"

    def before_task(self, ctx):
        super().before_task(ctx)
        if ctx.index > 0:
            for group in ctx.optimiser.param_groups:
                group["lr"] *= 0.5


class ShrinkingTwin(Shrinking):
    """A second plugin that claims the first plugin's name."""

    name = "shrinking"


class Impostor(Finetune):
    """Fine-tuning's subclass without a name of its own: it must not pass as ``finetune``."""


class Taker(Finetune):
    """A plugin that claims a built-in's name."""

    name = "finetune"


class Escaper(Finetune):
    """A plugin whose name would be a path out of ``--out``."""

    name = "../../escaped"


class Undocumented(Finetune):
    name = "undocumented"


def exiting():
    """What ``entry.load()`` meets in a plugin that calls ``sys.exit`` at its import."""
    raise SystemExit(3)
