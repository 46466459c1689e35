"""Run check ``buckling`` on a member root filled by premembers.py (same options), through the validation
runner, so the report folder holds report.md, results.json and buckling.png.

Usage: python run_check.py ROOT REPORT_DIR [key=value ...]   (the premembers.py options, without claims=)
"""
import ast
import json
import sys
import time

from dnarod.validate import run_validation


def _value(v):
    try:
        return ast.literal_eval(v)
    except ValueError:
        return v


root, out = sys.argv[1], sys.argv[2]
opts = {k: _value(v) for k, v in (a.split("=", 1) for a in sys.argv[3:] if "=" in a)}
opts.pop("claims", None)
t0, c0 = time.perf_counter(), time.process_time()
res = run_validation(out, checks=["buckling"], options={"buckling": dict(opts, member_root=root)})
r = res["checks"]["buckling"]
print("passed", r["passed"], "wall", round(time.perf_counter() - t0, 1), "cpu", round(time.process_time() - c0, 1))
print(json.dumps({k: r.get(k) for k in ("pre_buckling", "plateau", "extension_drop", "marko", "drift",
                                         "ring_pair_premise", "error")}, indent=1, default=str))
