"""The project as a user installs it: a wheel, in a fresh virtual environment, used from a folder
that is not the clone. The families and the real data ship inside the package."""

import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).parents[1]


def run(*command, **options) -> subprocess.CompletedProcess:
    done = subprocess.run(
        [str(c) for c in command], capture_output=True, text=True, check=False, **options
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return done


def test_a_wheel_in_a_fresh_environment_generates_domains_anywhere(tmp_path, monkeypatch):
    monkeypatch.setenv("PIP_CACHE_DIR", str(tmp_path / "pip-cache"))  # nothing written in ~
    run(sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", tmp_path / "dist", ROOT)
    (wheel,) = (tmp_path / "dist").glob("c2i_testbed-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "sim/scenarios/crowd_noise.toml" in names
    assert "sim/scenarios/data/eth_ucy/hotel/val/biwi_eth_val.txt" in names
    assert "sim/scenarios/data/orca/radius_0.3_test.txt" in names
    assert any(n.endswith("LICENSE") for n in names)
    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", venv)
    pip = (venv / "bin" / "python", "-m", "pip", "install", "-q", "--disable-pip-version-check")
    run(*pip, "--no-compile", wheel)  # no .pyc of every dependency up front: half the time
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    listed = run(venv / "bin" / "c2i-run", "--list", "families", cwd=elsewhere)
    assert "crowd_radius" in listed.stdout and "eth_ucy" in listed.stdout
    run(
        venv / "bin" / "c2i-generate",
        "--scenario",
        "crowd_radius_0.2+eth_ucy_eth",
        "--out",
        "out",
        "--workers",
        "1",
        cwd=elsewhere,
    )
    assert {p.name for p in (elsewhere / "out").glob("*.parquet")} == {
        "crowd_radius_0.2.parquet",
        "eth_ucy_eth.parquet",
    }
