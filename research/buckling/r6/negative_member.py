"""The sign question: one tweezers member at minus the turns of a post-buckling member of the check, with the
check's settings otherwise (``member_plan``'s straight member at that turn value, turns negated).

Usage: python negative_member.py OUT_DIR TURNS TIME_NS   (e.g. runs/neg_r6 2.5671 200)
"""
import sys
import time
from pathlib import Path

from dnarod.workflows.protocols.tweezers import run_member

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "check"))  # research/buckling/check
from buckling_check import member_plan  # noqa: E402

out, turns, time_ns = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
plan = member_plan(time_ns=time_ns, bracket=False, P_nm=20.0)  # P_nm: no rings in the plan
e = next(e for e in plan if e["role"] == "post" and abs(e["settings"]["turns"] - turns) < 1e-3)
s = dict(e["settings"], turns=-e["settings"]["turns"])
t0, c0 = time.perf_counter(), time.process_time()
r = run_member(s, f"{out}/turns{s['turns']:+.3f}")
print(s, "wall", round(time.perf_counter() - t0), "cpu", round(time.process_time() - c0),
      "torque (raw)", r["twist_torque_pN_nm"], "x/L", r["relative_extension"])
