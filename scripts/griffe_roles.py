"""A Griffe extension for the API pages: the docstrings' Sphinx markup read as Markdown.

The docstrings are written to be read in the source and in ``help()``: ``:func:`name``` roles
and ``::`` before a literal block. mkdocstrings renders docstrings as Markdown, where both
showed raw (about 95 roles); this turns a role into a code span of its name (the last part
where Sphinx would show only that: ``~pkg.Name``) and ``text::`` into ``text:``, the indented
block after it staying Markdown's code block. Loaded by ``mkdocs.yml``.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:func|class|meth|data|mod|attr|exc|obj):`(~?)([^`]+)`")
LITERAL = re.compile(r"::[ \t]*$", re.MULTILINE)


def markdown(text: str) -> str:
    """``text`` with its Sphinx roles as code spans and its ``::`` as ``:``."""

    def code(match: re.Match) -> str:
        short, name = match.groups()
        return f"`{name.rsplit('.', 1)[-1] if short else name}`"

    return LITERAL.sub(":", ROLE.sub(code, text))


class SphinxMarkup(griffe.Extension):
    """Every docstring of a loaded package read as Markdown (:func:`markdown`)."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        def convert(obj: griffe.Object) -> None:
            if obj.docstring is not None:
                obj.docstring.value = markdown(obj.docstring.value)
            for member in obj.members.values():
                if not member.is_alias:  # an import: converted where it is defined
                    convert(member)

        convert(pkg)
