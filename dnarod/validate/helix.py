"""Check ``helix``: the intrinsic helix is a zero-force state in both engines (docs/formulation.md §8).

Two intrinsic shapes: the analytic uniform helix (:class:`dnarod.physics.testsystems.UniformHelix`, a
strongly bent and sheared screw orbit whose closed form is also compared) and the
sequence-dependent intrinsic shape of the 355D sequence with the ``olson1998`` force field.
For each, measured:

* the analytic loads (:func:`dnarod.core.energy.loads`);
* the OpenMM engine's node forces and torques (Reference platform, both elastic paths: the
  numba ``PythonForce`` and the portable ``CustomCompoundBondForce``), summed from the particle
  forces;
* the right-hand side of the exact Lax-form system at rest;
* the largest displacement and rotation after a short NVE run from rest in the OpenMM engine,
  the Lax-form splitting and the exact Lax-form integrator.
"""
from __future__ import annotations

import time

import numpy as np


from dnarod.validate._common import rotation_angle
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.testsystems import UniformHelix
from dnarod.engines.openmm.particles import particle_forces_to_loads
from dnarod.engines.lax import SplittingIntegrator, integrate_exact
from dnarod.engines.lax.exact import ExactSystem

NAME = "helix"
#: The drift tolerance is set by the OpenMM engine's constraint solver, not by the forces: OpenMM holds
#: each three-particle node with SETTLE (used for every isolated constrained triangle), whose analytic
#: solution is accurate to ~sqrt(machine eps) relative; measured: the triangle sides settle 1.9e-8 nm
#: from their constrained length at the first step and the node centres creep by ~1.5e-8 nm per ps,
#: with elastic forces ~1e-12 kJ/mol/nm (which alone would move a node by ~1e-14 nm in 1 ps).
TOLERANCES = dict(force_tol_kJmol_nm=1e-8, torque_tol_kJmol=1e-8, closed_form_tol_nm=1e-10,
                  drift_tol_nm=1e-7, drift_tol_rad=1e-7)


def default_models():
    """``[(label, RodModel), ...]``: the analytic helix and the olson1998 intrinsic shape of 355D."""
    hx = UniformHelix(Omega0=[0.35, -0.2, 1.78], Gamma0=[0.08, -0.05, 1.0], ds=0.34, n_nodes=24)
    ff = load_forcefield("olson1998")
    return [("uniform helix (A5 i)", hx.model(), hx), ("olson1998 CGCGAATTCGCG", ff.model_from_sequence("CGCGAATTCGCG"),
                                                      None)]


def _openmm_loads(model, elastic):
    import openmm

    from dnarod.engines.openmm.simulation import RodSimulation  # loads OpenMM

    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=0.01, platform="Reference",
                               elastic=elastic,
                        nonbonded=False, constraint_tolerance=1e-12, seed=0)
    st = sim.context.getState(getPositions=True, getForces=True)
    x = sim.node_particles(st.getPositions(asNumpy=True))
    f = sim.node_particles(st.getForces(asNumpy=True))
    F, tau = particle_forces_to_loads(x, f)
    del openmm
    return F, tau, sim


def _drift(model, positions, frames):
    return (float(np.abs(positions - model.positions).max()),
            float(rotation_angle(frames, model.frames).max()))


def check_helix(out_dir, quick=False, models=None, t_run=1.0):
    """Run the check; ``models`` overrides :func:`default_models` (list of (label, model, helix or None))."""
    t0 = time.perf_counter()
    models = default_models() if models is None else models
    res = dict(TOLERANCES, run_time_ps=t_run, systems={})
    all_ok = True
    for label, model, hx in models:
        r = {}
        if hx is not None:
            pos, frm = hx.closed_form()
            r["closed_form_position_difference_nm"] = float(np.abs(pos - model.positions).max())
            r["closed_form_frame_difference_rad"] = float(rotation_angle(frm, model.frames).max())
        _, F, tau = model.loads()
        r["numpy_max_force"] = float(np.abs(F).max())
        r["numpy_max_torque"] = float(np.abs(tau).max())
        for elastic in ("fast", "portable"):
            F, tau, sim = _openmm_loads(model, elastic)
            r[f"openmm_{elastic}_max_force"] = float(np.abs(F).max())
            r[f"openmm_{elastic}_max_torque"] = float(np.abs(tau).max())
            if elastic == "fast":
                sim.advance(int(round(t_run / sim.dt)))
                c, f = sim.node_pose()
                r["openmm_nve_drift_nm"], r["openmm_nve_drift_rad"] = _drift(model, c, f)
        ex = ExactSystem(model)
        r["lax_exact_rhs_max"] = float(np.abs(ex.rhs(0.0, ex.initial_state())).max())
        integ = SplittingIntegrator(model, 0.01, check_stability=False)
        integ.step(int(round(t_run / 0.01)))
        r["lax_splitting_drift_nm"], r["lax_splitting_drift_rad"] = _drift(model, integ.state.positions,
                                                                            integ.state.frames)
        tr = integrate_exact(model, t_run, n_frames=2).trajectory
        r["lax_exact_drift_nm"], r["lax_exact_drift_rad"] = _drift(model, tr.positions[-1], tr.frames[-1])
        forces = [r[k] for k in r if k.endswith("max_force")] + [r["lax_exact_rhs_max"]]
        torques = [r[k] for k in r if k.endswith("max_torque")]
        drift_nm = [r[k] for k in r if k.endswith("drift_nm")]
        drift_rad = [r[k] for k in r if k.endswith("drift_rad")]
        ok = (max(forces) < TOLERANCES["force_tol_kJmol_nm"] and max(torques) < TOLERANCES["torque_tol_kJmol"]
              and max(drift_nm) < TOLERANCES["drift_tol_nm"] and max(drift_rad) < TOLERANCES["drift_tol_rad"])
        if hx is not None:
            ok = ok and r["closed_form_position_difference_nm"] < TOLERANCES["closed_form_tol_nm"]
        r["passed"] = bool(ok)
        all_ok = all_ok and ok
        res["systems"][label] = r
    res["passed"] = bool(all_ok)
    res["notes"] = ["OpenMM drift after the run comes from the SETTLE constraint solver's sqrt(eps) precision "
                    "(node triangle sides off by ~2e-8 nm after one step), not from forces; the drift tolerance is "
                    "set above that floor (1e-7 nm, 1e-7 rad).",
                    "lax_exact_rhs_max is the largest entry of the exact system's time derivative at rest "
                    "(strain rates and body accelerations); it is compared with the force tolerance."]
    res["runtime_s"] = time.perf_counter() - t0
    return res
