"""Check ``engines``: the OpenMM engine and the direct Lax-form integrator agree in NVE.

From one initial state (the Dickerson dodecamer 355D built from the bundled PDB with the
``dna-default`` force field, Maxwell velocities at 300 K with drift removed), the check runs

* the **Lax-form reference**: the exact strain-space system of docs/formulation.md §6
  (:func:`dnarod.engines.lax.integrate_exact`, DOP853, rtol = atol = 1e-12), whose time error is
  negligible here;
* the **OpenMM engine** (:class:`dnarod.engines.openmm.simulation.RodSimulation`, ``VerletIntegrator``,
  Reference platform, no non-bonded terms, constraint tolerance 1e-12) at a ladder of time steps,
  started exactly as a user starts it (``initial_velocities=(v, omega)``);
* the same OpenMM runs with leapfrog half-step velocities set by this module instead
  (independent diagnostic, see below);
* the Lax-form splitting integrator (:class:`dnarod.engines.lax.SplittingIntegrator`) at the same
  steps.

Compared over time: node positions (nm), frames (rotation angle, rad), total energy (kJ/mol),
momentum and angular momentum. Both engines must converge to the reference as dt^2, agree below
1e-6 nm at the smallest step, conserve momentum and angular momentum to 1e-8 relative, and use the
same node inertia and velocity convention (checked by a round trip through the OpenMM particles).

OpenMM's ``VerletIntegrator`` is a leapfrog: the velocities it stores belong to t - dt/2. A velocity
stored as if it were v(0) is off by ``dt/2 a(0)``, an O(dt) error that makes the whole trajectory
first order (measured: order 1.00 before ``RodSimulation.set_node_velocities`` took the half kick
off). The diagnostic runs set particle velocities ``u_i(0) - dt/2 du_i/dt(0)`` from rigid-body
kinematics (Euler and centripetal terms included), independently of the engine's own correction.
"""
from __future__ import annotations

import time

import numpy as np

from dnarod.core.units import md_value

from dnarod.core.errors import DnarodError
from dnarod.validate._common import observed_order, pairwise_orders, rotation_angle
from dnarod.analysis.plots import new_figure, save_figure
from dnarod.structure import model_from_structure
from dnarod.structure._data import data_file
from dnarod.engines.openmm.particles import BODY_OFFSETS, particle_velocities
from dnarod.engines.lax import RigidState, SplittingIntegrator, integrate_exact
from dnarod.engines.lax.splitting import maxwell_state

NAME = "engines"
PDB = "355D.pdb"
#: Momentum tolerances are relative to the scales sum_k m_k |v_k| and sum_k (|r_k x p_k| + |J_k omega_k|).
TOLERANCES = dict(order_min=1.8, order_max=2.2, small_dt_position_tol_nm=1e-6, relative_momentum_tol=1e-8,
                  relative_angular_momentum_tol=1e-8)


def default_model():
    """The 355D dodecamer with dna-default parameters (12 nodes, pose from the crystal structure)."""
    return model_from_structure(data_file("structures", PDB), forcefield="dna-default")


def _half_step_particle_velocities(model, radius, v, w, dt):
    """Particle velocities at t = -dt/2 (to O(dt^2)) of rigid nodes moving with (v lab, w body) at t = 0.

    ``u_i = v + L (w x b_i)`` with body offsets ``b_i``; ``du_i/dt = F/m + L (wdot x b_i + w x (w x b_i))``,
    ``wdot = J^-1 (L^T tau - w x J w)`` (Euler), loads from :func:`dnarod.core.energy.loads`.
    """
    _, F, tau = model.loads()
    J = model.inertia
    wdot = (np.einsum("kji,kj->ki", model.frames, tau) - np.cross(w, J * w)) / J
    b = BODY_OFFSETS[None] * np.asarray(radius)[:, None, None]
    wb = w[:, None, :]
    acc_body = np.cross(wdot[:, None, :], b) + np.cross(wb, np.cross(wb, b))
    acc = (F / model.mass[:, None])[:, None, :] + np.einsum("kab,kib->kia", model.frames, acc_body)
    u = particle_velocities(model.frames, radius, v, w).reshape(-1, 3, 3)
    return (u - 0.5 * dt * acc).reshape(-1, 3)


def _openmm_run(model, v, w, dt, t_report, half_step, elastic="auto"):
    """OpenMM NVE run; positions, frames, energy, momentum, angular momentum at ``t_report``."""
    from dnarod.engines.openmm.simulation import RodSimulation  # loads OpenMM

    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=dt, platform="Reference",
                        elastic=elastic, nonbonded=False, initial_velocities=(v, w),
                        constraint_tolerance=1e-12, seed=0)
    if half_step:
        sim.context.setVelocities(_half_step_particle_velocities(model, sim.rs.radius, v, w, dt))
    pm = np.repeat(model.mass / 3.0, 3)[:, None]
    steps = np.rint(np.asarray(t_report) / dt).astype(int)
    out = {k: [] for k in ("positions", "frames", "energy", "momentum", "angular_momentum")}
    for s in steps:
        if s > sim.step:
            sim.advance(s - sim.step)
        st = sim.context.getState(getPositions=True, getVelocities=True, getEnergy=True)
        x = md_value(st.getPositions(asNumpy=True))
        u = md_value(st.getVelocities(asNumpy=True))
        c, f = sim.node_pose(st)
        out["positions"].append(c)
        out["frames"].append(f)
        out["energy"].append(md_value(st.getPotentialEnergy()) + md_value(st.getKineticEnergy()))
        out["momentum"].append((pm * u).sum(0))
        out["angular_momentum"].append(np.cross(x, pm * u).sum(0))
    return {k: np.array(a) for k, a in out.items()}


