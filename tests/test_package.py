"""The project as a user installs it: every import a declared dependency, and a wheel in a
fresh virtual environment, used from a folder that is not the clone, with the families and the
real data inside the package."""

import ast
import importlib.metadata
import os
import re
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from pathlib import Path

from test_house import lazy_modules

ROOT = Path(__file__).parents[1]


PURELIB = "import sysconfig; print(sysconfig.get_path('purelib'))"


def run(*command, **options) -> subprocess.CompletedProcess:
    done = subprocess.run(
        [str(c) for c in command], capture_output=True, text=True, check=False, **options
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return done


def distribution(requirement: str) -> str:
    return re.split(r"[<>=!~\[ ;]", requirement, maxsplit=1)[0].lower().replace("_", "-")


EXTRA_MODULES: dict[str, str] = {}  # modules that are all about an extra's package


def test_every_import_of_the_package_is_a_declared_dependency():
    """What a fresh install must bring: a module-level import of the learner (``c2inet``)
    needs its package in ``dependencies``, one of ``sim`` or ``viz`` in those or the ``sim``
    extra; an optional extra (ray, tensorboard) may only be imported inside a function.
    Test-only packages count as neither (but in the fuzz targets, whose docstring says they
    need the ``test`` extra's hypothesis)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    learner = {distribution(r) for r in project["dependencies"]}
    testbed = learner | {distribution(r) for r in project["optional-dependencies"]["sim"]}
    extras = {
        distribution(r)
        for k, rs in project["optional-dependencies"].items()
        if k not in ("test", "sim")
        for r in rs
    }
    owners = importlib.metadata.packages_distributions()
    ours = {"sim", "c2inet", "viz"}
    wrong = []
    for path in sorted(p for package in ours for p in (ROOT / package).rglob("*.py")):
        # the learner needs only its dependencies; the world and the recorder the sim extra too
        required = learner if path.relative_to(ROOT).parts[0] == "c2inet" else testbed
        tree = ast.parse(path.read_text())
        in_functions = {
            id(inner)
            for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            for inner in ast.walk(node)
        }
        # an import guarded by `except ImportError` is optional: the module runs without it
        in_functions |= {
            id(inner)
            for node in ast.walk(tree)
            if isinstance(node, ast.Try)
            and any("ImportError" in ast.unparse(h.type or ast.Name("")) for h in node.handlers)
            for statement in node.body
            for inner in ast.walk(statement)
        }
        imports = []  # (module, imported at module level); a lazy module is paid on use
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                imports += [(a.name, id(node) not in in_functions) for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                imports.append((node.module, id(node) not in in_functions))
        imports += [(name, False) for name in lazy_modules(tree)]
        for name, at_module_level in imports:
            name = name.split(".")[0]
            if name in ours or name in sys.stdlib_module_names or name == "__future__":
                continue
            declared = {d.lower() for d in owners.get(name, [name])}
            if declared & required or (declared & (extras | testbed) and not at_module_level):
                continue
            if EXTRA_MODULES.get(str(path.relative_to(ROOT))) in declared:
                continue
            wrong.append(f"{path.relative_to(ROOT)}: {name}")
    assert not wrong, f"imports of undeclared packages: {wrong}"


def test_a_wheel_in_a_fresh_environment_generates_domains_anywhere(tmp_path, monkeypatch):
    """The wheel's own files and console scripts, from another folder. Its dependencies come
    from this environment (a path file; installing them again would copy 2 GB): CI's own
    install resolves them from scratch, and the test above proves they are declared."""
    monkeypatch.setenv("PIP_CACHE_DIR", str(tmp_path / "pip-cache"))  # nothing written in ~
    # built with this environment's setuptools (declared in the test extra): an isolated build
    # would install it again first
    wheel_of = (sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q")
    run(*wheel_of, "-w", tmp_path / "dist", ROOT)
    (wheel,) = (tmp_path / "dist").glob("c2i_testbed-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "sim/scenarios/crowd_noise.toml" in names
    assert "sim/scenarios/data/eth_ucy/hotel/val/biwi_eth_val.txt" in names
    assert "sim/scenarios/data/orca/radius_0.3_test.txt" in names
    assert "sim/studies/benchmark/tunings/radius.json" in names  # the shipped tunings
    assert any(n.endswith("LICENSE") for n in names)
    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", "--without-pip", venv)  # this pip installs into it
    site = Path(sysconfig.get_path("purelib"))  # this environment's packages, ours excepted
    fresh = Path(run(venv / "bin" / "python", "-c", PURELIB).stdout.strip())
    (fresh / "dependencies.pth").write_text(f"{site}\n")
    pip = (sys.executable, "-m", "pip", "--python", venv / "bin" / "python", "install", "-q")
    run(*pip, "--disable-pip-version-check", "--no-deps", "--no-compile", wheel)
    where = run(venv / "bin" / "python", "-c", "import sim; print(sim.__file__)", cwd=tmp_path)
    assert Path(where.stdout.strip()).is_relative_to(fresh)  # the wheel's copy, not the clone
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    listed = run(venv / "bin" / "c2i-run", "--list", "families", cwd=elsewhere)
    assert "crowd_radius" in listed.stdout and "eth_ucy" in listed.stdout
    # the wheel's files are what is tested here; numba compiling the kernels' fresh copy (10
    # CPU s) is test_jit's, so they run as plain Python on these few scenes
    no_jit = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    run(
        venv / "bin" / "c2i-generate",
        "--scenario",
        "crowd_noise_0.2+eth_ucy_eth",
        "--out",
        "out",
        "--workers",
        "1",
        *("--set", "data.splits.train=6", "--set", "data.splits.val=2"),  # a few scenes
        *("--set", "data.splits.test=2"),
        cwd=elsewhere,
        env=no_jit,
    )
    assert {p.name for p in (elsewhere / "out").glob("*.parquet")} == {
        "crowd_noise_0.2.parquet",
        "eth_ucy_eth.parquet",
    }
