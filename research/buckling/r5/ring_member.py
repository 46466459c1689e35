"""Ring member with poses saved. Usage: python ring_member.py OUT.npz N_BP DELTA_LK TIME_NS SEED"""
import sys
import numpy as np
from dnarod.core.forcefield import load_forcefield
from dnarod.workflows.protocols.rings import sample_ring, _settings
from dnarod.physics.thermal import persistence_length
from dnarod.core.units import kT
out_path, n_bp, dlk, time_ns, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
s = _settings(dict(n_bp=n_bp, delta_lk=dlk, time_ns=time_ns, seed=seed))
ff = load_forcefield("dna-default")
model = ff.ring(n_nodes=n_bp, delta_linking_number=dlk)
lp = persistence_length(model.params, model.ds, kT(300.0))
poses = []
def record(out, i, pos, frm):
    poses.append((pos.astype(np.float32), frm.astype(np.float32)))
cols = ("time_ps", "Tw", "Wr", "Lk", "radius_of_gyration_nm")
out, run = sample_ring(model, s, lp, cols, record, tau_fraction=0.1, samples_per_ns=200.0, max_sample_ps=200.0,
                       min_samples=4)
np.savez(out_path, pos=np.array([p for p, _ in poses]), frames=np.array([f for _, f in poses]),
         cpu=run["cpu_s"], wall=run["wall_s"], **{c: out[c] for c in cols})
print("done", run["cpu_s"], run["wall_s"], out["Wr"].mean(), out["Tw"].mean())
