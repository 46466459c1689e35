"""The repository's own checks, run in CI with the tests: the import-layer contracts (import-linter, which also sees
imports inside functions), ruff, mypy on the typed public API, and the product/research boundary (no study's round
wording or benchmark paths inside the installed package, a README a newcomer reads)."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _tool(name):
    exe = BIN / name
    if exe.exists():
        return str(exe)
    found = shutil.which(name)
    if found is None:
        pytest.fail(f"{name} is not installed: it comes with dnarod[test] (pip install -e '.[test]')")
    return found


def _run(args):
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_import_layers_are_kept():
    """core -> physics -> engines -> run -> workflows -> cli, protocols above ensembles through their interface,
    engines independent of each other (contracts in pyproject.toml)."""
    r = _run([_tool("lint-imports"), "--no-cache"])
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert "0 broken" in r.stdout


def test_ruff_is_clean():
    r = _run([_tool("ruff"), "check", "--no-cache", "."])
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]


def test_mypy_is_clean_on_the_typed_api():
    r = _run([_tool("mypy"), "--no-incremental", "--cache-dir", "/dev/null"])
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert (ROOT / "dnarod" / "py.typed").is_file()


def _package_files():
    return [p for p in (ROOT / "dnarod").rglob("*") if p.is_file() and p.suffix in (".py", ".toml", ".h", ".cpp",
                                                                                   ".cu", ".cl", ".txt", ".md")]


def test_no_study_rounds_or_benchmark_paths_in_the_package():
    """Research lives in research/ and benchmarks/: the installed package names neither a study's rounds nor a
    benchmark's files."""
    bad = []
    for p in _package_files():
        text = p.read_text(errors="replace")
        for pattern in (r"\b[Rr]ound \d+", r"\bbenchmarks/", r"\b[Ii]ssue \d+", r"\b[Dd]esign (item )?[A-Z]\d"):
            for m in re.finditer(pattern, text):
                line = text.count("\n", 0, m.start()) + 1
                bad.append(f"{p.relative_to(ROOT)}:{line}: {m.group(0)}")
    assert not bad, "\n".join(bad[:40])


def test_readme_is_a_newcomers_page():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) < 300, f"README.md has {len(lines)} lines"
    text = "\n".join(lines)
    assert "python3 -m venv .venv" in text and ".venv/bin/python -m pytest" in text
    ci = (ROOT / ".ci" / "run").read_text()
    assert "python3 -m venv .venv && .venv/bin/pip install -q -e '.[test]' && .venv/bin/python -m pytest" in ci
    assert "python3 -m venv .venv && .venv/bin/pip install -q -e '.[test]' && .venv/bin/python -m pytest" in text
