"""Every code example of the README, the user guide (docs/*.md) and the package's docstrings runs.

* ```python blocks of README.md and docs/*.md: the blocks of one file run in order in one namespace (a later block
  may use an earlier one's names), in a fresh folder holding links to the repository's ``data/`` and
  ``examples/``, so relative paths such as ``data/structures/355D.pdb`` work as from the repository root.
* ```bash blocks of README.md: each line is a ``dnarod`` command (comments and line continuations allowed), run
  in-process through the click group (no interpreter start-up per command) in the same kind of folder; each
  must exit with status 0.
* doctests (``>>>``) in the package's docstrings, run in such a folder too.

A block that must not run (the two set-up commands, a cluster's address) is marked by the line
``<!-- no-test -->`` right before its opening fence; the marker is used sparingly and each use is listed by
:func:`test_no_test_markers_are_few`. The examples are written small (tens of base pairs, tens of ps) so this
file stays fast.
"""
from __future__ import annotations

import doctest
import importlib
import os
import pkgutil
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MARKER = "<!-- no-test -->"
FENCE = re.compile(r"^```(\w+)\s*$")
DOC_FILES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))


def code_blocks(path, language):
    """``[(line number, code, skipped)]`` of the fenced blocks of ``language`` in a Markdown file."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m is None:
            i += 1
            continue
        lang, start = m.group(1), i
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        if lang == language:
            k = start - 1
            while k >= 0 and not lines[k].strip():
                k -= 1
            skipped = k >= 0 and lines[k].strip() == MARKER
            out.append((start + 1, "\n".join(lines[start + 1:j]), skipped))
        i = j + 1
    return out


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A fresh folder that looks like the repository root to relative paths in the examples."""
    for name in ("data", "examples"):
        (tmp_path / name).symlink_to(ROOT / name, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    return tmp_path


PY_FILES = [p for p in DOC_FILES if any(not s for _, _, s in code_blocks(p, "python"))]


@pytest.mark.parametrize("path", PY_FILES, ids=[p.relative_to(ROOT).as_posix() for p in PY_FILES])
def test_python_blocks(path, workdir):
    namespace = {"__name__": "__example__"}
    for line, code, skipped in code_blocks(path, "python"):
        if skipped:
            continue
        try:
            exec(compile(code, f"{path.name}:{line}", "exec"), namespace)  # noqa: S102 (running the examples is the test)
        except Exception as exc:  # name the block that failed
            raise AssertionError(f"{path.relative_to(ROOT)}, python block at line {line}: "
                                 f"{type(exc).__name__}: {exc}") from exc


def command_lines(code):
    """The commands of a bash block: comments dropped, continuation lines joined; each split like a shell."""
    joined = re.sub(r"\\\n", " ", code)
    cmds = []
    for raw in joined.splitlines():
        words = shlex.split(raw, comments=True)
        if words:
            cmds.append(words)
    return cmds


README_BASH = [(line, code) for line, code, skipped in code_blocks(ROOT / "README.md", "bash") if not skipped]


def test_readme_bash_blocks(workdir):
    from click.testing import CliRunner

    from dnarod.cli.main import main

    assert README_BASH, "the README has runnable bash blocks"
    runner = CliRunner()
    for line, code in README_BASH:
        for words in command_lines(code):
            assert words[0] == "dnarod", f"README.md bash block at line {line}: only dnarod commands run: {words}"
            res = runner.invoke(main, words[1:], catch_exceptions=True)
            assert res.exit_code == 0, (f"README.md bash block at line {line}: `{shlex.join(words)}` exited "
                                        f"{res.exit_code}: {res.output[-2000:]}"
                                        + (f" {type(res.exception).__name__}: {res.exception}" if res.exception
                                           and not isinstance(res.exception, SystemExit) else ""))


def test_no_test_markers_are_few():
    """The no-test marker is for blocks that cannot run here (set-up commands, a cluster); keep it rare."""
    marked = {p.relative_to(ROOT).as_posix(): sum(s for _, _, s in code_blocks(p, lang))
              for p in DOC_FILES for lang in ("python", "bash")}
    total = sum(marked.values())
    assert code_blocks(ROOT / "README.md", "bash")[0][2] and code_blocks(ROOT / "README.md", "bash")[1][2], \
        "the two set-up commands are the README's first two bash blocks, marked no-test"
    assert total <= 6, f"{total} blocks marked {MARKER}: {marked}"


def _modules_with_doctests():
    import dnarod

    names = []
    for info in pkgutil.walk_packages(dnarod.__path__, "dnarod."):
        if "._" in info.name:
            continue
        spec = importlib.util.find_spec(info.name)
        if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
            continue
        if ">>>" in Path(spec.origin).read_text(encoding="utf-8"):
            names.append(info.name)
    return names


DOCTEST_MODULES = _modules_with_doctests()


@pytest.mark.parametrize("name", DOCTEST_MODULES)
def test_docstring_examples(name, workdir):
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    tests = [t for t in finder.find(module) if t.examples]
    assert tests, f"{name} holds '>>>' but no doctest was found"
    for t in tests:
        runner.run(t)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} docstring examples of {name} failed"


def test_docstring_examples_are_doctests():
    """A docstring's code example is a doctest (``>>>``), so that the test above runs it; no ``Example::``
    literal blocks of Python that nothing runs."""
    import dnarod

    offenders = []
    for py in Path(dnarod.__file__).parent.rglob("*.py"):
        text = py.read_text(encoding="utf-8")
        for m in re.finditer(r"^\s*(Example|Examples|Python|Usage)::\s*$", text, flags=re.MULTILINE):
            offenders.append(f"{py.relative_to(ROOT)}:{text[:m.start()].count(chr(10)) + 1}")
    assert not offenders, f"literal Python examples that no test runs (write them as doctests): {offenders}"


def test_examples_run_in_a_fresh_folder(workdir):
    assert Path(os.getcwd()) == workdir and (workdir / "data" / "structures" / "355D.pdb").exists()
