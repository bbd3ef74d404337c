"""``lazy_module``: a module declared at the top and imported on its first attribute read."""

import sys

import pytest

from c2inet.lazy import lazy_module


def test_a_lazy_module_imports_on_its_first_read_and_is_then_the_module(tmp_path, monkeypatch):
    """Nothing loads at the declaration, not even the parent package of a submodule (which
    ``importlib``'s LazyLoader would import to find the spec); the first read imports it."""
    package = tmp_path / "planted_heavy"
    package.mkdir()
    (package / "__init__.py").write_text("LOADED = True\n")
    (package / "part.py").write_text("def answer():\n    return 42\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    part = lazy_module("planted_heavy.part")
    assert "planted_heavy" not in sys.modules and "planted_heavy.part" not in sys.modules
    assert part.answer() == 42
    assert sys.modules["planted_heavy"].LOADED and "answer" in dir(part)
    import planted_heavy.part

    assert part.answer is planted_heavy.part.answer
    for name in ("planted_heavy.part", "planted_heavy"):
        monkeypatch.delitem(sys.modules, name)


def test_a_missing_lazy_module_fails_where_it_is_first_used():
    missing = lazy_module("no_such_module_here")
    with pytest.raises(ModuleNotFoundError, match="no_such_module_here"):
        _ = missing.anything
