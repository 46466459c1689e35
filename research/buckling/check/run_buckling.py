"""Run the buckling check into a report folder: ``results.json`` (the check's result), ``report.md`` (its headline)
and ``buckling.png``.

    python research/buckling/check/run_buckling.py OUT [--quick] [KEY=VALUE ...]

KEY=VALUE are keywords of :func:`buckling_check.check_buckling` (values read as Python literals, e.g.
``time_ns=300 ring_seed=7 bracket=True post_turns=(2.567,3.594) nonbonded={'charge':'manning'}``). The members
live in ``OUT/buckling_members`` unless ``member_root=...`` is given; a rerun into OUT reuses them. Exit status 0
if the check passed, 1 if it failed, 2 on bad input (one line).
"""
from __future__ import annotations

import ast
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def parse_options(items):
    """``["time_ns=300", "bracket=True"]`` -> ``{"time_ns": 300, "bracket": True}`` (values as Python literals,
    else as strings)."""
    opts = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.isidentifier():
            raise SystemExit(f"run_buckling.py: error: {item!r}: give options as KEY=VALUE")
        try:
            opts[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            opts[key] = value
    return opts


def main(argv=None):
    import argparse

    from dnarod.core.errors import DnarodError
    from dnarod.core.io import jsonable, write_text_atomic

    from buckling_check import check_buckling, headline

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--quick", action="store_true", help="400 bp, 2-ns members (gates on the pre-buckling law only)")
    ap.add_argument("options", nargs="*", help="KEY=VALUE keywords of check_buckling")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        res = check_buckling(out, quick=a.quick, **parse_options(a.options))
    except (DnarodError, TypeError) as exc:
        print(f"run_buckling.py: error: {exc}", file=sys.stderr)
        return 2
    measured, tolerance = headline(res)
    write_text_atomic(out / "results.json", json.dumps(jsonable(res), indent=1) + "\n")
    write_text_atomic(out / "report.md", f"# Buckling check: {'passed' if res['passed'] else 'FAILED'}\n\n"
                                         f"- measured: {measured}\n- tolerance: {tolerance}\n")
    print(f"buckling: {'passed' if res['passed'] else 'FAILED'}: {measured}")
    return 0 if res["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
