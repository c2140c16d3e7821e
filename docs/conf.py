"""Sphinx configuration of the gpmultirate documentation.

Build (offline, warnings are errors)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
# document the working tree even when the package is not installed
sys.path.insert(0, str(DOCS.parent))
# plotting imports matplotlib; never open a window while importing it
os.environ.setdefault("MPLBACKEND", "Agg")

import sphinx.ext.autosummary as _autosummary  # noqa: E402

import gpmultirate  # noqa: E402

# autosummary's one-line summaries end at the first ". "; the docstrings cite
# "eq. 11" and "Fig. 5", which are not ends of sentences
if hasattr(_autosummary, "WELL_KNOWN_ABBREVIATIONS"):
    _autosummary.WELL_KNOWN_ABBREVIATIONS = tuple(
        dict.fromkeys((*_autosummary.WELL_KNOWN_ABBREVIATIONS, "eq.", "Fig."))
    )

# -- project -----------------------------------------------------------------
project = "gpmultirate"
author = "the gpmultirate developers"
copyright = "the gpmultirate developers, BSD-3-Clause"
release = gpmultirate.__version__
version = ".".join(release.split(".")[:2])

# -- extensions ----------------------------------------------------------------
# No intersphinx: the build must work without network access.  MathJax is
# bundled (copied into _static/mathjax) instead of loaded from a CDN, so the
# formulas render offline.
extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",
    "sphinx.ext.viewcode",
    "numpydoc",
]

templates_path = ["_templates"]
exclude_patterns = ["_build", "generated/*.md", "Thumbs.db", ".DS_Store"]
# generated/study.rst is pulled into results.rst with ``.. include::``; it is
# not a page of its own
exclude_patterns.append("generated/study.rst")
# so are the real-data benchmark's tables, into real_data.rst
exclude_patterns.append("generated/real_data_*.rst")
root_doc = "index"
default_role = "literal"
nitpicky = False

# -- autodoc / autosummary -------------------------------------------------------
autosummary_generate = True
autosummary_generate_overwrite = True
autosummary_imported_members = False
autosummary_ignore_module_all = False  # a module's public API is its __all__
# names that modules re-export from another module, documented there once
autosummary_context = {
    "reexported": {
        "gpmultirate.persistence": ["ModelFileError", "load_model", "save_model"],
        # the covariance layer's names, documented with gpmultirate.covariance
        "gpmultirate.inference": [
            "DataSpacePosterior", "GaussianCoefficients", "ParameterSpacePosterior",
            "PrecisionPosterior", "gaussian_samples", "inverse_from_cholesky", "log_gaussian",
            "robust_cholesky",
        ],
        "gpmultirate.noise": ["AR1Statistics", "dense_log_evidence", "dense_posterior"],
    },
}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # numpydoc sections carry the types
autodoc_inherit_docstrings = False

# -- numpydoc --------------------------------------------------------------------
# Methods and attributes come from the autosummary class template, not from
# numpydoc's member tables.
numpydoc_show_class_members = False
numpydoc_show_inherited_class_members = False
numpydoc_attributes_as_param_list = True
numpydoc_xref_param_type = False

# -- HTML ------------------------------------------------------------------------
html_theme = "alabaster"
html_title = f"gpmultirate {release}"
html_static_path: list[str] = []
html_theme_options = {
    "description": "Fast-rate impulse responses from slow-rate outputs",
    "fixed_sidebar": False,
    "page_width": "1100px",
    "sidebar_width": "230px",
}
html_sidebars = {"**": ["about.html", "navigation.html", "relations.html", "searchbox.html"]}

# -- the simulation-study table ------------------------------------------------------
STUDY = DOCS / "generated" / "study.rst"
STUDY_INCLUDE = ".. include:: generated/study.rst"
STUDY_STUB = """\
.. note::

   The table of this section has not been generated yet.  It comes from
   the command line, ``gpmultirate demo --runs 100 ...`` (see
   ``gpmultirate --help``), and appears here once it is saved as
   ``docs/generated/study.rst``.
"""


def _include_study(app, docname, source):
    """Replace the study include by a note while docs/generated/study.rst is missing."""
    if docname != "results":
        return
    app.env.note_dependency(str(STUDY))
    if not STUDY.is_file():
        source[0] = source[0].replace(STUDY_INCLUDE, STUDY_STUB)


EXAMPLES = DOCS.parent / "examples"
EXAMPLE_SOURCE = re.compile(
    r"^\.\. rubric:: (?P<name>\S+\.py)\n\n"
    r"\.\. literalinclude:: \.\./examples/(?P=name)\n(?:   :.*\n)*",
    re.MULTILINE,
)


def _existing_examples(app, docname, source):
    """Drop the source listing of example scripts not (yet) in examples/."""
    if docname != "examples":
        return
    missing = []

    def keep_or_drop(match):
        app.env.note_dependency(str(EXAMPLES / match["name"]))
        if (EXAMPLES / match["name"]).is_file():
            return match[0]
        missing.append(match["name"])
        return ""

    text = EXAMPLE_SOURCE.sub(keep_or_drop, source[0])
    if missing:
        listed = ", ".join(f"``{name}``" for name in missing)
        text += f"\nNot in the repository yet, so not shown: {listed}.\n"
    source[0] = text


def _skip_foreign_members(app, what, name, obj, skip, options):
    """Leave out members a class inherits from scikit-learn (documented there).

    ``get_params``, ``set_params``, ``theta``, ``clone_with_theta`` and the
    metadata-routing methods come from scikit-learn's base classes, whose
    docstrings refer to labels of scikit-learn's own documentation.
    """
    if what not in ("class", "exception"):
        return None
    target = getattr(obj, "fget", obj)  # a property's getter
    target = getattr(target, "__func__", target)  # a bound or class method
    module = getattr(target, "__module__", None) or ""
    if module.split(".")[0] == "sklearn":
        return True
    return None


def _public_bases(app, name, obj, options, bases):
    """Show public base classes: a private base is replaced by its own bases."""

    def public(classes):
        for cls in classes:
            if cls is object:
                continue
            if cls.__name__.startswith("_"):
                yield from public(cls.__bases__)
            else:
                yield cls

    shown = list(dict.fromkeys(public(list(bases))))
    bases[:] = shown or [object]


def setup(app):
    app.connect("autodoc-process-bases", _public_bases)
    app.connect("source-read", _include_study)
    app.connect("source-read", _existing_examples)
    app.connect("autodoc-skip-member", _skip_foreign_members)
