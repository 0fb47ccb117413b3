"""Sphinx configuration of the openmm_alphaprk documentation.

Build from the repository root (after ``pip install -e ".[docs]"``)::

    sphinx-build -W --keep-going -b html docs docs/_build/html

The pages are Markdown (MyST); the API reference is generated from the package's
numpydoc docstrings. Nothing here needs the network.
"""

import re

import openmm_alphaprk

project = "openmm_alphaprk"
author = "openmm_alphaprk developers"
copyright = "2026, openmm_alphaprk developers"  # noqa: A001
version = openmm_alphaprk.__version__
release = openmm_alphaprk.__version__

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
# Data (docs/data/<page>/: JSON, logs, run tables), the sweep's configuration and the
# figures live beside the pages; they are linked, not built.
exclude_patterns = [
    "_build",
    "data",
    "sweeps",
    "figures",
]

myst_enable_extensions = ["dollarmath", "colon_fence"]
# Section links such as [text](compositions.md#on-a-gpu-cuda-on-an-h100) resolve to headings.
myst_heading_anchors = 4

autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "none"
autodoc_class_signature = "mixed"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

html_theme = "furo"
html_title = f"openmm_alphaprk {release}"


_LITERAL_OR_BAR = re.compile(r"(``.*?``)|(?<!\\)\|")


def _escape_bars(app, what, name, obj, options, lines):
    """Escape ``|`` outside literals: the docstrings write |x| for absolute values, not substitutions."""
    for i, line in enumerate(lines):
        lines[i] = _LITERAL_OR_BAR.sub(lambda m: m.group(1) or "\\|", line)


def setup(app):
    app.connect("autodoc-process-docstring", _escape_bars, priority=400)
