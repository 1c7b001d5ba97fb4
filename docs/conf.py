"""Sphinx configuration: API reference from the numpydoc docstrings, methods pages in Markdown."""

from importlib.metadata import version as _version

project = "prismbatch"
author = "prismbatch developers"
release = _version("prismbatch")
extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "numpydoc", "myst_parser"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build"]
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
autosummary_generate = False
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]
html_theme = "alabaster"
html_title = f"prismbatch {release}"
