"""The walk of one run: which of the project's functions a reader passes from the command line to
the libraries that do the work (argparse, Pymunk, torch's layers and optimiser, Rerun).

It runs ``python -m sim.run ARGS`` in this process under a profiler hook and, at every first call
from a project function into one of those libraries, keeps the project functions on the stack;
their union is the run's spine ("stops"), counted with the files that hold them. Run it on two
trees (a ``git worktree`` of an older commit) with the same arguments to compare one walk's
length where the work is the same; every other function the run executes is counted apart.

    python scripts/run_walk.py [--tree DIR] [--json FILE] -- --scenario crowd_noise_0.1..0.2 \\
        --methods finetune --quick --workers 1 --out /tmp/walk
"""

from __future__ import annotations

import argparse
import json
import os
import runpy
import sys
from collections.abc import Callable
from pathlib import Path

PACKAGES = ("sim", "c2inet", "viz")
# where the work is done, by a part of the library's file path
LIBRARIES = {
    "argparse": "argparse",
    "pymunk": "pymunk",
    "highway_env": "highway-env",
    "torch/nn": "torch layers",
    "torch/optim": "torch optimiser",
    "rerun": "rerun",
}


def walk(run: Callable[[], object], roots: tuple[str, ...], libraries: dict[str, str]) -> dict:
    """Run ``run`` under the hook; per library, the project functions (``file:qualname``, files
    under ``roots``) on the stack when the project first called into it from each function; and
    ``all``, every project function executed."""
    stacks: dict[str, set] = {name: set() for name in libraries.values()}
    executed: set = set()
    seen: set = set()

    def ours(code) -> bool:
        return code.co_filename.startswith(roots)

    def hook(frame, event, _arg) -> None:
        if event != "call":
            return
        code, caller = frame.f_code, frame.f_back
        if ours(code):
            executed.add(code)
            return
        if caller is None or not ours(caller.f_code):
            return
        library = next((n for part, n in libraries.items() if part in code.co_filename), None)
        if library is None or (library, caller.f_code) in seen:
            return
        seen.add((library, caller.f_code))
        while caller is not None:
            if ours(caller.f_code):
                stacks[library].add(caller.f_code)
            caller = caller.f_back

    sys.setprofile(hook)
    try:
        run()
    except SystemExit:
        pass
    finally:
        sys.setprofile(None)
    return {"all": executed, **stacks}


def named(codes: set, root: str) -> list[str]:
    return sorted(f"{os.path.relpath(c.co_filename, root)}:{c.co_qualname}" for c in codes)


def summary(found: dict, root: str) -> dict:
    """Stops and files per library, of the spine (their union) and of everything executed."""
    spine = set().union(*(v for k, v in found.items() if k != "all"))
    parts = {**{k: v for k, v in found.items() if k != "all"}, "spine": spine, "all": found["all"]}
    return {
        k: {"stops": len(v), "files": len({c.co_filename for c in v}), "names": named(v, root)}
        for k, v in parts.items()
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tree", type=Path, default=Path(__file__).resolve().parents[1])
    p.add_argument("--json", type=Path, help="also write every stop's name here")
    p.add_argument("args", nargs=argparse.REMAINDER, help="after --: sim.run's arguments")
    args = p.parse_args(argv)
    tree = str(args.tree.resolve())
    run_args = args.args[1:] if args.args[:1] == ["--"] else args.args
    roots = tuple(os.path.join(tree, package) + os.sep for package in PACKAGES)
    sys.path.insert(0, tree)
    sys.argv = ["sim.run", *run_args]
    found = walk(lambda: runpy.run_module("sim.run", run_name="__main__"), roots, LIBRARIES)
    result = summary(found, tree)
    for name, part in result.items():
        print(f"{name:>16}: {part['stops']:4d} stops in {part['files']:3d} files", file=sys.stderr)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
