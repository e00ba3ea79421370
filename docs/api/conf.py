"""Sphinx configuration of the API reference (``make docs``), built from the package's docstrings.

The user documentation is the Markdown in ``docs/*.md``; this folder holds only
the reference pages, one per subpackage. ``tests/test_docs_build.py`` builds it
with warnings as errors.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))     # the working tree's package, also without an editable install

import shapedisplay  # noqa: E402

project = "shapedisplay"
author = "shapedisplay contributors"
release = version = shapedisplay.__version__

extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]

# numpy-style sections (Parameters, Returns, ...) in the docstrings; no Google style
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# The types in the docstrings are prose ("(x, y) m", "(rows, cols) float64"), not Python names: rendered as
# written, not turned into cross-references word by word (words such as x, y or model name several objects).
napoleon_use_param = False
# "Options" (a pad model's own options) and "Attributes" (a record's fields) are laid out like "Parameters":
# one field list, types as written. Attributes as separate object entries would describe a property twice
# (RenderResult.events: its docstring and the class's list) and read "x, y : ..." as a type "x," of y.
napoleon_custom_sections = [("Options", "params_style"), ("Attributes", "params_style")]

autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "signature"
# The package annotates in the code, never in "# type:" comments; reading them compiles every object's source
# again (a third of the build). Sphinx 8.2+; older versions ignore the name.
autodoc_use_type_comments = False

# cross-references to names outside the package (numpy, pathlib, ...) are not checked
nitpicky = False

exclude_patterns = ["_build"]
html_theme = "alabaster"
html_title = f"shapedisplay {release} API reference"
html_static_path = []
