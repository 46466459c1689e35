"""Check ``dispersion``: normal modes of the OpenMM engine equal the exact dispersion relation
(docs/formulation.md §8).

System: the periodic (screw-closed) twisted straight rod of the ``dna-default`` force field
(:meth:`dnarod.physics.testsystems.TwistedRod.from_forcefield`; isotropic, with its twist-stretch
coupling B33, so stretch and twist mix exactly into two branches), at its intrinsic pose.

The Hessian is built from the **OpenMM engine's** forces: each node coordinate (lab translation,
nm; lab rotation ``L -> Rot(e_a, eps) L``, rad) is displaced by +-eps, the particles are placed
rigidly, and the node forces and torques are summed from OpenMM's particle forces (both elastic
paths: the numba ``PythonForce`` and the portable ``CustomCompoundBondForce``, Reference platform).
With the mass matrix ``diag(m, L J L^T)`` the generalised eigenvalues are the squared normal-mode
frequencies, compared with :meth:`~dnarod.physics.testsystems.TwistedRod.all_frequencies` (four branches: two
stretch-twist
roots and the two bend/shear roots, each of the latter twice).
"""
from __future__ import annotations

import time

import numpy as np

import scipy.linalg

from dnarod.analysis.plots import new_figure, save_figure

NAME = "dispersion"
TOLERANCES = dict(frequency_tol_rad_per_ps=1e-6, zero_mode_tol_rad2_per_ps2=1e-8, zero_mode_cutoff_rad_per_ps=1e-2)
EPS = 1e-5


def openmm_hessian(model, elastic="fast", eps=EPS):
    """Hessian (6n, 6n) of the OpenMM engine's energy in lab node coordinates (central differences of forces).

    The differences are taken by :func:`dnarod.physics.modes.hessian_blocks` (one method for every Hessian of
    the package) with the OpenMM engine's node loads as the load function.

    Returns
    -------
    H : ndarray
        kJ/mol per (nm^2, nm rad, rad^2), symmetrised.
    asym : float
        Relative asymmetry of the raw differences before symmetrisation.
    """
    from dnarod.physics.modes import hessian_blocks
    from dnarod.engines.openmm.particles import particle_forces_to_loads, particle_positions
    from dnarod.engines.openmm.simulation import RodSimulation

    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=0.01, platform="Reference",
                        elastic=elastic, nonbonded=False, seed=0)
    radius = sim.rs.radius

    def loads(pos, frm):
        x = particle_positions(pos, frm, radius)
        sim.set_particle_positions(x)
        f = sim.node_particles(sim.context.getState(getForces=True).getForces(asNumpy=True))
        return particle_forces_to_loads(x, f)

    B = hessian_blocks(model, mass_weighted=False, load_fn=loads, rel_step=eps)
    return B.to_sparse().toarray(), B.asymmetry


def mass_matrix(model):
    """``diag(m_k I, L_k diag(J_k) L_k^T)``, shape (6n, 6n) (dense; :func:`dnarod.physics.modes.mass_matrix`)."""
    from dnarod.physics.modes import mass_matrix as sparse_mass

    return sparse_mass(model).toarray()


def labelled_spectrum(rod):
    """Analytic frequencies with branch names and wavenumbers, sorted: (omega, branch, q) arrays."""
    d = rod.dispersion()
    names = ["stretch", "twist"] if rod.B33 == 0 else ["stretch-twist low", "stretch-twist high"]
    w, b, q = [], [], []
    for key, name, qq, mult in (("stretch", names[0], d["q_axial"], 1), ("twist", names[1], d["q_axial"], 1),
                                ("bend_shear_low", "bend/shear low", d["q_bend"], 2),
                                ("bend_shear_high", "bend/shear high", d["q_bend"], 2)):
        for _ in range(mult):
            w.append(d[key])
            b += [name] * len(qq)
            q.append(qq)
    w, q, b = np.concatenate(w), np.concatenate(q), np.array(b)
    order = np.argsort(w, kind="stable")
    return w[order], b[order], q[order]


