"""Sphinx configuration of granchain's documentation (build: ``bash scripts/docs.sh``)."""
from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "granchain"
author = "granchain authors"
copyright = "granchain authors"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "sphinxarg.ext",
    "generated",           # docs/_ext/generated.py: the reference pages built from the code
]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = "granchain"

autodoc_default_options = {"members": True, "undoc-members": True,
                           "member-order": "bysource"}
# Signatures and parameter lists show the annotations as written; they name numpy, pandas
# and granchain types that need no link.
autodoc_typehints = "signature"
autodoc_typehints_format = "short"
napoleon_numpy_docstring = True
napoleon_google_docstring = False

# Nitpicky: every cross-reference must resolve, except to libraries whose inventories
# the build does not fetch (it runs offline).
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(np|numpy|pd|pandas|numba|scipy|yaml|matplotlib|argparse|pathlib|os"
               r"|collections|typing|types|dataclasses|enum|io)(\..*)?"),
    (r"py:class", r"(Path|ndarray|DataFrame|Series|ArrayLike|NDArray|Callable|Iterable"
                  r"|Iterator|Sequence|Mapping|Any|Figure|Axes)"),
    # a dataclass signature keeps an unevaluated annotation in quotes, and Sphinx splits
    # 'tuple[tuple[str, Any], ...]' at its comma
    (r"py:class", r"tuple\[str"),
]



def _escape_bars(line: str) -> str:
    """|x| is an absolute value in granchain's docstrings, never an rST substitution."""
    parts = line.split("``")
    return "``".join(x if i % 2 else x.replace("|", "\\|") for i, x in enumerate(parts))


def plain_to_rst(lines: list[str]) -> list[str]:
    """granchain's docstrings are plain text: a "- " list may follow its paragraph
    directly, and a paragraph line may continue with a hanging indent. rST needs a blank
    line around a list and reads a deeper line as a block quote; this adds the blank lines
    and flattens hanging indents, leaving the words as written."""
    out: list[str] = []
    item = None         # indentation of the current list's "- ", or None outside a list
    para = None         # indentation of the current paragraph, or None after a blank line
    for line in map(_escape_bars, lines):
        text = line.lstrip()
        indent = len(line) - len(text)
        if not text:
            item = para = None
            out.append(line)
            continue
        if text.startswith(("- ", "* ")):
            if item != indent and out and out[-1].strip():
                out.append("")
            item, para = indent, indent + 2
            out.append(line)
            continue
        if item is not None and indent <= item:
            out.append("")                      # the list ended
            item, para = None, indent
        elif para is None:
            para = indent
        elif indent > para:
            line = " " * para + text            # a hanging indent: same paragraph
        out.append(line)
    return out


def setup(app):
    """Napoleon reads the first line of an attribute's or property's docstring as
    ``type: description``, so a property documented as "K of f = K delta^(3/2): ..." would
    get "K of f = K delta^(3/2)" as its type. granchain's properties are plain prose:
    napoleon handles functions, classes and modules only, after :func:`plain_to_rst`."""
    from sphinx.ext import napoleon

    event = "autodoc-process-docstring"
    for listener in list(app.events.listeners[event]):
        if listener.handler is napoleon._process_docstring:
            app.disconnect(listener.id)

    def process(app, what, name, obj, options, lines):
        lines[:] = plain_to_rst(lines)
        if what not in ("attribute", "data", "property"):
            napoleon._process_docstring(app, what, name, obj, options, lines)

    app.connect(event, process)
