"""Summary of tweezers members: means, blocked SE and quarter means of the observables (torque: twisting moment less
its zero-torque offset). Usage: python an.py MEMBER_FOLDER... (reads samples.csv, or the checkpoint of a running member)."""
import sys, numpy as np
sys.path.insert(0, str(__import__('pathlib').Path(__file__).resolve().parents[3]))
sys.path.insert(0, str(__import__('pathlib').Path(__file__).resolve().parents[1] / 'check'))  # research/buckling/check
from buckling_check import block_standard_error as bse
from dnarod.core.forcefield import load_forcefield
from dnarod.workflows.protocols.measure import twisting_moment_offset

OFF = twisting_moment_offset(load_forcefield('dna-default').model_from_sequence(n_nodes=8), 300.0)[0]  # pN nm
for d in sys.argv[1:]:
    import os, json
    if os.path.exists(d + '/samples.csv'):
        x = np.genfromtxt(d + '/samples.csv', delimiter=',', names=True)
        x = {k: np.asarray(x[k], float) for k in x.dtype.names}
    else:
        m = json.loads(str(np.load(d + '/member_checkpoint.npz')['meta']))
        x = {k: np.asarray(v, float) for k, v in m['extra']['samples'].items()}
    n = len(x['extension_nm'])
    L = None
    print(d, n, 'samples', list(x) if '-v' in sys.argv else '')
    for c in ('extension_nm', 'twist_torque_pN_nm', 'clamp_torque_pN_nm', 'Wr', 'Tw', 'plectoneme_fraction'):
        if c not in list(x): continue
        v = np.asarray(x[c], float)
        q = np.array_split(v, 4)
        adj = -OFF if c == 'twist_torque_pN_nm' else 0
        print(f"  {c:22s} {v.mean()+adj:9.3f} +- {bse(v):.3f}  quarters " + " ".join(f"{w.mean()+adj:8.3f}" for w in q))
