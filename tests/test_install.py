"""The installer hands pip's configuration to uv under uv's names, pip's variables winning over
its files as in pip, and falls back to pip where uv fails."""

import importlib.util
import subprocess
from pathlib import Path

SCRIPT = Path(__file__).parents[1] / "scripts" / "install.py"
spec = importlib.util.spec_from_file_location("install", SCRIPT)
install = importlib.util.module_from_spec(spec)
spec.loader.exec_module(install)


def test_pip_configuration_becomes_uvs(monkeypatch):
    listed = [
        ":env:.find-links='/env/wheels'",
        "global.constraint='/etc/constraints.txt'",
        "global.extra-index-url='file:///a/simple file:///b/simple'",
        "global.find-links='/opt/wheels /more/wheels'",
        "global.default-timeout='60'",
    ]
    done = subprocess.CompletedProcess([], 0, stdout="\n".join(listed) + "\n")
    monkeypatch.setattr(install, "pip", lambda *args, **kwargs: done)
    env = install.uv_environment()
    assert env["UV_CONSTRAINT"] == "/etc/constraints.txt"
    assert env["UV_EXTRA_INDEX_URL"] == "file:///a/simple file:///b/simple"
    assert env["UV_FIND_LINKS"] == "/env/wheels"  # PIP_FIND_LINKS overrides the file's
    assert env["UV_INDEX_STRATEGY"] == "unsafe-best-match"  # pip's: the best of every index
    assert not any(key.startswith("UV_") and "TIMEOUT" in key for key in env)


def test_pip_installs_where_uv_fails(monkeypatch):
    calls = []

    def pip(*args, **kwargs):
        calls.append(("pip", *args))
        return subprocess.CompletedProcess([], 0, stdout="")

    def run(command, **kwargs):
        calls.append(("uv", *command[3:]))
        return subprocess.CompletedProcess(command, 2)

    monkeypatch.setattr(install, "pip", pip)
    monkeypatch.setattr(install.subprocess, "run", run)
    assert install.main(["-e", ".[test]"]) == 0
    assert calls[0] == ("pip", "install", "--quiet", "uv")
    assert calls[-2][:3] == ("uv", "pip", "install") and calls[-2][-2:] == ("-e", ".[test]")
    assert calls[-1] == ("pip", "install", "--quiet", "--no-compile", "-e", ".[test]")
