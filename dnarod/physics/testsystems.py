"""Test systems with analytic answers (in the spirit of openmmtools.testsystems), docs/formulation.md §8.

* :class:`UniformHelix` (A5 i): a rod with constant intrinsic strains is a screw orbit; its
  nodes and frames have a closed form, its strains are the intrinsic ones and its loads vanish.
* :class:`TwistedRod` (A5 ii): the periodic, uniform, isotropic twisted straight rod and the
  exact dispersion relation of its small oscillations, all four branches (stretch, twist, and
  the two bend/shear roots); with a twist-stretch coupling ``B33`` the stretch and twist branches
  mix exactly (2x2 per wavenumber).
* :func:`thermal_tangent_correlation`: the exact thermal answer of A5 iii via :mod:`dnarod.physics.thermal`.

Units: nm, ps, amu, kJ/mol, rad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from dnarod.core.errors import ParameterError
from dnarod.core.model import RodModel
from dnarod.core.parameters import StepParameters
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.strains import Closure, chain_from_strains


@dataclass
class UniformHelix:
    """A uniform rod at its intrinsic shape: a discrete helix with a closed form (docs/formulation.md §8).

    Parameters
    ----------
    Omega0 : array_like, shape (3,)
        Intrinsic bend/twist strain, 1/nm (nonzero).
    Gamma0 : array_like, shape (3,)
        Intrinsic shear/stretch strain.
    ds : float
        nm.
    n_nodes : int
    stiffness : array_like, shape (6, 6), optional
        Default: a diagonal DNA-like stiffness.
    mass : float, amu
    inertia : array_like (3,), amu nm^2
    """

    Omega0: np.ndarray
    Gamma0: np.ndarray
    ds: float
    n_nodes: int
    stiffness: np.ndarray = None
    mass: float = 650.0
    inertia: tuple = (117.0, 117.0, 234.0)

    def __post_init__(self):
        self.Omega0 = np.asarray(self.Omega0, float)
        self.Gamma0 = np.asarray(self.Gamma0, float)
        if np.linalg.norm(self.Omega0) == 0:
            raise ParameterError("UniformHelix needs a nonzero Omega0 (a straight rod has no helix axis)")
        if self.stiffness is None:
            self.stiffness = np.diag([110.0, 110.0, 200.0, 300.0, 300.0, 700.0])

    @property
    def axis(self):
        """Unit helix axis n (same components in every body frame; lab for node 0 at identity)."""
        return self.Omega0 / np.linalg.norm(self.Omega0)

    @property
    def rotation_per_step(self):
        """theta = 2 arctan(ds |Omega0| / 2), rad."""
        return 2.0 * np.arctan(0.5 * self.ds * np.linalg.norm(self.Omega0))

    @property
    def rise_per_step(self):
        """h = ds Gamma0 . n, nm."""
        return self.ds * self.Gamma0 @ self.axis

    @property
    def radius(self):
        """rho = |Gamma0 x Omega0| sqrt(1 + ds^2 |Omega0|^2 / 4) / |Omega0|^2, nm."""
        O = self.Omega0
        return np.linalg.norm(np.cross(self.Gamma0, O)) * np.sqrt(1 + 0.25 * self.ds**2 * O @ O) / (O @ O)

    @property
    def pitch(self):
        """2 pi h / theta, nm."""
        return 2 * np.pi * self.rise_per_step / self.rotation_per_step

    def closed_form(self):
        """Exact node positions (n, 3) and frames (n, 3, 3) for node 0 at the origin with identity frame."""
        n_ax = self.axis
        theta = self.rotation_per_step
        b = self.ds * self.Gamma0
        b_perp = b - (b @ n_ax) * n_ax
        p = 0.5 * (b_perp + np.cross(n_ax, b_perp) / np.tan(0.5 * theta))
        k = np.arange(self.n_nodes)
        Rk = rotation_about_axis(np.broadcast_to(n_ax, (self.n_nodes, 3)), k * theta)
        r = p + np.outer(k * self.rise_per_step, n_ax) - Rk @ p
        return r, Rk

    def model(self):
        """A :class:`RodModel` built from the strains with :func:`chain_from_strains` (not the closed form)."""
        m = self.n_nodes - 1
        params = StepParameters.uniform(self.stiffness, np.concatenate([self.Omega0, self.Gamma0]), m, "helix")
        return RodModel.intrinsic(params, self.ds, self.mass, np.asarray(self.inertia, float))


@dataclass
class TwistedRod:
    """Periodic uniform isotropic twisted straight rod with its exact dispersion relation (docs/formulation.md §8).

    Parameters
    ----------
    n_nodes : int
        Nodes (= steps) of the ring; the screw closure is a rotation about z by ``n theta0``
        and a translation ``n ds`` along z.
    ds : float
        nm.
    theta0 : float
        Intrinsic twist per step, rad (``Omega0_3 = (2/ds) tan(theta0/2)``).
    A1, A3 : float
        Bend and twist stiffness, kJ/mol nm.
    C1, C3 : float
        Shear and stretch stiffness, kJ/mol/nm.
    B33 : float
        Twist-stretch coupling, kJ/mol (the only coupling allowed here).
    mass : float
        amu.
    J1, J3 : float
        Inertia about d1 = d2 and about d3, amu nm^2.
    """

    n_nodes: int
    ds: float = 0.34
    theta0: float = 2 * np.pi / 10.5
    A1: float = 112.73
    A3: float = 207.97
    C1: float = 294.43
    C3: float = 674.21
    B33: float = 0.0
    mass: float = 650.0
    J1: float = 117.0
    J3: float = 234.0

    @classmethod
    def from_forcefield(cls, forcefield, n_nodes, **overrides):
        """The twisted rod of a uniform, isotropic force field (e.g. ``"dna-default"``)."""
        from dnarod.core.forcefield import load_forcefield

        ff = load_forcefield(forcefield) if isinstance(forcefield, str) else forcefield
        if "*" not in ff.table:
            raise ParameterError(f"force field {ff.name} is not uniform; TwistedRod needs one step type")
        K, xi0 = ff.table["*"]
        J = ff.node_inertia
        off = K.copy()
        for i in range(6):
            off[i, i] = 0.0
        off[2, 5] = off[5, 2] = 0.0
        if (np.abs(off).max() > 0 or K[0, 0] != K[1, 1] or K[3, 3] != K[4, 4] or J[0] != J[1]
                or np.abs(xi0 - [0, 0, xi0[2], 0, 0, 1]).max() > 0):
            raise ParameterError(f"force field {ff.name} is not an isotropic straight twisted rod "
                                 f"(A1 = A2, C1 = C2, only B33 coupling, Omega0 = (0, 0, tau), Gamma0 = e3, J1 = J2)")
        kw = dict(ds=ff.ds, theta0=2 * np.arctan(0.5 * ff.ds * xi0[2]), A1=K[0, 0], A3=K[2, 2], C1=K[3, 3],
                  C3=K[5, 5], B33=K[2, 5], mass=ff.node_mass, J1=J[0], J3=J[2])
        kw.update(overrides)
        return cls(n_nodes, **kw)

    @property
    def tau0(self):
        """Omega0_3 = (2/ds) tan(theta0/2), 1/nm."""
        return 2.0 / self.ds * np.tan(0.5 * self.theta0)

    @property
    def stiffness(self):
        K = np.diag([self.A1, self.A1, self.A3, self.C1, self.C1, self.C3]).astype(float)
        K[2, 5] = K[5, 2] = self.B33
        return K

    def model(self):
        """The ring at its intrinsic pose (a :class:`RodModel` with a screw closure)."""
        n = self.n_nodes
        xi0 = np.array([0, 0, self.tau0, 0, 0, 1.0])
        params = StepParameters.uniform(self.stiffness, xi0, n, "twisted-rod")
        pos, frm = chain_from_strains(np.tile(xi0[:3], (n, 1)), np.tile(xi0[3:], (n, 1)), self.ds)
        closure = Closure(frm[-1], pos[-1])
        return RodModel(pos[:-1], frm[:-1], params, self.ds, self.mass, np.array([self.J1, self.J1, self.J3]),
                        closure=closure, metadata={"testsystem": "TwistedRod"})

    def wavenumbers(self):
        """Stretch/twist wavenumbers q_j = 2 pi j/(N ds) and bend/shear ones (2 pi j + alpha)/(N ds), 1/nm.

        ``alpha = N theta0`` is the closure rotation: the lab bend field obeys psi_{k+N} = e^{i alpha} psi_k.
        """
        n = self.n_nodes
        j = np.arange(n)
        alpha = np.mod(n * self.theta0, 2 * np.pi)
        return 2 * np.pi * j / (n * self.ds), (2 * np.pi * j + alpha) / (n * self.ds)

    def dispersion(self):
        """Exact angular frequencies (rad/ps) of every branch at the ring's wavenumbers.

        Returns
        -------
        dict
            ``"stretch"``, ``"twist"`` (shape (N,) each; with ``B33 != 0`` the two mixed
            stretch-twist roots, lower and upper), ``"bend_shear_low"``, ``"bend_shear_high"`` (shape (N,)),
            and ``"q_axial"``, ``"q_bend"`` (1/nm).
        """
        ds, m, J1, J3 = self.ds, self.mass, self.J1, self.J3
        sec = 1.0 / np.cos(0.5 * self.theta0)
        A1p, A3p, Bp = self.A1 * sec**2, self.A3 * sec**4, self.B33 * sec**2
        qa, qb = self.wavenumbers()
        sa = 4 * np.sin(0.5 * qa * ds) ** 2
        sb = 4 * np.sin(0.5 * qb * ds) ** 2
        # stretch-twist: det(s^2/ds [[C3, B'], [B', A3']] - w^2 diag(m, J3)) = 0
        a = m * J3
        b = -(self.C3 * J3 + A3p * m) * sa / ds
        c = (self.C3 * A3p - Bp**2) * sa**2 / ds**2
        disc = np.sqrt(np.maximum(b * b - 4 * a * c, 0.0))
        lo, hi = (-b - disc) / (2 * a), (-b + disc) / (2 * a)
        if self.B33 == 0:
            st, tw = self.C3 * sa / (m * ds), A3p * sa / (J3 * ds)
        else:
            st, tw = lo, hi
        # bend/shear quadratic in w^2
        a = m * J1
        b = -(self.C1 * sb * J1 / ds + (A1p * sb + ds**2 * self.C1) * m / ds)
        c = self.C1 * A1p * sb**2 / ds**2
        disc = np.sqrt(np.maximum(b * b - 4 * a * c, 0.0))
        bl, bh = (-b - disc) / (2 * a), (-b + disc) / (2 * a)
        f = lambda w2: np.sqrt(np.maximum(w2, 0.0))
        return dict(stretch=f(st), twist=f(tw), bend_shear_low=f(bl), bend_shear_high=f(bh), q_axial=qa, q_bend=qb)

    def all_frequencies(self):
        """All 6N normal-mode frequencies (rad/ps), sorted; each bend/shear root counts twice (x and y)."""
        d = self.dispersion()
        w = np.concatenate([d["stretch"], d["twist"], d["bend_shear_low"], d["bend_shear_low"],
                            d["bend_shear_high"], d["bend_shear_high"]])
        return np.sort(w)

    def omega_max(self):
        """Largest normal-mode frequency, rad/ps."""
        return float(self.all_frequencies()[-1])


def thermal_tangent_correlation(params, ds, temperature, n_max):
    """Exact ``<d3(k)·d3(k+n)>``, n = 0..n_max, of the free open chain at ``temperature`` (K)
    (docs/formulation.md §8)."""
    from dnarod.physics.thermal import tangent_correlation
    from dnarod.core.units import kT

    return tangent_correlation(params, ds, kT(temperature), n_max)


def dna_like_rod(n_nodes=20, seed=0, twist_deg=33.75, bend_noise=0.08, B33=-54.0):
    """The free open DNA-like rod (reference system of the integrator tests).

    Twist ``twist_deg`` per step, intrinsic bends drawn uniformly in +-``bend_noise`` 1/nm, the
    dna-default stiffness with twist-stretch coupling ``B33`` (kJ/mol), node mass 650 amu and
    inertia (117, 117, 234) amu nm^2, ds = 0.34 nm.

    Returns
    -------
    RodModel
        At its intrinsic shape.
    """
    from dnarod.core.forcefield import load_forcefield

    ff = load_forcefield("dna-default")
    K, _ = ff.table["*"]
    K = K.copy()
    K[2, 5] = K[5, 2] = B33
    rng = np.random.default_rng(seed)
    m = n_nodes - 1
    xi0 = np.zeros((m, 6))
    xi0[:, 2] = 2.0 / ff.ds * np.tan(0.5 * np.radians(twist_deg))
    xi0[:, :2] = rng.uniform(-bend_noise, bend_noise, (m, 2))
    xi0[:, 5] = 1.0
    params = StepParameters(np.repeat(K[None], m, 0), xi0, ["dna-like"] * m)
    return RodModel.intrinsic(params, ff.ds, ff.node_mass, ff.node_inertia)


def gaussian_coil(model, temperature=300.0, seed=0, min_distance=1.0, n_exclude=12, max_redraws=None):
    """A coiled pose of an open chain drawn from its thermal equilibrium (Gaussian approximation).

    Each step's strains are drawn independently from ``N(xi0_k, kT (ds K_k)^-1)``, the
    equilibrium density of the harmonic step energy without the Haar factor (a relative
    correction of order ``kT ds / B ~ 1e-2`` on the bending variance), and the chain is grown
    node by node (:func:`_grow_chain`). A node that comes closer than ``min_distance`` to a node
    more than ``n_exclude`` steps before it is removed with up to ``n_exclude`` nodes before it,
    the strain of the step leading to the first removed node is redrawn, and growth resumes
    (a spatial hash finds the close nodes, so the cost is O(n): about 1 s at 10^6 nodes).

    Parameters
    ----------
    model : RodModel
        Open chain (its parameters, ds; the pose is ignored).
    temperature : float
        K.
    seed : int
    min_distance : float
        nm (``0`` for no check).
    n_exclude : int
        Chain separation below which close pairs are allowed.
    max_redraws : int, optional
        Redraws before giving up (error); default ``max(10000, n_nodes)``.

    Returns
    -------
    RodModel
        The model with the coiled pose.
    """
    from dnarod.core.units import kT

    if model.closure is not None:
        raise ParameterError("gaussian_coil needs an open chain")
    rng = np.random.default_rng(seed)
    K = np.asarray(model.params.stiffness, float)
    xi0 = np.ascontiguousarray(model.params.intrinsic, float)
    L = np.ascontiguousarray(np.linalg.cholesky(kT(temperature) * np.linalg.inv(model.ds * K)))
    xi = xi0 + np.einsum("kab,kb->ka", L, rng.normal(size=xi0.shape))
    n = K.shape[0] + 1
    if min_distance <= 0:
        pos, frm = chain_from_strains(xi[:, :3], xi[:, 3:], model.ds)
        return model.with_pose(pos, frm)
    max_redraws = max(10000, n) if max_redraws is None else int(max_redraws)
    # random numbers for the redraws, drawn here so that the compiled loop needs no generator
    z = rng.normal(size=(max_redraws, 6))
    back = rng.integers(1, n_exclude + 1, size=max_redraws)
    pos = np.zeros((n, 3))
    frm = np.zeros((n, 3, 3))
    frm[0] = np.eye(3)
    used = _grow_chain(xi, xi0, L, float(model.ds), float(min_distance), int(n_exclude), z, back, pos, frm)
    if used < 0:
        raise ParameterError(f"gaussian_coil: close pairs still left after {max_redraws} redraws (lower "
                             f"min_distance)")
    return model.with_pose(pos, frm)


@numba.njit(cache=True)
def _grow_chain(xi, xi0, L, ds, dmin, n_exclude, z, back, pos, frm):
    """Grow the chain of :func:`gaussian_coil` from node 0 (``pos[0]``, ``frm[0]`` set), redrawing on
    close contacts; returns the number of redraws used, or -1 when ``z`` ran out.

    Compiled and hand-written (no library grows a chain with rejection): nodes sit in a hash of
    cubic cells of side ``dmin`` (linked lists, newest first, so removing nodes in reverse order of
    insertion pops list heads); a node is checked against the 27 cells around it.
    """
    n = pos.shape[0]
    size = 1
    while size < 2 * n:
        size *= 2
    head = np.full(size, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    key = np.zeros(n, np.int64)
    R = np.empty((3, 3))
    used = 0

    def cell_hash(ix, iy, iz):
        return ((ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791)) & (size - 1)

    def insert(j):
        ix = int(np.floor(pos[j, 0] / dmin))
        iy = int(np.floor(pos[j, 1] / dmin))
        iz = int(np.floor(pos[j, 2] / dmin))
        h = cell_hash(ix, iy, iz)
        key[j] = h
        nxt[j] = head[h]
        head[h] = j

    insert(0)
    j = 1
    while j < n:
        k = j - 1
        # node j from node k and step k's strains: R = cayley(ds Omega), c_j = c_k + ds F_k Gamma
        w0, w1, w2 = ds * xi[k, 0], ds * xi[k, 1], ds * xi[k, 2]
        den = 1.0 + 0.25 * (w0 * w0 + w1 * w1 + w2 * w2)
        W = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
        W2 = W @ W
        for a in range(3):
            for b in range(3):
                R[a, b] = (1.0 if a == b else 0.0) + (W[a, b] + 0.5 * W2[a, b]) / den
        for a in range(3):
            acc = 0.0
            for b in range(3):
                acc += frm[k, a, b] * xi[k, 3 + b]
            pos[j, a] = pos[k, a] + ds * acc
            for b in range(3):
                acc = 0.0
                for c in range(3):
                    acc += frm[k, a, c] * R[c, b]
                frm[j, a, b] = acc
        # contact with a node more than n_exclude steps back?
        ix = int(np.floor(pos[j, 0] / dmin))
        iy = int(np.floor(pos[j, 1] / dmin))
        iz = int(np.floor(pos[j, 2] / dmin))
        clash = False
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    i = head[cell_hash(ix + dx, iy + dy, iz + dz)]
                    while i >= 0 and not clash:
                        if i < j - n_exclude:
                            d2 = ((pos[i, 0] - pos[j, 0]) ** 2 + (pos[i, 1] - pos[j, 1]) ** 2
                                  + (pos[i, 2] - pos[j, 2]) ** 2)
                            clash = d2 < dmin * dmin
                        i = nxt[i]
        if not clash:
            insert(j)
            j += 1
            continue
        if used >= z.shape[0]:
            return -1
        # remove nodes j-1 .. j0 (newest first) and redraw step j0 - 1
        j0 = max(1, j - back[used])
        for m in range(j - 1, j0 - 1, -1):
            head[key[m]] = nxt[m]
        k = j0 - 1
        for a in range(6):
            acc = 0.0
            for b in range(6):
                acc += L[k, a, b] * z[used, b]
            xi[k, a] = xi0[k, a] + acc
        used += 1
        j = j0
    return used


def plectoneme_centres(n_nodes, ds=0.34, radius=1.05, pitch=6.0):
    """Node centres (n, 3) nm of a synthetic plectoneme: two interwound right-handed helices.

    One chain runs up a helix of superhelical ``radius`` and ``pitch`` (nm) about the z axis,
    turns through a semicircular end loop and runs back down the second helix, shifted by half
    a turn, so nodes far apart along the chain face each other ``2 radius`` apart across the
    axis. Consecutive centres are ``ds`` apart along the curve (to first order).
    """
    n_loop = max(1, int(round(np.pi * radius / ds)) - 1)
    n_arm = (n_nodes - n_loop) // 2
    n_loop = n_nodes - 2 * n_arm
    dtheta = ds / np.hypot(radius, pitch / (2 * np.pi))
    th = np.arange(n_arm) * dtheta
    up = np.stack([radius * np.cos(th), radius * np.sin(th), pitch * th / (2 * np.pi)], axis=1)
    top = th[-1] if n_arm else 0.0
    z_top = pitch * top / (2 * np.pi)
    phi = np.linspace(0, np.pi, n_loop + 2)[1:-1]
    # end loop: a semicircle of radius `radius` above the top, from (angle top) to (angle top + pi)
    loop = np.stack([radius * np.cos(top + phi), radius * np.sin(top + phi),
                     z_top + radius * np.sin(phi)], axis=1)
    down = up[::-1].copy()
    down[:, :2] = -down[:, :2]  # half a turn about the axis: the second strand
    return np.concatenate([up, loop, down])[:n_nodes]
