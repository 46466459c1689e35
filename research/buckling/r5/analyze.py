"""Analysis of long tweezers members / rings with poses."""
import sys, json
import numpy as np
from dnarod.core.forcefield import load_forcefield
from dnarod.core.strains import strains
from dnarod.core.units import PN
from dnarod.physics.thermal import relaxed_ribbon_twist
from dnarod.core.units import kT
from dnarod.workflows.protocols.measure import plectoneme_state, twisting_moment_offset
from dnarod.physics.writhe import writhe
from dnarod.analysis.polymer import integrated_autocorrelation_time
KT = kT(300.0) / PN
C = 98.3

def se_tau(x):
    x = np.asarray(x, float); x = x[np.isfinite(x)]
    t = integrated_autocorrelation_time(x); t = t if np.isfinite(t) and t > 0.5 else 0.5
    return x.mean(), x.std(ddof=1) * np.sqrt(2 * t / len(x)), t

def m3_steps(model, pos, frm, closure=None):
    Om, Ga = strains(pos, frm, model.ds, closure)
    p = model.params
    dxi = np.concatenate([Om, Ga], axis=-1) - p.intrinsic
    m3 = np.einsum("kj,...kj->...k", p.stiffness[:, 2, :], dxi) * (1.0 + 0.25 * (model.ds * Om[..., 2]) ** 2)
    return m3 / PN, Om

def tweezers(path, skip_ns=0.0, every=1):
    d = np.load(path)
    n = int(d["n"]); pos = d["pos"][:n:every].astype(float); frm = d["frames"][:n:every].astype(float)
    t = d["time_ps"][:n:every] / 1000.0
    keep = t >= t[0] + skip_ns
    pos, frm, t = pos[keep], frm[keep], t[keep]
    n_bp = pos.shape[1]
    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    off, off_se = twisting_moment_offset(model, 300.0)
    ds = model.ds; L = ds * (n_bp - 1)
    rows = []
    for P_, F_ in zip(pos, frm):
        m3, Om = m3_steps(model, P_, F_)
        f, length, plec, mask = plectoneme_state(P_, ds, 25.0, 6.0, return_mask=True)  # round 5's fixed distances
        stepmask = mask[:-1] | mask[1:]
        d3z = F_[:-1, 2, 2]
        idx = np.flatnonzero(mask)
        if len(idx) >= 10:
            i0, i1 = idx.min(), idx.max()
            # largest cluster span as in the detector is close to min..max when one plectoneme
            seg = P_[i0:i1 + 1]
            wr_p = writhe(seg); Lp = ds * (i1 - i0)
        else:
            wr_p, Lp = 0.0, 0.0
        rows.append(dict(m3_all=m3.mean() - off, m3_ext=m3[~stepmask].mean() - off if (~stepmask).any() else np.nan,
                         m3_plec=m3[stepmask].mean() - off if stepmask.any() else np.nan,
                         m3_est=m3[(d3z > 0.9) & ~stepmask].mean() - off,
                         wr_p=wr_p, Lp=Lp, frac=f, z=P_[-1, 2] - P_[0, 2]))
    R = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    Wr = d["Wr"][:n:every][keep]; Lk = d["Lk"][:n:every][keep]; Tw = d["Tw"][:n:every][keep]
    out = dict(path=path, n_frames=len(t), t_span_ns=float(t[-1] - t[0]))
    for k in ("m3_all", "m3_ext", "m3_plec", "m3_est", "z", "frac", "Lp", "wr_p"):
        out[k] = se_tau(R[k])
    out["Wr"] = se_tau(Wr); out["Tw"] = se_tau(Tw); out["Lk"] = se_tau(Lk)
    out["clamp"] = se_tau(d["clamp_torque_pN_nm"][:n:every][keep])
    lk0T, _ = relaxed_ribbon_twist(model, 300.0)
    dLk = Lk.mean() - lk0T
    tau = out["m3_est"][0]
    # phases: plectoneme = detector span; linking density = writhe density + uniform twist density tau/(kT C)
    om_tw = tau / (KT * C)
    Lp = R["Lp"].mean(); Ls = L - Lp
    om_p = 2 * np.pi * R["wr_p"].mean() / Lp + om_tw
    om_s = (2 * np.pi * dLk - om_p * Lp) / Ls
    out.update(dLk=dLk, L=L, om_tw=om_tw, om_p=om_p, om_s=om_s, P_tw=tau / (KT * om_p), Cs_tw=tau / (KT * om_s),
               maxwell_g=0.5 * tau * (om_p - om_s), twist_torque_from_Tw=KT * C * 2 * np.pi * (Tw.mean() - (lk0T - 0.0)) / L)
    # drift: halves
    h = len(t) // 2
    for k in ("z", "m3_est"):
        a, b = se_tau(R[k][:h]), se_tau(R[k][h:])
        out[k + "_halves"] = (a[0], a[1], b[0], b[1], (b[0] - a[0]) / np.hypot(a[1], b[1]))
    # window means of z (25 ns)
    w = max(1, int(round(25.0 / np.median(np.diff(t)))))
    out["z_windows"] = [float(R["z"][i:i + w].mean()) for i in range(0, len(t), w)]
    out["tau_windows"] = [float(R["m3_est"][i:i + w].mean()) for i in range(0, len(t), w)]
    return out

def ring(path, n_bp, every=1):
    d = np.load(path)
    ff = load_forcefield("dna-default")
    lkint = int(np.rint(d["Lk"][0]))
    model = ff.ring(n_nodes=n_bp, delta_linking_number=0)
    off, off_se = twisting_moment_offset(model, 300.0)
    tw0T, tw0se = relaxed_ribbon_twist(model, 300.0)
    L = model.ds * n_bp
    m3s = []
    mdl = ff.ring(n_nodes=n_bp, delta_linking_number=lkint - int(round(model_lk0(model))))
    for P_, F_ in zip(d["pos"][::every].astype(float), d["frames"][::every].astype(float)):
        m3, Om = m3_steps(mdl, P_, F_, mdl.closure)
        m3s.append(m3.mean() - off)
    m3s = np.array(m3s)
    tau = se_tau(m3s)
    dLk = d["Lk"].mean() - tw0T
    om = 2 * np.pi * dLk / L
    Wr = se_tau(d["Wr"]); Tw = se_tau(d["Tw"])
    return dict(path=path, Lk=float(d["Lk"].mean()), dLk=dLk, sigma=dLk / tw0T, tau_moment=tau, om=om,
                P_moment=tau[0] / (KT * om), P_moment_se=tau[1] / (KT * om),
                Wr=Wr, Tw=Tw, wr_frac=Wr[0] / dLk, P_writhe=C * (1 - Wr[0] / dLk),
                tau_from_Tw=KT * C * 2 * np.pi * (Tw[0] - tw0T) / L, cpu=float(d["cpu"]), n=len(m3s), offset=(off, off_se))

def model_lk0(model):
    from dnarod.physics.loads import intrinsic_turns
    return intrinsic_turns(model)

if __name__ == "__main__":
    kind = sys.argv[1]
    if kind == "t":
        r = tweezers(sys.argv[2], float(sys.argv[3]) if len(sys.argv) > 3 else 0.0,
                     int(sys.argv[4]) if len(sys.argv) > 4 else 1)
    else:
        r = ring(sys.argv[2], int(sys.argv[3]))
    print(json.dumps(r, indent=1, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
