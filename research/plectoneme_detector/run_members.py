"""Short ring and tweezers members whose poses are kept for the plectoneme-detector study (round 7).

Usage: python run_members.py ROOT NAME

``NAME`` picks one member of ``MEMBERS`` below; it runs through :func:`dnarod.workflows.protocols.rings.run_ring_member` or
:func:`dnarod.workflows.protocols.tweezers.run_member` with exactly those settings into ``ROOT/NAME``, and every pose the
plectoneme detector sees is kept (float32 positions) in ``ROOT/NAME.poses.npz`` (``plectoneme_state`` is wrapped
in this process only, as in ``research/buckling/r6/premembers.py``). ``analyze.py`` reads them.
"""
import json
import sys
import time
from pathlib import Path

import numpy as np

import dnarod.workflows.protocols.measure as measure

# 400 bp: Lk0 = 38.0 turns (quick buckling plan: pre-buckling 0.01 Lk0 = 0.38, post-buckling 0.045 Lk0 = 1.71 and
# 0.063 Lk0 = 2.39 turns)
MEMBERS = {
    # ring at sigma = -3/38.0 = -0.079, calibrated charge (the default) and Manning's (old default, 5 Debye lengths)
    "ring400_-3": ("ring", dict(n_bp=400, delta_lk=-3, time_ns=3.0, equilibration_ns=5.0, seed=5)),
    "ring400_-3_manning": ("ring", dict(n_bp=400, delta_lk=-3, time_ns=3.0, equilibration_ns=5.0, seed=5,
                                        charge="manning", cutoff_debye=5.0)),
    # a longer ring at sigma = -5/57.0 = -0.088 (the full buckling plan's ring): longer arms
    "ring600_-5": ("ring", dict(n_bp=600, delta_lk=-5, time_ns=3.0, equilibration_ns=5.0, seed=5)),
    # tweezers at 1 pN: pre-buckling (zeta) and past buckling from a plectoneme grown at 0.3 pN
    "tw400_pre": ("tweezers", dict(n_bp=400, force_pN=1.0, turns=0.381, time_ns=2.0, equilibration_ns=1.0, seed=31)),
    "tw400_+2.40": ("tweezers", dict(n_bp=400, force_pN=1.0, turns=2.40, time_ns=3.0, equilibration_ns=0.5, seed=43,
                                     start_force_pN=0.3, start_ns=2.0)),
    "tw400_+2.40_manning": ("tweezers", dict(n_bp=400, force_pN=1.0, turns=2.40, time_ns=3.0, equilibration_ns=0.5,
                                             seed=43, start_force_pN=0.3, start_ns=2.0, charge="manning",
                                             cutoff_debye=5.0)),
    # a longer plectoneme (sigma = +0.089): more interwound superhelix, less end loop
    "tw400_+3.40": ("tweezers", dict(n_bp=400, force_pN=1.0, turns=3.40, time_ns=3.0, equilibration_ns=0.5, seed=47,
                                     start_force_pN=0.3, start_ns=2.0)),
    "tw400_+3.40_manning": ("tweezers", dict(n_bp=400, force_pN=1.0, turns=3.40, time_ns=3.0, equilibration_ns=0.5,
                                             seed=47, start_force_pN=0.3, start_ns=2.0, charge="manning",
                                             cutoff_debye=5.0)),
    # the README's 300-bp hat at 0.5 pN: -1.6 turns (writhe -0.81, fraction 0 with the fixed 6 nm) and 0 turns (zeta)
    "hat300_-1.60": ("tweezers", dict(n_bp=300, force_pN=0.5, turns=-1.6, time_ns=3.0, equilibration_ns=6.2, seed=3)),
    "hat300_pre": ("tweezers", dict(n_bp=300, force_pN=0.5, turns=0.0, time_ns=3.0, equilibration_ns=3.0, seed=4)),
    "tw400_pre_manning": ("tweezers", dict(n_bp=400, force_pN=1.0, turns=0.381, time_ns=2.0, equilibration_ns=1.0,
                                           seed=31, charge="manning", cutoff_debye=5.0)),
}

root, name = Path(sys.argv[1]), sys.argv[2]
kind, settings = MEMBERS[name]
_orig = measure.plectoneme_state
_poses = []


def _wrapped(positions, ds, *a, **k):
    _poses.append(np.asarray(positions, np.float32))
    return _orig(positions, ds, *a, **k)


measure.plectoneme_state = _wrapped
t0, c0 = time.time(), time.process_time()
grow = (settings.pop("start_force_pN", None), settings.pop("start_ns", None))  # a grown-plectoneme start
if kind == "ring":
    from dnarod.workflows.protocols.rings import run_ring_member as run
elif grow[0] is not None:  # until 2026-12-07 the member settings start_force_pN / start_ns
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "turn_sweeps"))  # research/turn_sweeps
    from turn_sweep import run_grown_member

    def run(s, d):
        return run_grown_member(s, d, *grow)
else:
    from dnarod.workflows.protocols.tweezers import run_member as run
row = run(settings, root / name)
np.savez_compressed(root / f"{name}.poses.npz", positions=np.array(_poses), ds=0.34, kind=kind,
                    settings=json.dumps(settings))
print(name, f"{time.time() - t0:.0f} s wall, {time.process_time() - c0:.0f} s CPU, {len(_poses)} poses")
