"""The documentation: the Sphinx site builds without a warning, and the README stays what a newcomer reads.

The build is the one of ``docs/conf.py``'s docstring (``sphinx-build -W -b html``), run on a copy of ``docs/`` (and
the top-level pages it includes) so that the API stubs autosummary generates are not written into the work tree.
"""
from __future__ import annotations

import importlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TOP_LEVEL_PAGES = ("ARCHITECTURE.md", "CONTRIBUTING.md", "CHANGELOG.md")


def _require(module):
    """The docs tools come with the ``test`` extra; under CI (``CI=true``) a missing one fails, elsewhere it skips."""
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        importlib.import_module(module)
    else:
        pytest.importorskip(module)


def test_sphinx_builds_without_warnings(tmp_path):
    for module in ("sphinx", "myst_parser", "numpydoc"):
        _require(module)
    src = tmp_path / "src"
    shutil.copytree(ROOT / "docs", src / "docs", ignore=shutil.ignore_patterns("_build", "generated"))
    for name in TOP_LEVEL_PAGES:
        shutil.copy(ROOT / name, src / name)
    out = tmp_path / "html"
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           str(src / "docs"), str(out)], capture_output=True, text=True, cwd=tmp_path, check=False)
    assert proc.returncode == 0, f"sphinx-build -W failed:\n{proc.stderr[-6000:]}"
    assert not proc.stderr.strip(), f"sphinx-build printed warnings:\n{proc.stderr[-6000:]}"
    # the user guide and every layer's API page are there, with the autodoc of a numpydoc docstring
    for page in ("index", "running", "supported", "validation", "api/core", "api/run", "api/workflows"):
        assert (out / f"{page}.html").exists(), page
    api = (out / "api" / "generated" / "dnarod.core.strains.html").read_text(encoding="utf-8")
    assert "Parameters" in api and "dnarod.core.strains" in api


def test_every_guide_page_is_in_the_toctree():
    index = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^([a-z_0-9/]+)\s*$", index, flags=re.MULTILINE))
    pages = {p.stem for p in (ROOT / "docs").glob("*.md")} - {"index"}
    assert pages <= listed, f"pages not in docs/index.md's toctree: {sorted(pages - listed)}"


def test_readme_is_short():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n < 300, f"README.md has {n} lines; reference material belongs in docs/"


def test_readme_validation_table_names_the_checks():
    """The README's table lists exactly the checks of ``dnarod validate``, with the quick ones marked as such."""
    from dnarod.validate import CHECKS, QUICK_CHECKS

    rows = re.findall(r"^\| `(\w+)` \| (yes|no) \|", README.read_text(encoding="utf-8"), flags=re.MULTILINE)
    assert sorted(name for name, _ in rows) == sorted(CHECKS)
    assert sorted(name for name, quick in rows if quick == "yes") == sorted(QUICK_CHECKS)


def test_readme_and_guide_links_resolve():
    """Relative links of the README and the guide point at files that exist (anchors are Sphinx's to check)."""
    missing = []
    for page in [README, *(ROOT / n for n in TOP_LEVEL_PAGES), *(ROOT / "docs").glob("*.md")]:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text(encoding="utf-8")):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = (page.parent / target.split("#")[0]).resolve()
            if not path.exists():
                missing.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not missing, missing


def test_validation_report_kept_for_the_readme():
    report = ROOT / "benchmarks" / "results" / "validation_quick" / "report.md"
    text = report.read_text(encoding="utf-8")
    assert text.startswith("# dnarod validation report (quick)")
    from dnarod.validate import QUICK_CHECKS

    for name in QUICK_CHECKS:
        assert f"| {name} |" in text, name