def _lax_splitting_run(model, v, w, dt, t_report):
    integ = SplittingIntegrator(model, dt, state=RigidState.from_model(model, v, w), check_stability=False)
    steps = np.rint(np.asarray(t_report) / dt).astype(int)
    out = {k: [] for k in ("positions", "frames", "energy", "momentum", "angular_momentum")}
    for s in steps:
        if s > integ.step_count:
            integ.step(s - integ.step_count)
        st = integ.state
        out["positions"].append(st.positions.copy())
        out["frames"].append(st.frames.copy())
        out["energy"].append(integ.total_energy())
        P, L = st.total_momentum()
        out["momentum"].append(P)
        out["angular_momentum"].append(L)
    return {k: np.array(a) for k, a in out.items()}


def _conventions(model, v, w):
    """Same node inertia and velocity convention in both engines?

    The OpenMM triangle's principal inertia ``m l^2 (1/2, 1/2, 1)`` against the model's (which the
    Lax-form engine uses), and the round trip of (v lab, omega body) through the OpenMM particles.
    """
    from dnarod.engines.openmm.simulation import RodSimulation  # loads OpenMM

    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=0.001, platform="Reference",
                        nonbonded=False, initial_velocities=(v, w), seed=0)
    r = sim.rs.radius
    J_openmm = model.mass[:, None] * r[:, None] ** 2 * np.array([0.5, 0.5, 1.0])
    _, _, v2, w2 = sim.node_state()
    return dict(inertia_relative_difference=float(np.abs(J_openmm / model.inertia - 1).max()),
                velocity_roundtrip_error_nm_per_ps=float(np.abs(v2 - v).max()),
                angular_velocity_roundtrip_error_rad_per_ps=float(np.abs(w2 - w).max()),
                angular_velocity_frame="body (components on d1, d2, d3) in both engines")


def _differences(run, ref):
    """Time series (n_report,) of the largest differences of a run from the reference."""
    return dict(
        position_nm=np.abs(run["positions"] - ref["positions"]).max(axis=(1, 2)),
        frame_rad=rotation_angle(run["frames"], ref["frames"]).max(axis=1),
        energy_kJmol=np.abs(run["energy"] - ref["energy"]),
        momentum=np.linalg.norm(run["momentum"] - ref["momentum"], axis=1),
        angular_momentum=np.linalg.norm(run["angular_momentum"] - ref["angular_momentum"], axis=1),
    )


