"""Run the members of check ``buckling`` in advance, in several processes, into one member root.

Usage: python premembers.py ROOT WORKER_NAME [quick] [claims=NAME] [key=value ...]

Every process walks the same plan (:func:`buckling_check.member_plan` in research/buckling/check, the very settings the check
uses) in order and claims each member by creating ``ROOT/.claims[_NAME]/<folder>`` (atomic mkdir): start two processes
and they share the members. ``check_buckling(member_root=ROOT, ...)`` with the same options then reuses the
finished members. Options ``key=value`` go to ``member_plan`` (numbers parsed as Python literals).

For the ring-pair premise (how many end loops each ring has), the poses seen by the plectoneme detector are
also kept (float32 positions, every sample of rings, every 4th of tweezers members) in
``ROOT/<folder>.poses.npz``: ``dnarod.workflows.protocols.measure.plectoneme_state`` is wrapped in this process only, so the
members' settings, samples and results are those of the check.
"""
import ast
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

import dnarod.workflows.protocols.measure as measure

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "check"))  # research/buckling/check
from buckling_check import member_plan, run_planned  # noqa: E402

root, worker = Path(sys.argv[1]), sys.argv[2]
quick = "quick" in sys.argv[3:]


def _value(v):
    try:
        return ast.literal_eval(v)
    except ValueError:
        return v


opts = {k: _value(v) for k, v in (a.split("=", 1) for a in sys.argv[3:] if "=" in a)}
claims = root / (".claims_" + str(opts.pop("claims")) if "claims" in opts else ".claims")
root.mkdir(parents=True, exist_ok=True)
claims.mkdir(exist_ok=True)
plan = member_plan(quick=quick, **opts)
# rings first (P, and the premise check), then the post-buckling twins, the pre-buckling member last
_order = {"ring": 0, "ring_pair": 1, "above_source": 2, "post": 3, "post_grown": 3, "post_above": 3, "pre": 9}
plan = sorted(plan, key=lambda e: (_order[e["role"]], e["index"], e["role"] in ("post_grown", "post_above")))
log = root / f"worker_{worker}.log"

_orig = measure.plectoneme_state
_poses = []
_state = dict(every=1, count=0)


def _wrapped(positions, ds, *a, **k):
    if _state["count"] % _state["every"] == 0:
        _poses.append(np.asarray(positions, np.float32))
    _state["count"] += 1
    return _orig(positions, ds, *a, **k)


measure.plectoneme_state = _wrapped


def say(msg):
    with open(log, "a") as f:
        f.write(f"{time.strftime('%H:%M:%S')} {msg}\n")


for e in plan:
    try:
        os.mkdir(claims / e["folder"])
    except FileExistsError:
        continue
    if e.get("start_from"):  # an "above" twin: wait for its source member (another process may run it)
        while not (root / e["start_from"] / "protocol_result.json").exists():
            time.sleep(30)
    _poses.clear()
    _state.update(every=1 if e["kind"] == "ring" else 4, count=0)
    t0, c0 = time.perf_counter(), time.process_time()
    say(f"start {e['folder']} {json.dumps(e['settings'])}")
    last = [0.0]

    def progress(i, n):
        if time.perf_counter() - last[0] > 300:
            last[0] = time.perf_counter()
            say(f"  {e['folder']} sample {i}/{n} wall {time.perf_counter() - t0:.0f} s cpu {time.process_time() - c0:.0f} s "
                f"load {os.getloadavg()[0]:.1f}")

    r = run_planned(e, root, progress=progress)
    if _poses:
        np.savez_compressed(root / f"{e['folder']}.poses.npz", pos=np.array(_poses), every=_state["every"])
    say(f"done {e['folder']} wall {time.perf_counter() - t0:.0f} s cpu {time.process_time() - c0:.0f} s "
        f"(member wall_s {r.get('wall_s', float('nan')):.0f} cpu_s {r.get('cpu_s', float('nan')):.0f}) "
        f"load {os.getloadavg()[0]:.1f}")
