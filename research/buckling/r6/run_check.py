"""Run the buckling check on a member root filled by premembers.py (same options), so the report folder holds
report.md, results.json and buckling.png (through ``research/buckling/check/run_buckling.py``; until 2026-12-07 through
``dnarod.validate.run_validation``, check ``buckling``).

Usage: python run_check.py ROOT REPORT_DIR [key=value ...]   (the premembers.py options, without claims=)
"""
import ast
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "check"))  # research/buckling/check
from run_buckling import main as run_check  # noqa: E402


def _value(v):
    try:
        return ast.literal_eval(v)
    except ValueError:
        return v


root, out = sys.argv[1], sys.argv[2]
opts = {k: _value(v) for k, v in (a.split("=", 1) for a in sys.argv[3:] if "=" in a)}
opts.pop("claims", None)
t0, c0 = time.perf_counter(), time.process_time()
run_check([out, *[f"{k}={v!r}" for k, v in dict(opts, member_root=root).items()]])
r = json.loads((Path(out) / "results.json").read_text())
print("passed", r["passed"], "wall", round(time.perf_counter() - t0, 1), "cpu", round(time.process_time() - c0, 1))
print(json.dumps({k: r.get(k) for k in ("pre_buckling", "plateau", "extension_drop", "marko", "drift",
                                         "ring_pair_premise", "error")}, indent=1, default=str))
