"""Progress bars on stderr: live in a terminal, plain lines in a log.

Off a terminal (a ``nohup`` log, CI, a pipe) tqdm's carriage returns and cursor moves pile up as
one unreadable line; there each main bar writes one plain line when it moves and a short-lived
(``transient``) bar, such as the domains of a curriculum, writes nothing.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any, TextIO

from tqdm import tqdm


class LineStream:
    """A stream for tqdm that turns each refresh into one line and drops the blank ones."""

    def __init__(self, stream: TextIO):
        self.stream = stream

    def write(self, text: str) -> None:
        for part in text.replace("\x1b[A", "").split("\r"):
            if part.strip():
                self.stream.write(part.strip() + "\n")

    def flush(self) -> None:
        self.stream.flush()


def progress_bar(
    iterable: Iterable | None = None, *, transient: bool = False, **options: Any
) -> tqdm:
    """A tqdm bar on stderr; in a terminal as tqdm draws it, elsewhere as lines (at most one
    every ``mininterval`` seconds, 10 by default) or, for a ``transient`` bar (or one given
    ``leave=False``), not at all."""
    stream = sys.stderr
    transient = transient or options.pop("leave", True) is False
    if stream.isatty():
        return tqdm(iterable, file=stream, leave=not transient, **options)
    options.setdefault("mininterval", 10.0)
    return tqdm(
        iterable, file=LineStream(stream), disable=transient, ascii=True, ncols=100, **options
    )
