"""Numba's cache never stops a command: none where none can be written, a damaged one rebuilt
(issue 64's first case). Each test runs compiled kernels in a fresh process, as a user would:
STGAT's graph attention forwards and back (the training steps of the learner's tests take the
same cache)."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
# the graph attention forwards and back: three compiled functions
STEP = """
import torch
from c2inet.kernels.attention import attend
g = torch.Generator().manual_seed(0)
h = torch.randn(2, 5, 2, 4, generator=g, requires_grad=True)
a_src, a_dst = torch.randn(2, 2, 4, generator=g).unbind(0)
out = attend(h, a_src.requires_grad_(), a_dst.requires_grad_(), torch.tensor([0, 2, 5]), 3)
out.square().sum().backward()
print("attend", out.sum().item(), h.grad.sum().item(), a_src.grad.sum().item())
"""


def step(env: dict, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess:
    command = [*prefix, sys.executable, "-c", STEP]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=300, cwd=ROOT)


def base_env(tmp_path: Path) -> dict:
    return {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "PYTHONPATH": str(ROOT)}


def test_a_damaged_cache_is_rebuilt_with_one_note(tmp_path):
    """Truncated, random and swapped cache files: the work gives the same numbers, saying which
    file was damaged (once a file), and writes the cache anew."""
    env = {**base_env(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    first = step(env)
    assert first.returncode == 0, first.stderr
    (kernels,) = (tmp_path / "numba").glob("kernels_*")
    index, *_ = sorted(kernels.glob("*.nbi"))
    index.write_bytes(index.read_bytes()[:7])  # truncated
    data = sorted(kernels.glob("*.nbc"))
    data[0].write_bytes(b"\x80\x05not a pickle at all")  # random
    a, b = data[1].read_bytes(), data[2].read_bytes()
    data[1].write_bytes(b)  # two functions' files swapped
    data[2].write_bytes(a)
    damaged = step(env)
    assert damaged.returncode == 0, damaged.stderr
    assert damaged.stdout == first.stdout and first.stdout.startswith("attend ")
    assert "numba's cache" in damaged.stderr and "is damaged" in damaged.stderr


def _read_only_namespace() -> bool:
    if not shutil.which("unshare"):
        return False
    probe = ["unshare", "-m", "sh", "-c", "mount -t tmpfs -o ro tmpfs /mnt"]
    return subprocess.run(probe, capture_output=True).returncode == 0


@pytest.mark.skipif(not _read_only_namespace(), reason="needs unshare -m and mount (root)")
def test_a_read_only_install_and_home_compile_without_a_cache(tmp_path):
    """The package folder and HOME read-only (a bind mount in a private mount namespace): the
    compiled work runs without a cache, with one note saying so."""
    home = tmp_path / "home"
    home.mkdir()
    mounts = (
        f"mount --bind {ROOT} {ROOT} && mount -o remount,bind,ro {ROOT} && "
        f'mount --bind {home} {home} && mount -o remount,bind,ro {home} && exec "$@"'
    )
    env = {**base_env(home), "PYTHONDONTWRITEBYTECODE": "1"}
    done = step(env, ("unshare", "-m", "sh", "-c", mounts, "sh"))
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("attend ")
    assert done.stderr.count("numba cannot write a cache here") == 1


def test_without_numba_auto_is_the_tensor_kernels_said_once_and_compiled_is_refused(
    monkeypatch, capsys
):
    """Where numba cannot be imported (``jit.MISSING`` says why), ``auto`` resolves to the
    tensor kernels with one note a process, and ``compiled`` is refused in one line. (That the
    learner then trains is the house test's: it blocks numba with the whole sim extra.)"""
    from c2inet import jit, kernels

    monkeypatch.setattr(jit, "MISSING", "ImportError: numba is blocked")
    monkeypatch.setattr(jit, "_said", set())
    assert kernels.resolve("auto", "cpu") == kernels.resolve("auto", "cpu") == "tensor"
    assert capsys.readouterr().err.count("numba cannot be imported") == 1
    with pytest.raises(ValueError, match="'compiled' needs numba"):
        kernels.resolve("compiled", "cpu")
