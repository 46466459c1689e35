"""Ring members and ring pairs (n and 2n bp at the same sigma): writhe, end loops, the pair's bulk plectoneme torque
and Marko's plateau torque from the measured plectoneme points. Usage: python rings_an.py RING_FOLDER..."""
import sys, json, numpy as np
sys.path.insert(0, str(__import__('pathlib').Path(__file__).resolve().parents[3]))
from pathlib import Path
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.thermal import relaxed_ribbon_twist
from dnarod.core.units import kT
from dnarod.core.units import PN
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'check'))  # research/buckling/check
from buckling_check import block_standard_error as bse, drift_z
from buckling_theory import ring_pair_bulk_torque, two_phase_from_plectoneme_eos
from dnarod.physics.theory.supercoil import plectoneme_P_from_ring_pair
from dnarod.physics.theory.torsion import bare_twist_persistence, moroz_nelson
from dnarod.physics.thermal import persistence_length
ff = load_forcefield('dna-default'); T = 300.0; kt = kT(T) / PN
m4 = ff.model_from_sequence(n_nodes=600)
C = bare_twist_persistence(ff.model_from_sequence(n_nodes=4), T); A = persistence_length(m4.params, m4.ds, kT(T))
Cs = float(moroz_nelson(C, A, 1.0, kt))
rows = {}
for d in sys.argv[1:]:
    r = json.loads((Path(d) / 'protocol_result.json').read_text())['result']
    x = np.genfromtxt(Path(d) / 'samples.csv', delimiter=',', names=True)
    tw0, _ = relaxed_ribbon_twist(ff.ring(n_nodes=r['n_bp']), T)
    wr = np.asarray(x['Wr'], float)
    rows[d] = dict(n=r['n_bp'], dlk=r['Lk'] - tw0, wr=wr.mean(), se=bse(wr), loops=float(np.mean(x['end_loops'])), z=drift_z(Path(d) / 'samples.csv', 'Wr'), L=r['n_bp'] * m4.ds)
    q = rows[d]
    tau1 = kt * C * 2 * np.pi * (q['dlk'] - q['wr']) / q['L']
    print(f"{d}: n {q['n']} dLk_T {q['dlk']:.3f} Wr {q['wr']:.3f}+-{q['se']:.3f} frac {q['wr']/q['dlk']:.3f} loops {q['loops']:.2f} driftz {q['z']:.1f} single-ring torque {abs(tau1):.2f} omega {2*np.pi*abs(q['dlk'])/q['L']:.4f}")
pts = []
for a in rows.values():
    for b in rows.values():
        if b['n'] == 2 * a['n'] and abs(b['dlk'] / b['L'] - a['dlk'] / a['L']) < 0.1 * abs(a['dlk'] / a['L']):
            om, tau, se = ring_pair_bulk_torque(a['wr'], a['dlk'], a['L'], b['wr'], b['dlk'], b['L'], C, kt, a['se'], b['se'])
            P, Pe = plectoneme_P_from_ring_pair(a['wr'], a['dlk'], b['wr'], b['dlk'], C, a['se'], b['se'])
            print(f"pair {a['n']}/{b['n']}: omega {om:.4f} tau_b {tau:.2f}+-{se:.2f} P_b {P:.2f}+-{Pe:.2f} loops {a['loops']:.2f}/{b['loops']:.2f}")
            pts.append((om, tau))
print('A', A, 'C', C, 'Cs', Cs)
if pts:
    pts.sort()
    for k in range(1, len(pts) + 1):
        try:
            e = two_phase_from_plectoneme_eos([p[0] for p in pts[-k:]], [p[1] for p in pts[-k:]], A, Cs, 1.0, kt, 203.7)
            print('EOS with last', k, 'points: tau*', round(e['torque_pN_nm'], 3), 'omega_p', round(float(e['omega_p']), 4), 'P_sec', round(float(e['P_secant_nm']), 2), 'slope', round(float(e['extension_slope_nm_per_turn']), 1))
        except Exception as ex:
            print('EOS', k, ex)