def check_dispersion(out_dir, quick=False, n_nodes=None, rod=None, reference_rod=None, plots=True):
    """Run the check.

    Parameters
    ----------
    n_nodes : int, optional
        Ring size (default 12 quick, 24 full).
    rod : TwistedRod, optional
        The system the OpenMM engine simulates (default dna-default).
    reference_rod : TwistedRod, optional
        The system whose analytic dispersion is the reference (default ``rod``; a different one
        is how the tests show the check can fail).
    """
    from dnarod.physics.testsystems import TwistedRod

    t0 = time.perf_counter()
    n_nodes = n_nodes or (12 if quick else 24)
    rod = rod or TwistedRod.from_forcefield("dna-default", n_nodes)
    reference_rod = reference_rod or rod
    model = rod.model()
    Mm = mass_matrix(model)
    w_ex, branch, q = labelled_spectrum(reference_rod)
    res = dict(TOLERANCES, system=f"dna-default twisted ring, {rod.n_nodes} nodes, theta0 = "
               f"{np.degrees(rod.theta0):.3f} deg, B33 = {rod.B33:.3f} kJ/mol", fd_step=EPS,
               omega_max_exact=float(w_ex[-1]))
    ok = True
    spectra = {}
    for elastic in ("fast", "portable"):
        H, asym = openmm_hessian(model, elastic)
        lam = scipy.linalg.eigh(H, Mm, eigvals_only=True)
        w_num = np.sign(lam) * np.sqrt(np.abs(lam))
        nonzero = w_ex > TOLERANCES["zero_mode_cutoff_rad_per_ps"]
        err = np.abs(w_num - w_ex)
        per_branch = {b: float(err[(branch == b) & nonzero].max()) for b in np.unique(branch)
                      if ((branch == b) & nonzero).any()}
        r = dict(hessian_relative_asymmetry=asym, max_frequency_error=float(err[nonzero].max()),
                 max_relative_frequency_error=float((err[nonzero] / w_ex[nonzero]).max()),
                 max_error_per_branch=per_branch, n_zero_modes=int((~nonzero).sum()),
                 max_zero_mode_eigenvalue=float(np.abs(lam[~nonzero]).max()) if (~nonzero).any() else 0.0)
        r["passed"] = bool(r["max_frequency_error"] < TOLERANCES["frequency_tol_rad_per_ps"]
                           and r["max_zero_mode_eigenvalue"] < TOLERANCES["zero_mode_tol_rad2_per_ps2"])
        ok = ok and r["passed"]
        res[f"openmm_{elastic}"] = r
        spectra[elastic] = w_num
    res["passed"] = bool(ok)
    if plots:
        res["plots"] = [_plot(out_dir, w_ex, branch, q, spectra["portable"], rod.ds)]
    res["runtime_s"] = time.perf_counter() - t0
    return res


def _plot(out_dir, w_ex, branch, q, w_num, ds):
    fig, ax = new_figure(1, 1, width=6.5, height=4.5)
    a = ax[0, 0]
    qf = np.mod(q * ds + np.pi, 2 * np.pi) - np.pi  # fold to the zone (-pi, pi]
    for j, b in enumerate(np.unique(branch)):
        s = branch == b
        o = np.argsort(qf[s])
        a.plot(qf[s][o], w_ex[s][o], "-", color=f"C{j}", lw=1, label=f"{b} (exact)")
        a.plot(qf[s], w_num[s], "x", color=f"C{j}", ms=6)
    a.set_xlabel("q ds (rad)")
    a.set_ylabel("omega (rad/ps)")
    a.set_title("normal modes: OpenMM Hessian (x) vs exact dispersion (lines)", fontsize=9)
    a.legend(fontsize=7)
    return save_figure(fig, out_dir, "dispersion.png")
