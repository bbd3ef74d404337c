"""The docs site's API pages: the docstrings' Sphinx markup is read as Markdown, so no role or
``::`` shows raw (``scripts/griffe_roles.py``, loaded by ``mkdocs.yml``)."""

import re
from pathlib import Path

import griffe
import pytest

ROOT = Path(__file__).parents[1]
EXTENSION = "scripts/griffe_roles.py:SphinxMarkup"


def test_roles_become_code_spans_and_literal_markers_colons():
    import importlib.util

    spec = importlib.util.spec_from_file_location("griffe_roles", ROOT / EXTENSION.split(":")[0])
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    markdown = module.markdown
    assert markdown("see :func:`c2inet.x` and :class:`~c2inet.registry.Registry`.") == (
        "see `c2inet.x` and `Registry`."
    )
    assert markdown("From a notebook::\n\n    run()\nnot :: here") == (
        "From a notebook:\n\n    run()\nnot :: here"
    )


@pytest.mark.parametrize("package", ["c2inet", "sim", "viz"])
def test_the_api_pages_load_no_raw_sphinx_markup(package, monkeypatch):
    monkeypatch.chdir(ROOT)  # the path as mkdocs.yml gives it
    assert EXTENSION in (ROOT / "mkdocs.yml").read_text()
    loaded = griffe.load(package, extensions=griffe.load_extensions(EXTENSION))
    raw = re.compile(r":(func|class|meth|data|mod|attr|exc):`|::\s*$", re.MULTILINE)
    seen = 0

    def walk(obj):
        nonlocal seen
        if obj.is_alias:
            return
        if obj.docstring is not None:
            seen += 1
            assert not raw.search(obj.docstring.value), f"{obj.path}: {obj.docstring.value[:200]}"
        for member in obj.members.values():
            walk(member)

    walk(loaded)
    assert seen > 20  # the walk read the package's docstrings
