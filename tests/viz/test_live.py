"""The live viewer on 127.0.0.1 only, addresses checked before a run, screenshots all or nothing."""

import subprocess
import time
from pathlib import Path

import pytest

from c2inet.errors import InputError
from viz.live import check_reachable, viewer_command, viewer_url
from viz.serve import free_port, launch, stop


@pytest.mark.parametrize(
    "target",
    ["connect=foo", "connect=rerun+http://127.0.0.1:99999/proxy", "connect=http://x:1/proxy"],
)
def test_malformed_viewer_addresses_are_refused(target):
    with pytest.raises(InputError, match="expected rerun\\+http://HOST:PORT/proxy"):
        viewer_url(target)


def test_addresses_parse_and_default():
    assert viewer_url("connect") == "rerun+http://127.0.0.1:9876/proxy"
    url = "rerun+http://[::1]:9000/proxy"
    assert viewer_url(f"connect={url}") == url


def test_an_address_where_nothing_listens_fails_before_the_run():
    with pytest.raises(InputError, match="no viewer answers there"):
        check_reachable(f"rerun+http://127.0.0.1:{free_port()}/proxy")


def test_the_spawned_viewer_listens_on_loopback_only():
    """The viewer's own log names the address its server bound (rerun's default: 0.0.0.0);
    without a display the window then fails, after binding."""
    port = free_port()
    viewer = launch(viewer_command(port), None, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        log, deadline = "", time.monotonic() + 20
        while "Listening for gRPC" not in log and time.monotonic() < deadline:
            line = viewer.stdout.readline().decode(errors="replace")
            if not line and viewer.poll() is not None:
                break
            log += line
    finally:
        stop(viewer)
    assert f"Listening for gRPC connections on 127.0.0.1:{port}" in log
    assert "0.0.0.0" not in log


def test_a_failed_screenshot_writes_nothing(tmp_path, monkeypatch):
    """Chromium saves a loading screen: no attempt renders, so the output never appears."""
    import viz.screenshot as shot

    def fake_chromium(cmd, **kwargs):
        path = next(a for a in cmd if a.startswith("--screenshot=")).split("=", 1)[1]
        Path(path).write_bytes(b"\x89PNG loading")
        return subprocess.CompletedProcess(cmd, 0)

    which = shot.shutil.which
    monkeypatch.setattr(
        shot.shutil,
        "which",
        lambda name: "/usr/bin/chromium" if "chromium" in name else which(name),
    )
    monkeypatch.setattr(shot.subprocess, "run", fake_chromium)
    monkeypatch.setattr(shot, "rendered", lambda png: False)
    monkeypatch.setattr(shot.time, "sleep", lambda s: None)
    recording = tmp_path / "r.rrd"
    recording.write_bytes(b"")
    with pytest.raises(RuntimeError, match="not written"):
        shot.screenshot(recording, tmp_path / "out.png", attempts=2)
    assert not (tmp_path / "out.png").exists()
