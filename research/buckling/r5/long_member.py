"""Long tweezers member with poses saved (investigation of the buckling check). Usage:
python long_member.py OUT.npz TURNS TIME_NS SEED [grown] [n_bp] [force]"""
import sys, time, os, json
import numpy as np
from dnarod.workflows.protocols.tweezers import COLUMNS, _member_simulation, build_member
from dnarod.workflows.protocols.measure import clamp_torque_z, plectoneme_state, rotation_about_z, twisting_moment
from dnarod.physics.observables import twist_writhe_open

out_path, turns, time_ns, seed = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
grown = len(sys.argv) > 5 and sys.argv[5] == "grown"
n_bp = int(sys.argv[6]) if len(sys.argv) > 6 else 600
force = float(sys.argv[7]) if len(sys.argv) > 7 else 1.0
s = dict(n_bp=n_bp, force_pN=force, turns=turns, time_ns=time_ns, temperature_K=300.0, seed=seed,
         sample_ps=200.0)
m = build_member(s)
t0, c0 = time.perf_counter(), time.process_time()
if grown:  # a plectoneme grown 20 ns at 0.3 pN (same turns and clamp target), as tweezers.grown_start did
    pre = build_member(dict(s, force_pN=0.3))
    psim = _member_simulation(pre, pre["model"])
    psim.advance(int(round(20000.0 / psim.dt)))
    m = {**m, "model": m["model"].with_pose(*psim.node_pose())}
model = m["model"]
sim = _member_simulation(m, model)
dt = sim.dt
stride = max(1, int(round(m["sample_ps"] / dt)))
n_eq = int(round(m["equilibration_ps"] / dt))
n_samp = int(round(m["production_ps"] / (stride * dt)))
f_ref = m["ref_frame"]
st = dict(last=0.0, acc=0.0)
def end_rotation(frm):
    a = float(rotation_about_z(frm[-1], f_ref))
    st["acc"] += ((a - st["last"] + np.pi) % (2 * np.pi) - np.pi) / (2 * np.pi)
    st["last"] = a
    return st["acc"]
done = 0
while done < n_eq:
    k = min(stride, n_eq - done); sim.advance(k); done += k; end_rotation(sim.node_pose()[1])
out = {c: np.zeros(n_samp) for c in COLUMNS}
P = np.zeros((n_samp, n_bp, 3), np.float32); F = np.zeros((n_samp, n_bp, 3, 3), np.float32)
k_clamp = m["settings"]["clamp_k_kJ_mol"]
last_save = time.perf_counter()
def save(i):
    tmp = out_path + ".tmp.npz"
    np.savez(tmp, n=i, pos=P[:i], frames=F[:i], settings=json.dumps({k: v for k, v in m["settings"].items()}, default=str),
             lk0=m["lk0"], dt=dt, stride=stride, n_eq=n_eq, friction=m["friction"],
             wall=time.perf_counter() - t0, cpu=time.process_time() - c0, **{c: out[c][:i] for c in COLUMNS})
    os.replace(tmp, out_path)
for i in range(n_samp):
    sim.advance(stride)
    pos, frm = sim.node_pose()
    P[i], F[i] = pos, frm
    out["time_ps"][i] = (n_eq + (i + 1) * stride) * dt
    out["extension_nm"][i] = pos[-1, 2] - pos[0, 2]
    out["end_turns"][i] = m["turns"] + end_rotation(frm)
    out["clamp_torque_pN_nm"][i] = clamp_torque_z(frm[-1], m["clamp_target"], k_clamp)
    tw, wr = twist_writhe_open(pos, frm)
    out["Tw"][i], out["Wr"][i], out["Lk"][i] = tw, wr, tw + wr
    f, length, plec, mask = plectoneme_state(pos, model.ds, 25.0, 6.0, return_mask=True)  # round 5's fixed distances
    out["twist_torque_pN_nm"][i] = twisting_moment(pos, frm, model.params, model.ds, mask)
    out["plectoneme_fraction"][i], out["plectoneme_length_nm"][i], out["plectonemic"][i] = f, length, plec
    if time.perf_counter() - last_save > 120:
        save(i + 1); last_save = time.perf_counter()
save(n_samp)
print("done", out_path, time.perf_counter() - t0, time.process_time() - c0)
