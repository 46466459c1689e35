"""Per-frame tweezers observables from node positions/frames and the loads (both engines).

* ``extension_nm`` -- extension along the pull axis: ``(r_pulled - r_anchor) . a``, a the unit vector of
  the (largest) pulling force, the pulled node its node, the anchor the first clamped or trapped node
  that is not pulled (else the chain end farthest from the pulled node). nm.
* ``turns`` -- turns applied by the (first) rotation clamp at this time (``clamp_angle / 2 pi``).
* ``clamp_torque_pN_nm`` -- torque the (first) rotation clamp applies to its node, about the clamp
  axis, pN nm (positive when the clamp drives the node right-handedly about the axis, i.e. the
  torque in the molecule for a positively turned clamp).
* ``lk`` -- linking number ``Lk = Tw + Wr`` of the base-pair ribbon (centreline through the node
  centres, ribbon vector d1), with Tw and Wr from :mod:`dnarod.physics.writhe` (one home):
  for a ring (identity closure) of the closed ribbon (an integer); for an open chain whose two end
  frames are held (Clamp or RotationClamp on node 0 and on node n-1), ``Lk = Tw(chain) + Wr(closed
  curve)``, the curve closed by the standard magnetic-tweezers construction: from each end straight
  out along the pull axis far beyond the molecule, joined by a segment far to the side (Vologodskii &
  Marko 1997, Biophys. J. 73:123-132, "Extension of torsionally stressed DNA by external force";
  the closure carries writhe only). Lk then changes by exactly the turns of the held end about the
  axis as long as the molecule does not pass around the closure. Cost O(n^2) per frame (numba pair
  sum), so ``lk`` is reported by default only up to :data:`LK_MAX_NODES` nodes.
"""
from __future__ import annotations

import numpy as np

from dnarod.physics.writhe import _perp, _signed_angle, _transport, twist, writhe
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Trap, clamp_angle, resolve_loads, resolve_node
from dnarod.core.units import PN

__all__ = ["extension", "applied_turns", "clamp_torque", "linking_number", "open_twist", "csv_observables",
           "TweezersGeometry", "LK_MAX_NODES"]

#: Largest chain for which :func:`csv_observables` reports ``lk`` by default (O(n^2) writhe per frame).
LK_MAX_NODES = 4000
#: Closure legs of an open chain: this many times the molecule's size beyond it.
CLOSURE_FACTOR = 100.0


class TweezersGeometry:
    """Which nodes and axis define the observables of a set of loads on a model.

    Attributes
    ----------
    pulled, anchor : int or None
        Node indices (``None`` without a pulling force).
    axis : ndarray (3,) or None
        Unit pull axis (lab).
    rotation_clamp : RotationClamp or None
        The first rotation clamp (its node resolved in ``rc_node``; its axis in ``rc_axis``).
    ends_held : bool
        Both end frames are held (open chain), so Lk is defined with the closure.
    """

    def __init__(self, model, loads):
        loads = tuple(loads or ())
        n = model.n_nodes
        rl = resolve_loads(loads, model)
        self.n_nodes = n
        self.circular = model.circular
        pulls = [ld for ld in loads if isinstance(ld, PullingForce)]
        self.pulled = self.anchor = self.axis = None
        if pulls:
            big = max(range(len(pulls)), key=lambda i: (np.linalg.norm(pulls[i].force), i))
            self.pulled = resolve_node(pulls[big].node, n)
            self.axis = pulls[big].force / np.linalg.norm(pulls[big].force) if np.any(pulls[big].force) else None
            held = [resolve_node(ld.node, n) for ld in loads if isinstance(ld, (Clamp, Trap))]
            held = [k for k in held if k != self.pulled]
            self.anchor = held[0] if held else (0 if self.pulled > (n - 1) / 2 else n - 1)
            if self.axis is None:
                self.pulled = None
        rcs = [ld for ld in loads if isinstance(ld, RotationClamp)]
        self.rotation_clamp = rcs[0] if rcs else None
        self.rc_index = 0
        self.rc_node = rl.rotation_clamps[0].node if rcs else None
        self.rc_axis = rl.rotation_clamps[0].axis if rcs else None
        self.resolved = rl
        held_frames = set(np.flatnonzero(rl.clamped).tolist()) | {c.node for c in rl.rotation_clamps}
        self.ends_held = (not model.circular) and {0, n - 1} <= held_frames
        ring = model.circular and np.allclose(model.closure.Q, np.eye(3)) and np.allclose(model.closure.t, 0.0)
        self.has_lk = bool(ring or self.ends_held)
        if self.ends_held:
            a = self.axis if self.axis is not None else self.rc_axis
            if a is None:
                e = model.positions[-1] - model.positions[0]
                a = e / np.linalg.norm(e)
            self.closure_axis = np.asarray(a, float)
        else:
            self.closure_axis = None


