"""Sphinx configuration of dnarod's documentation: the user guide (Markdown pages, MyST) and the API reference
(autodoc of the numpydoc docstrings, one autosummary page per layer).

Build (the docs test runs the same command; every warning is an error)::

    .venv/bin/sphinx-build -W -b html docs docs/_build/html

Cross-references are checked (``nitpicky = True`` below, as ``-n`` would).
"""
from __future__ import annotations

import importlib.metadata
import re
import warnings
from typing import ClassVar

project = "dnarod"
author = "the dnarod developers"
copyright = "the dnarod developers"
release = importlib.metadata.version("dnarod")
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "api/generated/*.rst.tmp", "**/.ipynb_checkpoints"]
templates_path = ["_templates"]

# MyST: GitHub-style tables, $math$, anchors for "#section" links within and across pages
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 4

# autodoc / autosummary: one stub page per module, generated at build time (api/generated, not committed)
autosummary_generate = True
autosummary_imported_members = False
# members defined in each module (a package's re-exports are documented in their own module, once); scipy's cKDTree,
# imported by dnarod.structure.findpair, is a Cython class that autodoc would otherwise try to describe there
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True,
                           "ignore-module-all": True, "exclude-members": "cKDTree"}
autodoc_member_order = "bysource"
# cross-references are checked (-n): names outside dnarod (no inventories are fetched: the build runs offline) and
# dnarod's private helpers (not part of the API pages) are not link targets
nitpicky = True
nitpick_ignore_regex = [
    ("py:.*", r"(numpy|scipy|openmm|numba|mdtraj|MDAnalysis|gemmi|click|dask|distributed|dask_jobqueue|pyarrow|"
              r"matplotlib|tqdm|logging|pymbar)(\..*)?"),
    ("py:.*", r"(.*\.)?_[A-Za-z]\w*"),
    ("py:.*", r"(.*\.)?_[A-Za-z]\w*\..*"),  # names in private modules (e.g. a base class's home)
    ("py:class", r"(Context|System|Platform|Integrator|Simulation|Force|Client|LocalCluster|SLURMCluster|Table)"),
    ("py:attr", r"context_class"),  # in click's docstring of Group.make_context, inherited by dnarod's group
]
autodoc_typehints = "none"  # numpydoc states the types in the Parameters sections

# numpydoc: members are listed by autodoc, not by numpydoc's own autosummary tables
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()
# numpydoc also reads the raw class docstring for the signature and says it does not know "Results" (the rendered
# page gets the section, as "Attributes", from _results_section below)
warnings.filterwarnings("ignore", message="Unknown section Results", category=UserWarning)

html_theme = "alabaster"
html_static_path: list[str] = []
html_title = f"dnarod {release}"


_LITERAL = re.compile(r"(``.+?``|`[^`]+`)")


def _escape_bars(app, what, name, obj, options, lines):
    """Docstrings write absolute values and norms as plain text (``|x|``, ``|sigma|``); reStructuredText would read
    ``|...|`` as a substitution. Escape every ``|`` outside inline literals and interpreted text (the package's
    docstrings hold no reStructuredText tables or line blocks)."""
    for i, line in enumerate(lines):
        if "|" in line:
            parts = _LITERAL.split(line)
            lines[i] = "".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


def _results_section(lines):
    """The analyses document ``.results`` (the MDAnalysis pattern) in a "Results" section, which numpydoc does not
    know (it would drop it): render it as "Attributes" with the names prefixed ``results.``."""
    i = 0
    while i + 1 < len(lines):
        head, rule = lines[i], lines[i + 1]
        if head.strip() == "Results" and rule.strip() and set(rule.strip()) == {"-"}:
            indent = head[: len(head) - len(head.lstrip())]
            lines[i], lines[i + 1] = indent + "Attributes", indent + "-" * len("Attributes")
            j = i + 2
            while j < len(lines):
                line = lines[j]
                nxt = lines[j + 1] if j + 1 < len(lines) else ""
                if line.strip() and nxt.strip() and set(nxt.strip()) == {"-"}:
                    break  # the next section
                if line.strip() and line[: len(indent) + 1].strip() and line.startswith(indent):
                    names, sep, rest = line[len(indent):].partition(" : ")
                    names = ", ".join("results." + n.strip() for n in names.split(","))
                    lines[j] = indent + names + sep + rest
                j += 1
            i = j
        else:
            i += 1


def _process(app, what, name, obj, options, lines):
    _results_section(lines)
    _escape_bars(app, what, name, obj, options, lines)


def _cache_numpydoc_template():
    """numpydoc builds a new Jinja environment, and compiles its docstring template, for every docstring it renders
    (about a third of this build's time); compile it once. Rendering is unchanged."""
    try:
        import numpydoc.docscrape_sphinx as ds
    except ImportError:  # pragma: no cover - numpydoc is in the test extra
        return
    base = getattr(ds, "SandboxedEnvironment", None)
    if base is None or getattr(base, "_dnarod_cached", False):
        return

    class CachedEnvironment(base):
        _dnarod_cached = True
        _templates: ClassVar[dict] = {}

        def get_template(self, name, *args, **kwargs):
            if name not in self._templates:
                self._templates[name] = super().get_template(name, *args, **kwargs)
            return self._templates[name]

    ds.SandboxedEnvironment = CachedEnvironment


def _resolve_reexports(app, env, node, contnode):
    """Resolve a Python cross-reference that names an object where it is imported rather than where it is defined
    (``dnarod.run.RunSpec``; an unqualified ``RunSpec`` inside a module that imports it): the API pages document each
    object once, in its defining module. Returns None (a real missing reference) when no documented object fits."""
    import importlib

    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    candidates = [target]
    module = node.get("py:module")
    cls = node.get("py:class")
    if module and target.startswith("."):
        candidates.append(module.rsplit(".", 1)[0] + target)
    elif module and not target.startswith("dnarod."):
        candidates += [f"{module}.{cls}.{target}" if cls else None, f"{module}.{target}"]
    domain = env.get_domain("py")
    for name in filter(None, candidates):
        parts = name.split(".")
        for i in range(len(parts) - 1, 0, -1):
            try:
                obj = importlib.import_module(".".join(parts[:i]))
            except ImportError:
                continue
            try:
                for attr in parts[i:]:
                    obj = getattr(obj, attr)
            except AttributeError:
                break
            real = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
            if None in real and hasattr(obj, "__name__") and isinstance(obj, type(importlib)):
                real = (obj.__name__, None)
            full = ".".join(p for p in real if p)
            if full and full in domain.objects:
                return domain.resolve_xref(env, node["refdoc"], app.builder, "obj", full, node, contnode)
            break
    return None


def setup(app):
    _cache_numpydoc_template()
    app.connect("missing-reference", _resolve_reexports)
    app.connect("autodoc-process-docstring", _process, priority=400)
