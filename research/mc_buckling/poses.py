"""Buckled start poses at dLk 4 and 3 (from the dLk 4 start pose; 2000 sweeps each)."""
import numpy as np
from common import engine, sample

e = engine(4.0)
x, t, c = sample(e, 2000, 10, torque=False)
print("dLk4", x[::20], c, flush=True)
np.savez("pose4.npz", pos=e.pos, frm=e.frm, amp=e.amp)
e3 = engine(3.0, e.node_pose(), 4.0)
x, t, c = sample(e3, 2000, 10, torque=False)
print("dLk3", x[::20], c, flush=True)
np.savez("pose3.npz", pos=e3.pos, frm=e3.frm, amp=e3.amp)
