"""The house rules of DESIGN.md, checked: imports point one way (``sim`` -> ``viz`` -> ``c2inet``);
inside ``sim``, floors (the world, then the engine ``sim.experiment``, then the studies, then
the commands) import only downwards, with no circle; and the learner, with its tests, loads and
trains without the simulators or the recorder."""

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
FORBIDDEN = {
    "c2inet": {"sim", "viz", "pymunk", "highway_env", "gymnasium", "rerun", "matplotlib", "ray"},
    "viz": {"sim", "pymunk", "highway_env", "gymnasium", "ray"},
}


def lazy_modules(tree: ast.AST) -> set[str]:
    """The modules a file declares with ``lazy_module("NAME")``: imports, paid on first use."""
    return {
        node.args[0].value
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and getattr(node.func, "id", None) == "lazy_module"
        and node.args
        and isinstance(node.args[0], ast.Constant)
    }


def imported(path: Path) -> set[str]:
    """Top-level names of every module ``path`` imports, wherever in the file, lazily too."""
    tree = ast.parse(path.read_text())
    names = {name.split(".")[0] for name in lazy_modules(tree)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_imports_point_one_way(package):
    for path in sorted((ROOT / package).rglob("*.py")):
        wrong = imported(path) & FORBIDDEN[package]
        assert not wrong, f"{path.relative_to(ROOT)} imports {sorted(wrong)}"


def test_the_kernels_room_has_no_arrow_up():
    """``c2inet/kernels`` (STGAT's fast kernels) imports nothing of the learner but itself and
    numba's cache options (``c2inet.jit``): the network uses the kernels, never the reverse, and
    nothing in the room registers."""
    allowed = ("c2inet.kernels", "c2inet.jit")
    for path in sorted((ROOT / "c2inet" / "kernels").rglob("*.py")):
        tree = ast.parse(path.read_text())
        modules = {f"{n.module}.{a.name}" for n in ast.walk(tree)
                   if isinstance(n, ast.ImportFrom) and n.module for a in n.names}  # fmt: skip
        modules |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        ours = {m for m in modules if m.split(".")[0] == "c2inet"}
        assert all(m.startswith(allowed) for m in ours), f"{path.name} imports {sorted(ours)}"
        calls = {getattr(n.func, "attr", getattr(n.func, "id", "")) for n in ast.walk(tree)
                 if isinstance(n, ast.Call)}  # fmt: skip
        assert not calls & {"register", "enrol", "add_entry"}, f"{path.name} registers"


COMMANDS = {
    *("sim.run", "sim.sweep", "sim.bench", "sim.generate", "sim.study", "sim.cli"),
    "sim.config_file",
}
FLOOR_NAMES = ("the world", "the engine", "the studies", "the commands")


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def floor(module: str) -> int:
    """0 the world (scenario language, families, generators, data, io, statistics), 1 the
    engine, 2 the studies, 3 the commands and their shared options."""
    if module in COMMANDS:
        return 3
    if module.startswith("sim.studies"):
        return 2
    if module.startswith("sim.experiment"):
        return 1
    return 0


def sim_imports(path: Path) -> set[str]:
    """The ``sim`` modules ``path`` imports, wherever in the file (a name imported from a
    package that is a module of it counts as that module; a lazy module counts)."""
    tree = ast.parse(path.read_text())
    found = {name for name in lazy_modules(tree) if name.split(".")[0] == "sim"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "sim"}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("sim"):
            for alias in node.names:
                inner = f"{node.module}.{alias.name}"
                is_module = (ROOT / inner.replace(".", "/")).with_suffix(".py").exists()
                found.add(inner if is_module else node.module)
    return found


def sim_graph() -> dict[str, set[str]]:
    """Module -> the sim modules it imports; the package facade ``sim/__init__.py``, which
    re-exports the engine's names lazily, is left out."""
    paths = [p for p in (ROOT / "sim").rglob("*.py") if p != ROOT / "sim" / "__init__.py"]
    return {module_name(p): sim_imports(p) - {"sim"} for p in paths}


def test_sim_floors_import_only_downwards():
    graph = sim_graph()
    assert {m for m in graph if floor(m) == 1} >= {"sim.experiment.outputs", "sim.experiment.sweep"}
    assert "sim.experiment.sweep" in graph["sim.studies.reproduce"]  # declared lazily there
    for module, imports in sorted(graph.items()):
        for target in sorted(imports):
            assert floor(target) <= floor(module), (
                f"{module} ({FLOOR_NAMES[floor(module)]}) imports {target} "
                f"({FLOOR_NAMES[floor(target)]})"
            )


def test_sim_has_no_import_circle():
    graph = sim_graph()
    state: dict[str, int] = {}  # 1 on the current path, 2 done

    def visit(module: str, path: list[str]) -> None:
        state[module] = 1
        for target in sorted(graph.get(module, ())):
            assert state.get(target) != 1, "circle: " + " -> ".join([*path, module, target])
            if target not in state:
                visit(target, [*path, module])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [])


