"""The Monte Carlo and MD engines sample the same equilibrium: a short tweezers point (fast, default suite) and,
slow, a point past buckling and a supercoiled ring's writhe; agreement within 3 combined calibrated standard
errors (:func:`dnarod.analysis.statistics.mean_and_error`, transients cut, series flagged short refused).

The torque is the tail-rotation estimate of the clamp torque (:meth:`MCEngine.tail_torque_z`), evaluated on the MD
poses with an MC engine used as a calculator: the identity behind it holds for any sampler of the equilibrium."""
import numpy as np
import pytest

from dnarod.analysis.statistics import combined_z, mean_and_error
from dnarod.core.units import PN
from dnarod.engines.mc import MCEngine
from dnarod.physics.nonbonded import member_nonbonded
from dnarod.workflows.protocols.tweezers import _member_simulation, build_member


def _engine(mb, seed, tune_sweeps=200):
    return MCEngine(mb["model"], 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=seed,
                    tune_sweeps=tune_sweeps)


def _md_series(mb, n_samples, stride, eq_steps):
    sim = _member_simulation(mb, mb["model"])
    sim.advance(eq_steps)
    calc = _engine(mb, 1, tune_sweeps=0)
    x, t = np.empty(n_samples), np.empty(n_samples)
    for i in range(n_samples):
        sim.advance(stride)
        p, f = sim.node_pose()
        calc.set_pose(p, f)
        x[i] = p[-1, 2] - p[0, 2]
        t[i] = calc.tail_torque_z() / PN
    return x, t


def _mc_series(mb, n_sweeps, eq_sweeps, seed=2):
    e = _engine(mb, seed)
    e.advance(eq_sweeps)
    x, t = np.empty(n_sweeps), np.empty(n_sweeps)
    for i in range(n_sweeps):
        e.advance(1)
        x[i] = e.pos[-1, 2] - e.pos[0, 2]
        t[i] = e.tail_torque_z() / PN
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


def test_mc_md_short_tweezers_point():
    """40 bp at 2 pN, 0.3 turns, walls and default non-bonded terms: extension and clamp torque agree (each to
    about 1 %)."""
    mb = build_member(dict(n_bp=40, force_pN=2.0, turns=0.3, platform="CPU", threads=1, seed=3))
    res = _compare(mb, (3000, 100, 2000), (12000, 300))
    for name, (a, b, z) in res.items():
        assert abs(z) < 3.0, (name, a, b, z)
    assert res["extension"][0].error < 0.015 * res["extension"][0].mean


@pytest.mark.slow
def test_mc_md_past_buckling():
    """300 bp at 1 pN, 1.5 turns (past buckling for this length: a plectoneme): extension and torque agree."""
    mb = build_member(dict(n_bp=300, force_pN=1.0, turns=1.5, platform="CPU", threads=1, seed=5))
    res = _compare(mb, (3000, 2000, 100000), (20000, 2000))
    for name, (a, b, z) in res.items():
        assert abs(z) < 3.0, (name, a, b, z)


@pytest.mark.slow
def test_mc_md_ring_writhe():
    """A 300-bp ring at Delta Lk = -3 (default non-bonded terms): the mean writhe agrees."""
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.physics.nonbonded import NonbondedSettings
    from dnarod.physics.writhe import writhe

    from conftest import uniform_ring

    ring = uniform_ring(300, 26)
    e = MCEngine(ring, 300.0, nonbonded=NonbondedSettings(), seed=2)
    e.advance(2000)
    wc = np.empty(6000)
    for i in range(len(wc)):
        e.advance(2)
        wc[i] = writhe(e.pos)
    sim = RodSimulation.create(ring, temperature=300.0, friction=0.05, nonbonded=NonbondedSettings(), seed=3,
                        platform="CPU", threads=1)
    sim.advance(100000)
    wm = np.empty(3000)
    for i in range(len(wm)):
        sim.advance(1000)
        wm[i] = writhe(sim.node_pose()[0])
    a, b = mean_and_error(wm), mean_and_error(wc)
    assert a.flag is None and b.flag is None, (a, b)
    assert abs(combined_z(a, b)) < 3.0, (a, b)