def extension(positions, geometry):
    """Extension along the pull axis, nm (``(r_pulled - r_anchor) . axis``); NaN without a pulling force."""
    g = geometry
    if g.pulled is None:
        return float("nan")
    return float((positions[g.pulled] - positions[g.anchor]) @ g.axis)


def applied_turns(geometry, time_ps, duration_ps=None):
    """Turns applied by the first rotation clamp at ``time_ps``; NaN without one."""
    if geometry.rotation_clamp is None:
        return float("nan")
    return clamp_angle(geometry.rotation_clamp, time_ps, duration_ps) / (2 * np.pi)


def clamp_torque(frames, geometry, time_ps, duration_ps=None):
    """Torque of the first rotation clamp on its node about the clamp axis, pN nm; NaN without one."""
    g = geometry
    if g.rotation_clamp is None:
        return float("nan")
    angles = g.resolved.clamp_angles(time_ps, duration_ps)
    tau = g.resolved.clamp_torques(frames, angles)[0]
    return float(tau @ g.rc_axis) / PN


def open_twist(points, ribbon):
    """Twist (turns) of an open polygonal ribbon: the along-edge rotations of the ribbon plus the
    parallel-transport corners at the interior vertices (the open form of
    :func:`dnarod.physics.writhe.twist`, with its helpers)."""
    P = np.asarray(points, float)
    U = np.asarray(ribbon, float)
    e = P[1:] - P[:-1]
    t = e / np.linalg.norm(e, axis=1)[:, None]
    a0 = _perp(U[:-1], t)
    a1 = _perp(U[1:], t)
    along = _signed_angle(a0, a1, t)
    moved = _transport(a1[:-1], t[:-1], t[1:])
    corner = _signed_angle(moved, a0[1:], t[1:])
    return float((along.sum() + corner.sum()) / (2 * np.pi))


def closure_points(positions, axis):
    """Vertices (4, 3) closing an open chain far along ``axis`` (see the module docstring), nm."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    h = positions @ a
    size = max(float(np.ptp(positions, axis=0).max()), 1.0)
    far = CLOSURE_FACTOR * size
    x = np.cross(a, [1.0, 0.0, 0.0])
    if np.linalg.norm(x) < 0.5:
        x = np.cross(a, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    top = h.max() + far
    bot = h.min() - far
    A = positions[-1] + (top - h[-1]) * a
    D = positions[0] + (bot - h[0]) * a
    return np.array([A, A + far * x, D + far * x, D])


def linking_number(positions, frames, geometry):
    """Lk = Tw + Wr (see the module docstring); NaN where it is not defined."""
    g = geometry
    if not g.has_lk:
        return float("nan")
    d1 = frames[:, :, 0]
    if g.circular:
        return float(twist(positions, d1) + writhe(positions))
    closed = np.concatenate([positions, closure_points(positions, g.closure_axis)])
    return float(open_twist(positions, d1) + writhe(closed))


def csv_observables(model, loads=(), duration_ps=None, lk=None):
    """The observable columns defined by ``loads`` on ``model`` and a function computing them per frame.

    Parameters
    ----------
    model : RodModel
    loads : sequence of :mod:`dnarod.physics.loads` dataclasses
    duration_ps : float, optional
        Run length (ps) over which rotation clamps' ``turns`` are spread.
    lk : bool, optional
        Report ``lk`` (default: when defined and the chain has at most :data:`LK_MAX_NODES` nodes).

    Returns
    -------
    callable
        ``obs(snapshot) -> dict`` column -> float, where ``snapshot.state = (positions (n,3) nm,
        frames (n,3,3), ...)`` and ``snapshot.time_ps``; attribute ``columns`` (list of str, a subset
        of ``extension_nm, turns, clamp_torque_pN_nm, lk`` in that order) and ``geometry``.
    """
    g = TweezersGeometry(model, loads)
    cols = []
    if g.pulled is not None:
        cols.append("extension_nm")
    if g.rotation_clamp is not None:
        cols += ["turns", "clamp_torque_pN_nm"]
    want_lk = g.has_lk and (model.n_nodes <= LK_MAX_NODES if lk is None else bool(lk))
    if want_lk:
        cols.append("lk")

    def obs(snapshot):
        pos, frm = snapshot.state[0], snapshot.state[1]
        pos = np.asarray(pos, float)
        frm = np.asarray(frm, float)
        t = float(snapshot.time_ps)
        out = {}
        if "extension_nm" in cols:
            out["extension_nm"] = extension(pos, g)
        if "turns" in cols:
            out["turns"] = applied_turns(g, t, duration_ps)
            out["clamp_torque_pN_nm"] = clamp_torque(frm, g, t, duration_ps)
        if "lk" in cols:
            out["lk"] = linking_number(pos, frm, g)
        return out

    obs.columns = cols
    obs.geometry = g
    return obs
