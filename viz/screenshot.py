"""``python -m viz.screenshot FILE.rrd OUT.png``: the web viewer rendered by headless Chromium.

Serves the recording on 127.0.0.1 (``viz.serve``), opens the viewer in Debian's ``chromium``
(SwiftShader's software WebGL, no GPU needed) driven by Playwright, and polls in real time until
the viewer has drawn, then saves a screenshot. Real time, not Chromium's virtual time: on a busy
machine the viewer's WebAssembly takes tens of seconds to compile, and a virtual-time budget ran
out after about 3 s of real time whatever its size. Needs ``pip install '.[screenshot]'``.
"""

from __future__ import annotations

import argparse
import io
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from c2inet.errors import InputError
from c2inet.files import write_atomic
from viz.cli import guarded, plain_parser
from viz.serve import command, free_port, launch, stop, wait_for_port

MIN_COLOURS = 500  # a blank page has under 10, the loading screen a few dozen
POLL_S = 3.0  # seconds between pictures: the viewer is done when two in a row are the same
CHROMIUM_FLAGS = [
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
    # the viewer asks the internet for fonts, its latest release and telemetry: no name but
    # the loopback resolves, so nothing leaves the machine and no lookup waits on a resolver
    "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1",
]


def rendered(png: bytes) -> bool:
    """True when the picture shows a drawn viewer, not a blank or loading page (few colours)."""
    from matplotlib.image import imread

    image = imread(io.BytesIO(png), format="png")
    return len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > MIN_COLOURS


def drawn(page, deadline: float) -> bytes | None:
    """The viewer's picture once it has drawn and then stopped changing (the recording has
    streamed in: a large one takes minutes on a busy machine), polling every ``POLL_S``; the
    last drawn picture at ``deadline``; None if it never drew."""
    last = None
    while time.monotonic() < deadline:
        page.wait_for_timeout(POLL_S * 1000)
        png = page.screenshot()
        if last is not None and png == last:
            return png
        last = png if rendered(png) else None
    return last


def screenshot(
    recording: Path, out: Path, size: str = "1600,900", timeout_s: float = 300.0
) -> Path:
    """Render ``recording`` in the web viewer and save ``out`` once it has drawn and settled
    (:func:`drawn`), within ``timeout_s``; raises RuntimeError if it never drew."""
    try:
        from playwright.sync_api import Error, sync_playwright
    except ImportError:
        raise RuntimeError("needs Playwright: pip install '.[screenshot]'") from None
    browser_path = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser_path is None:
        raise RuntimeError("no chromium on PATH (Debian: apt-get install chromium)")
    width, height = (int(v) for v in size.split(","))
    web, grpc = free_port(), free_port()
    server = launch(
        command(recording, web, grpc),
        dict(os.environ),  # the user's own Rerun configuration
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        wait_for_port(web)
        url = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp://127.0.0.1:{grpc}/proxy"
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=browser_path, args=CHROMIUM_FLAGS)
            try:
                page = browser.new_page(viewport={"width": width, "height": height})
                page.goto(url, timeout=timeout_s * 1000)
                png = drawn(page, time.monotonic() + timeout_s)
                if png is not None:
                    write_atomic(out, lambda path: path.write_bytes(png))
                    return out
            except Error as error:
                raise RuntimeError(f"chromium: {error.message.splitlines()[0]}") from None
            finally:
                browser.close()
    finally:
        stop(server)
    raise RuntimeError(f"the viewer did not draw within {timeout_s:g} s; {out} not written")


def picture_size(text: str) -> str:
    """An argparse ``type``: ``WIDTH,HEIGHT`` in pixels, each 200 to 4000."""
    parts = text.split(",")
    if len(parts) != 2 or not all(p.strip().isdigit() and 200 <= int(p) <= 4000 for p in parts):
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTH,HEIGHT (each 200 to 4000)")
    return ",".join(p.strip() for p in parts)


@guarded
def main(argv: list[str] | None = None) -> int:
    p = plain_parser("viz.screenshot", __doc__.splitlines()[0])
    p.add_argument("recording", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument(
        "--size",
        type=picture_size,
        default="1600,900",
        help="the picture in pixels, WIDTH,HEIGHT (default 1600,900; software WebGL draws "
        "every frame on the CPU, so a smaller one is faster)",
    )
    args = p.parse_args(argv)
    if not args.recording.is_file():
        raise InputError(f"{args.recording}: no such recording")
    try:
        print(screenshot(args.recording, args.out, args.size))
    except (RuntimeError, subprocess.SubprocessError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
