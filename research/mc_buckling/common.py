"""Shared set-up of the buckling studies: the bench's 1-kbp tweezers point as an MCEngine."""
import time

import numpy as np

from dnarod.core.units import PN
from dnarod.engines.mc import MCEngine
from dnarod.engines.mc.ladder import twist_ramp
from dnarod.physics.nonbonded import member_nonbonded
from dnarod.workflows.protocols.tweezers import build_member


def engine(turns, pose=None, prev=None, seed=1, **kw):
    mb = build_member(dict(n_bp=1000, force_pN=1.0, turns=turns))
    model = mb["model"]
    if pose is not None:
        model = model.with_pose(pose[0], twist_ramp(pose[1], turns - prev))
    return MCEngine(model, 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=seed, **kw)


def sample(e, n, every=1, torque=True):
    L = e.model.ds * (e.model.n_nodes - 1)
    x, t = [], []
    c0 = time.process_time()
    for _ in range(n // every):
        e.advance(every)
        x.append((e.pos[-1, 2] - e.pos[0, 2]) / L)
        if torque:
            t.append(e.tail_torque_z() / PN)
    return np.array(x), np.array(t), time.process_time() - c0