def check_engines(out_dir, quick=False, model=None, lax_model=None, temperature=300.0, seed=1, t_end=2.0,
                  dts=None, plots=True):
    """Run the check.

    Parameters
    ----------
    out_dir : str or Path
        Where the plot goes.
    quick : bool
        Shorter time-step ladder.
    model : RodModel, optional
        Initial state and the OpenMM engine's model (default :func:`default_model`).
    lax_model : RodModel, optional
        The model the Lax-form engine integrates (default ``model``; a different one is how the
        tests show the check can fail).
    temperature : float
        K, initial Maxwell velocities.
    t_end : float
        ps.
    dts : sequence of float, optional
        ps, decreasing by halves.

    Returns
    -------
    dict
    """
    t0 = time.perf_counter()
    model = default_model() if model is None else model
    lax_model = model if lax_model is None else lax_model
    if dts is None:
        dts = [0.02, 0.01, 0.005, 0.0025] if quick else [0.02, 0.01, 0.005, 0.0025, 0.00125]
    dts = [float(x) for x in dts]
    state = maxwell_state(model, temperature, seed=seed)
    v, w = state.velocities(model.mass, model.inertia)
    # Report times: multiples of the largest step, so every run of the ladder lands on them exactly.
    every = max(1, int(round(t_end / 20 / dts[0])))
    t_rep = dts[0] * every * np.arange(int(round(t_end / (dts[0] * every))) + 1)
    for dt in dts:
        if abs(dts[0] * every / dt - round(dts[0] * every / dt)) > 1e-9:
            raise DnarodError(f"time step {dt} ps does not divide the report interval {dts[0] * every} ps; "
                              f"use a ladder of halvings of the first step")
    ex = integrate_exact(lax_model, t_end, v, w, rtol=1e-12, atol=1e-12, t_eval=t_rep)
    ref = dict(positions=ex.trajectory.positions, frames=ex.trajectory.frames, energy=ex.energy,
               momentum=ex.momentum, angular_momentum=ex.angular_momentum)
    series = {"openmm": [], "openmm_half_step": [], "lax_splitting": []}
    for dt in dts:
        series["openmm"].append(_differences(_openmm_run(model, v, w, dt, t_rep, half_step=False), ref))
        series["openmm_half_step"].append(_differences(_openmm_run(model, v, w, dt, t_rep, half_step=True), ref))
        series["lax_splitting"].append(_differences(_lax_splitting_run(lax_model, v, w, dt, t_rep), ref))
    conv = _conventions(model, v, w)
    res = dict(conventions=conv,
               model=f"{PDB} dna-default ({model.n_nodes} nodes), Maxwell velocities {temperature:g} K seed {seed}",
               t_end_ps=t_end, dt_ps=dts, reference="Lax-form exact strain-space system, DOP853 rtol=atol=1e-12",
               reference_energy_drift_kJmol=float(np.ptp(ex.energy)),
               initial_energy_kJmol=float(ex.energy[0]))
    for name, runs in series.items():
        mx = {q: np.array([r[q].max() for r in runs]) for q in runs[0]}
        res[name] = dict(
            max_position_difference_nm=mx["position_nm"], max_frame_difference_rad=mx["frame_rad"],
            max_energy_difference_kJmol=mx["energy_kJmol"], max_momentum_difference=mx["momentum"],
            max_angular_momentum_difference=mx["angular_momentum"],
            order_positions=observed_order(dts, mx["position_nm"]),
            pairwise_orders_positions=pairwise_orders(dts, mx["position_nm"]),
            order_frames=observed_order(dts, mx["frame_rad"]),
            order_energy=observed_order(dts, mx["energy_kJmol"]))
    p_scale = float(np.sum(model.mass * np.linalg.norm(v, axis=1)))
    L_scale = float(np.sum(np.linalg.norm(np.cross(model.positions, model.mass[:, None] * v), axis=1))
                    + np.sum(np.linalg.norm(model.inertia * w, axis=1)))
    for name in series:
        res[name]["relative_momentum_difference"] = res[name]["max_momentum_difference"].max() / p_scale
        res[name]["relative_angular_momentum_difference"] = res[name]["max_angular_momentum_difference"].max() / L_scale
    res.update(momentum_scale=p_scale, angular_momentum_scale=L_scale)
    res.update(TOLERANCES)

    def ok(name):
        r = res[name]
        return bool(TOLERANCES["order_min"] <= r["order_positions"] <= TOLERANCES["order_max"]
                    and TOLERANCES["order_min"] <= r["order_frames"] <= TOLERANCES["order_max"]
                    and r["max_position_difference_nm"][-1] < TOLERANCES["small_dt_position_tol_nm"]
                    and r["relative_momentum_difference"] < TOLERANCES["relative_momentum_tol"]
                    and r["relative_angular_momentum_difference"] < TOLERANCES["relative_angular_momentum_tol"])

    res["openmm_passed"] = ok("openmm")
    res["openmm_half_step_passed"] = ok("openmm_half_step")
    res["lax_splitting_passed"] = ok("lax_splitting")
    # The check is about the engines as users run them: OpenMM started through its public API.
    res["same_conventions_passed"] = bool(conv["inertia_relative_difference"] < 1e-12
                                          and conv["velocity_roundtrip_error_nm_per_ps"] < 1e-12
                                          and conv["angular_velocity_roundtrip_error_rad_per_ps"] < 1e-12)
    res["passed"] = res["openmm_passed"] and res["lax_splitting_passed"] and res["same_conventions_passed"]
    notes = []
    if not res["openmm_passed"] and res["openmm_half_step_passed"]:
        notes.append("OpenMM engine started with initial_velocities=(v, omega) is first order: its "
                     "VerletIntegrator is a leapfrog whose stored velocities belong to t - dt/2, and "
                     "RodSimulation.set_node_velocities stores v(0) there; with half-step initial velocities "
                     "(u_i(0) - dt/2 du_i/dt) the same engine converges at second order.")
    res["notes"] = notes
    if plots:
        res["plots"] = [_plot(out_dir, t_rep, dts, series)]
    res["runtime_s"] = time.perf_counter() - t0
    return res


def _plot(out_dir, t, dts, series):
    fig, ax = new_figure(3, 1, width=5.0, height=3.8)
    for j, (name, title) in enumerate((("openmm", "OpenMM (public API) - Lax exact"),
                                       ("openmm_half_step", "OpenMM (half-step v0) - Lax exact"),
                                       ("lax_splitting", "Lax splitting - Lax exact"))):
        a = ax[0, j]
        for dt, r in zip(dts, series[name]):
            a.semilogy(t[1:], r["position_nm"][1:], label=f"dt = {dt:g} ps")
        a.axhline(1e-6, color="k", ls=":", lw=0.8)
        a.set_xlabel("time (ps)")
        a.set_ylabel("max |r - r_ref| (nm)")
        a.set_title(title, fontsize=9)
        a.legend(fontsize=7)
    return save_figure(fig, out_dir, "engines_differences.png")
