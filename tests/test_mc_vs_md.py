"""The Monte Carlo and MD engines sample the same equilibrium: a short tweezers point (fast) and, slow, a point
past buckling and a supercoiled ring's writhe; agreement within 3 combined calibrated standard errors."""
import numpy as np
import pytest

from dnarod.analysis.statistics import combined_z, mean_and_error
from dnarod.engines.mc import MCEngine
from dnarod.physics.loads import rotation_clamp_load
from dnarod.physics.nonbonded import member_nonbonded
from dnarod.workflows.protocols.tweezers import _member_simulation, build_member
from dnarod.core.units import PN


def _md_series(mb, n_samples, stride, eq_steps):
    sim = _member_simulation(mb, mb["model"])
    sim.advance(eq_steps)
    k = mb["settings"]["clamp_k_kJ_mol"]
    x, t = np.empty(n_samples), np.empty(n_samples)
    for i in range(n_samples):
        sim.advance(stride)
        p, f = sim.node_pose()
        x[i] = p[-1, 2] - p[0, 2]
        t[i] = rotation_clamp_load(f[-1], mb["clamp_target"], k)[1][2] / PN
    return x, t


def _mc_series(mb, n_sweeps, eq_sweeps, seed=1):
    model = mb["model"]
    e = MCEngine(model, 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=seed)
    e.advance(eq_sweeps)
    x, t = np.empty(n_sweeps), np.empty(n_sweeps)
    for i in range(n_sweeps):
        e.advance(1)
        x[i] = e.pos[-1, 2] - e.pos[0, 2]
        t[i] = rotation_clamp_load(e.frm[-1], e.rc_T[-1], e.rc_k[-1])[1][2] / PN
    return x, t


def _compare(mb, md_args, mc_args):
    xm, tm = _md_series(mb, *md_args)
    xc, tc = _mc_series(mb, *mc_args)
    out = {}
    for name, a, b in (("extension", xm, xc), ("torque", tm, tc)):
        ea, eb = mean_and_error(a), mean_and_error(b)
        assert ea.flag is None and eb.flag is None, (name, ea, eb)
        out[name] = (ea, eb, combined_z(ea, eb))
    return out


@pytest.mark.slow
def test_mc_md_short_tweezers_point():
    """60 bp at 2 pN, 0.5 turns, walls and default non-bonded terms: extension and clamp torque agree.

    Open (issue 34): on its last run the MC extension (19.11 +- 0.10 nm) lay 3.1 combined errors above MD's
    (18.22 +- 0.26 nm) and its series was still flagged short (tau ~ 200 sweeps); kept out of the default suite
    until the clamped-geometry decorrelation is improved and the difference is resolved."""
    mb = build_member(dict(n_bp=60, force_pN=2.0, turns=0.5, platform="CPU", threads=1, seed=3))
    res = _compare(mb, (1200, 250, 5000), (12000, 500))
    for name, (a, b, z) in res.items():
        assert abs(z) < 3.0, (name, a, b, z)


@pytest.mark.slow
def test_mc_md_past_buckling():
    """300 bp at 1 pN, 2.5 turns (past buckling for this length): extension and torque agree."""
    mb = build_member(dict(n_bp=300, force_pN=1.0, turns=2.5, platform="CPU", threads=1, seed=5))
    res = _compare(mb, (4000, 500, 200000), (20000, 3000))
    for name, (a, b, z) in res.items():
        assert abs(z) < 3.0, (name, a, b, z)


@pytest.mark.slow
def test_mc_md_ring_writhe():
    """A 300-bp ring at Delta Lk = -3 (default non-bonded terms): mean writhe agrees."""
    from dnarod.physics.writhe import writhe
    from dnarod.physics.nonbonded import NonbondedSettings
    from dnarod.engines.openmm.simulation import RodSimulation

    from .test_mc_engine import _ring

    ring = _ring(300, 26)
    e = MCEngine(ring, 300.0, nonbonded=NonbondedSettings(), seed=2)
    e.advance(2000)
    wc = np.empty(4000)
    for i in range(len(wc)):
        e.advance(5)
        wc[i] = writhe(e.pos)
    sim = RodSimulation(ring, temperature=300.0, friction=0.05, nonbonded=NonbondedSettings(), seed=3)
    sim.advance(200000)
    wm = np.empty(3000)
    for i in range(len(wm)):
        sim.advance(500)
        wm[i] = writhe(sim.node_pose()[0])
    a, b = mean_and_error(wm), mean_and_error(wc)
    assert a.flag is None and b.flag is None, (a, b)
    assert abs(combined_z(a, b)) < 3.0, (a, b)
