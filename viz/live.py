"""A live viewer: start one listening on 127.0.0.1 only, and check an address before streaming.

``rr.spawn`` starts the viewer with its default bind, every interface; here the ``rerun``
command is started with ``--bind 127.0.0.1`` instead. A ``connect=URL`` is parsed and tried when
the run starts, so a wrong address fails at once with one line instead of after the training.
"""

from __future__ import annotations

import re
import socket
import subprocess

from c2inet.errors import InputError
from viz.serve import launch, rerun_command, wait_for_port

DEFAULT_PORT = 9876
DEFAULT_URL = f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy"
URL = re.compile(
    r"rerun\+https?://(?P<host>[A-Za-z0-9.\-]+|\[[0-9A-Fa-f:]+\]):(?P<port>\d{1,5})/proxy"
)


def viewer_url(target: str) -> str:
    """The viewer address of ``connect`` or ``connect=URL``; a malformed one is an InputError."""
    url = target.partition("=")[2] or DEFAULT_URL
    match = URL.fullmatch(url)
    if match is None or not 0 < int(match["port"]) < 65536:
        raise InputError(
            f"--rerun connect={url[:80]!r}: expected rerun+http://HOST:PORT/proxy, "
            f"e.g. {DEFAULT_URL}"
        )
    return url


def check_reachable(url: str, seconds: float = 2.0) -> None:
    """InputError unless a viewer accepts connections at ``url``."""
    match = URL.fullmatch(url)
    host, port = match["host"].strip("[]"), int(match["port"])
    try:
        socket.create_connection((host, port), timeout=seconds).close()
    except OSError as error:
        raise InputError(
            f"--rerun connect={url}: no viewer answers there ({error.strerror or error}); "
            "start one with: rerun --bind 127.0.0.1"
        ) from None


def viewer_command(port: int) -> list[str]:
    """The native viewer listening on 127.0.0.1:``port`` alone (rerun's default is 0.0.0.0)."""
    return [*rerun_command(), "--bind", "127.0.0.1", "--port", str(port), "--expect-data-soon"]


def spawn_viewer(port: int = DEFAULT_PORT) -> str:
    """Start a native viewer on 127.0.0.1:``port`` (unless one already listens there) and
    return its address. It outlives the run, as ``rr.spawn``'s does."""
    if not wait_for_port(port, 0):
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
        launch(viewer_command(port), None, **quiet)
        if not wait_for_port(port, 20):
            raise InputError(
                f"--rerun spawn: no viewer came up on 127.0.0.1:{port} in 20 s (no display? "
                "then record and open the file with: python -m viz.serve FILE.rrd)"
            )
    return f"rerun+http://127.0.0.1:{port}/proxy"
