"""``python -m viz.screenshot FILE.rrd OUT.png``: the web viewer rendered by headless Chromium.

Serves the recording on 127.0.0.1 (``viz.serve``), loads the viewer in Debian's ``chromium`` with
SwiftShader's software WebGL (no GPU needed), and saves a screenshot. Used to check that the
viewer renders, and for the README's picture.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from c2inet.errors import InputError
from c2inet.files import write_atomic
from viz.cli import guarded, plain_parser
from viz.serve import command, free_port, launch, stop, wait_for_port

MIN_COLOURS = 500  # a blank page has under 10, the loading screen a few dozen
CHROMIUM_FLAGS = [
    "--headless=new",
    "--no-sandbox",
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def rendered(png: Path) -> bool:
    """True when the picture shows a drawn viewer, not a blank or loading page (few colours)."""
    from matplotlib.image import imread

    image = imread(png)
    return len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > MIN_COLOURS


def screenshot(
    recording: Path, out: Path, size: str = "1600,900", budget_ms: int = 60000, attempts: int = 3
) -> Path:
    """Render ``recording`` in the web viewer and save ``out``; raises RuntimeError on failure."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        raise RuntimeError("no chromium on PATH (Debian: apt-get install chromium)")
    web, grpc = free_port(), free_port()
    with tempfile.TemporaryDirectory() as tmp:
        shot = Path(tmp) / "viewer.png"  # out is written only once a drawn viewer is in it
        env = dict(os.environ)  # the user's own Rerun configuration
        server = launch(
            command(recording, web, grpc), env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        try:
            wait_for_port(web)
            url = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp://127.0.0.1:{grpc}/proxy"
            for attempt in range(1, attempts + 1):  # a loaded machine may still show the loader
                subprocess.run(
                    [
                        browser,
                        *CHROMIUM_FLAGS,
                        f"--user-data-dir={tmp}/chromium",
                        f"--window-size={size}",
                        f"--virtual-time-budget={budget_ms * attempt}",
                        f"--screenshot={shot}",
                        url,
                    ],
                    env=env,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                    timeout=300,
                    check=True,
                )
                if shot.exists() and rendered(shot):
                    write_atomic(out, lambda path: shutil.copyfile(shot, path))
                    return out
                time.sleep(2)  # let the viewer server settle before the next try
        finally:
            stop(server)
    raise RuntimeError(f"the viewer did not render within {attempts} attempts; {out} not written")


@guarded
def main(argv: list[str] | None = None) -> int:
    p = plain_parser("viz.screenshot", __doc__.splitlines()[0])
    p.add_argument("recording", type=Path)
    p.add_argument("out", type=Path)
    args = p.parse_args(argv)
    if not args.recording.is_file():
        raise InputError(f"{args.recording}: no such recording")
    try:
        print(screenshot(args.recording, args.out))
    except (RuntimeError, subprocess.SubprocessError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
