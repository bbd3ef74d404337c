"""``scripts/run_walk.py``: the spine of a run is the project functions on the stack when the
project calls into a library; what runs beside the path is counted apart."""

import sys


def test_the_spine_holds_the_path_to_a_library_and_not_what_runs_beside_it(script, tmp_path):
    walker = script("scripts/run_walk.py")
    package = tmp_path / "planted"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "calls.py").write_text(
        "import json\n\n"
        "def side():\n    return 1\n\n"
        "def inner():\n    return json.dumps([side()])\n\n"
        "def outer():\n    side()\n    return inner()\n"
    )
    sys.path.insert(0, str(tmp_path))
    try:
        from planted import calls

        found = walker.walk(calls.outer, (str(package) + "/",), {"json": "json"})
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("planted.calls", None)
        sys.modules.pop("planted", None)
    result = walker.summary(found, str(tmp_path))
    assert result["spine"]["names"] == ["planted/calls.py:inner", "planted/calls.py:outer"]
    assert result["spine"]["files"] == 1
    assert result["all"]["names"] == [
        "planted/calls.py:inner", "planted/calls.py:outer", "planted/calls.py:side"
    ]  # fmt: skip