BLOCKER = """
import sys

BLOCKED = {"sim", "viz", "pymunk", "highway_env", "gymnasium", "rerun"}
BLOCKED |= {"matplotlib", "pyarrow", "numba", "optuna", "yaml"}  # the sim extra's


class Blocker:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"{name} is blocked: the learner must not need it")


sys.meta_path.insert(0, Blocker())
"""


def test_the_learner_and_its_tests_load_and_train_without_the_simulators(tmp_path):
    """Every learner test module imports with the simulators, the recorder and the rest of
    the ``sim`` extra blocked (their collection; numba too: STGAT then runs its tensor
    kernels), and a continual run trains there (the determinism test), in one pytest
    process. The static check above covers imports inside functions, so the learner's suite
    need not run twice."""
    (tmp_path / "block_simulators.py").write_text(BLOCKER)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-x",
            "-rP",
            "-p",
            "block_simulators",
            "tests/c2inet",
        ]
        + ["-k", "test_same_seed_same_training_on_cpu"],
        cwd=ROOT,
        env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:]
    summary = done.stdout.strip().splitlines()[-1]
    assert re.search(r"^1 passed, (1 skipped, )?\d+ deselected", summary), summary  # no numba
    assert "numba cannot be imported" in done.stdout + done.stderr  # the tensor kernels trained
    assert "error" not in summary, summary


def test_a_command_without_the_sim_extra_says_what_to_install_in_one_line():
    """A learner-only install (``pip install c2i-testbed``): a command of the testbed is one line
    naming the extra, exit code 2; importing ``sim`` from Python is an ImportError saying it."""
    probe = "import runpy, sys\nsys.modules['pymunk'] = None\nsys.argv = {argv!r}\n{body}\n"
    command = probe.format(argv=["-m"], body="runpy.run_module('sim.run', run_name='__main__')")
    done = subprocess.run([sys.executable, "-c", command], capture_output=True, text=True)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.strip() == (
        "error: the simulators and the recorder are not installed (no pymunk): "
        "pip install 'c2i-testbed[sim]'"
    )
    library = probe.format(argv=["script.py"], body="import sim")
    done = subprocess.run([sys.executable, "-c", library], capture_output=True, text=True)
    assert "ImportError: the simulators and the recorder are not installed" in done.stderr


MAX_FILE_LINES, MAX_FUNCTION_LINES = 400, 60


def oversized(source: str, name: str) -> list[str]:
    """What of ``source`` breaks the size bars: the file over 400 lines, a function over 60."""
    found = []
    lines = len(source.splitlines())
    if lines > MAX_FILE_LINES:
        found.append(f"{name}: {lines} lines")
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            length = node.end_lineno - node.lineno + 1
            if length > MAX_FUNCTION_LINES:
                found.append(f"{name}:{node.lineno} {node.name}: {length} lines")
    return found


def test_no_module_or_function_outgrows_the_size_bars():
    """Every module of the packages at most 400 lines, every function at most 60; the check
    itself fails a planted 61-line function."""
    planted = "def long():\n" + "    x = 1\n" * 59 + "    return x\n"
    assert oversized(planted, "planted") == ["planted:1 long: 61 lines"]
    assert oversized(planted.replace("    x = 1\n", "", 1), "planted") == []
    found = [
        problem
        for package in ("c2inet", "sim", "viz")
        for path in sorted((ROOT / package).rglob("*.py"))
        for problem in oversized(path.read_text(), str(path.relative_to(ROOT)))
    ]
    assert not found, found


FUNCTION_IMPORTS = 20  # issue 63: 133 then; these are optional extras, PEP 562 and the like


def function_imports(source: str, where: str) -> list[str]:
    """``where:LINE function`` for each import inside a function body of ``source``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            found += [
                f"{where}:{sub.lineno} {node.name}"
                for sub in ast.walk(node)
                if isinstance(sub, ast.Import | ast.ImportFrom)
            ]
    return found


def test_dependencies_are_declared_at_the_top_of_their_module():
    """A module's imports stand at its top (heavy ones as ``lazy_module``, paid on first use);
    inside a function only what must be (an optional extra's check, PEP 562's ``__getattr__``),
    and the check itself counts a planted one."""
    assert function_imports("def f():\n    import json\n", "planted") == ["planted:2 f"]
    found = [
        problem
        for package in ("c2inet", "sim", "viz")
        for path in sorted((ROOT / package).rglob("*.py"))
        for problem in function_imports(path.read_text(), str(path.relative_to(ROOT)))
    ]
    assert len(found) <= FUNCTION_IMPORTS, "\n".join(found)
