"""``python -m viz.serve FILE.rrd``: open a recording in Rerun's web viewer, on 127.0.0.1 only.

Starts the ``rerun`` command of the installed rerun-sdk bound to the loopback address (never
0.0.0.0), prints the address to open in a browser, and serves until interrupted.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from c2inet.errors import InputError
from viz.cli import bounded_int, guarded, plain_parser


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for_port(port: int, seconds: float = 10.0) -> bool:
    """Wait until something listens on 127.0.0.1:port; False after ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return True
        time.sleep(0.1)
    return False


def launch(cmd: list[str], env: dict[str, str], **popen) -> subprocess.Popen:
    """Start ``cmd`` in a process group of its own, so :func:`stop` ends all of it.

    ``rerun`` on PATH is a Python wrapper around the real binary: ending the wrapper alone
    would leave the viewer server running.
    """
    return subprocess.Popen(cmd, env=env, start_new_session=True, **popen)


def stop(process: subprocess.Popen, timeout: float = 10.0) -> None:
    """End ``process`` and everything it started (its process group); return once all are gone."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        deadline = time.monotonic() + timeout
        try:
            os.killpg(process.pid, sig)
            while time.monotonic() < deadline:
                process.poll()  # reap the group leader
                os.killpg(process.pid, 0)  # raises once no member is left
                time.sleep(0.05)
        except ProcessLookupError:
            return


def rerun_command() -> list[str]:
    """The installed rerun-sdk's ``rerun`` command."""
    return [shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))]


def how_to_open(recording: Path) -> str:
    """The command lines that open ``recording``: the installed native viewer (as a path
    relative to here where that is shorter), and the web viewer of this module."""
    native = rerun_command()[0]
    relative = os.path.relpath(native)
    native = relative if not relative.startswith("..") else native
    return f"{native} {recording}  (in a browser: python -m viz.serve {recording})"


def command(path: Path, web_port: int, grpc_port: int) -> list[str]:
    return [
        *rerun_command(),
        "--bind",
        "127.0.0.1",
        "--web-viewer",
        "--web-viewer-port",
        str(web_port),
        "--port",
        str(grpc_port),
        str(path),
    ]


def _interrupt(*_) -> None:
    raise KeyboardInterrupt


@guarded
def main(argv: list[str] | None = None) -> int:
    p = plain_parser("viz.serve", __doc__.splitlines()[0])
    p.add_argument("recording", type=Path)
    p.add_argument("--web-port", type=bounded_int(1, 65535), default=9090)
    p.add_argument("--grpc-port", type=bounded_int(1, 65535), default=9876)
    args = p.parse_args(argv)
    if not args.recording.is_file():
        raise InputError(f"{args.recording}: no such recording")
    env = dict(os.environ)  # the user's own Rerun configuration: its notice shows once, not always
    grpc = f"rerun%2Bhttp://127.0.0.1:{args.grpc_port}/proxy"
    print(f"serving {args.recording} at http://127.0.0.1:{args.web_port}/?url={grpc}", flush=True)
    server = launch(command(args.recording, args.web_port, args.grpc_port), env)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        return server.wait()
    except KeyboardInterrupt:
        return 0
    finally:
        stop(server)


if __name__ == "__main__":
    sys.exit(main())
