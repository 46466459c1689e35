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
  frames are held (Clamp or RotationClamp on node 0 and on node n-1), ``Lk = Tw + Wr`` of the chain
  closed by the standard magnetic-tweezers construction (:func:`closed_polygon`, :func:`open_twist`: from
  each end straight out along the pull axis far beyond the molecule, joined far to the side; Vologodskii &
  Marko 1997, Biophys. J. 73:123-132). Lk then changes by exactly the turns of the held end about the
  axis as long as the molecule does not pass around the closure. This is the one home of Tw, Wr and Lk
  of open chains (the protocols measure with it too). Cost O(n^2) per frame (numba pair
  sum), so ``lk`` is reported by default only up to :data:`LK_MAX_NODES` nodes.
"""
from __future__ import annotations

import numpy as np

from dnarod.physics.writhe import _perp, _signed_angle, _transport, twist, writhe
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Trap, clamp_angle, resolve_loads, resolve_node
from dnarod.core.units import PN

__all__ = ["extension", "applied_turns", "clamp_torque", "linking_number", "open_twist", "closed_polygon",
           "twist_writhe_open", "csv_observables", "TweezersGeometry", "LK_MAX_NODES"]

#: Largest chain for which :func:`csv_observables` reports ``lk`` by default (O(n^2) writhe per frame).
LK_MAX_NODES = 4000


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
    """Extension along the pull axis, nm (``(r_pulled - r_anchor)·axis``); NaN without a pulling force."""
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


Z = np.array([0.0, 0.0, 1.0])


def _to_axis_frame(axis):
    """A rotation R (3, 3) with ``R @ axis = z`` (Tw and Wr do not change under a rotation)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    v = np.cross(a, Z)
    s, c = np.linalg.norm(v), float(a @ Z)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = v / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * K + (1.0 - c) * K @ K


def closed_polygon(positions, axis=Z, margin=None):
    """The open chain (n, 3) extended along ``axis`` at both ends and closed far away, shape (n + 4, 3), nm.

    The chain is extended by straight legs along ``-axis`` below node 0 and ``+axis`` beyond the last node, and
    closed far away in the plane of those two parallel lines (two parallel lines are always coplanar), so the
    closure is planar: it adds no writhe of its own and no twist holonomy. ``margin`` (nm, default ``1000 x``
    the chain's extent + 1000 nm) is the length of the legs and the reach of the return path; the chain-closure
    cross terms fall off as extent/margin. This is the standard magnetic-tweezers construction (Vologodskii &
    Marko 1997, Biophys. J. 73:123-132).
    """
    R = _to_axis_frame(axis)
    P = np.asarray(positions, float) @ R.T
    ext = float(np.ptp(P, axis=0).max())
    h = 1000.0 * ext + 1000.0 if margin is None else float(margin)
    u = P[-1, :2] - P[0, :2]
    nu = np.linalg.norm(u)
    u = np.array([1.0, 0.0]) if nu < 1e-9 * max(ext, 1.0) else u / nu
    top = P[:, 2].max() + h
    bottom = P[:, 2].min() - h
    far = P[-1, :2] + h * u
    Q = np.vstack([P, [P[-1, 0], P[-1, 1], top], [far[0], far[1], top], [far[0], far[1], bottom],
                   [P[0, 0], P[0, 1], bottom]])
    return Q @ R


def open_twist(positions, ribbon, axis=Z):
    """Twist (turns) of the open polygonal ribbon with legs along ``axis`` at both ends.

    Along each chain edge: rotation of the ribbon about the edge; at each node: rotation about the next edge
    relative to parallel transport, where the edge before node 0 and the edge after the last node point along
    ``axis`` (the legs of :func:`closed_polygon`, whose planar closure adds no twist).

    Parameters
    ----------
    positions : ndarray, shape (n, 3)
        Node centres, nm.
    ribbon : ndarray, shape (n, 3)
        Ribbon vector at each node (d1), not parallel to the adjacent edges.
    axis : ndarray, shape (3,)
        Direction of the end legs (the pull axis).

    Returns
    -------
    float
    """
    R = _to_axis_frame(axis)
    P = np.asarray(positions, float) @ R.T
    U = np.asarray(ribbon, float) @ R.T
    e = np.diff(P, axis=0)
    t = e / np.linalg.norm(e, axis=1)[:, None]
    a0 = _perp(U[:-1], t)
    a1 = _perp(U[1:], t)
    along = _signed_angle(a0, a1, t).sum()
    tz = np.broadcast_to(Z, (1, 3))
    # corners: at node 0 from the leg to t_0, at interior nodes from t_{k-1} to t_k, at the last node to the leg
    t_in = np.vstack([tz, t])
    t_out = np.vstack([t, tz])
    u_in = np.vstack([_perp(U[:1], tz), a1])     # ribbon arriving at each node, perpendicular to the incoming edge
    u_out = np.vstack([a0, _perp(U[-1:], tz)])   # ribbon leaving each node, perpendicular to the outgoing edge
    corner = _signed_angle(_transport(u_in, t_in, t_out), u_out, t_out).sum()
    return float((along + corner) / (2.0 * np.pi))


def twist_writhe_open(positions, frames, axis=Z):
    """``(Tw, Wr)`` (turns) of an open chain closed along ``axis`` (:func:`open_twist`, :func:`closed_polygon`):
    ``Lk = Tw + Wr`` changes exactly by the rotation of the last node about the axis as long as the chain does not
    pass around the closure. Positions (n, 3) nm, frames (n, 3, 3)."""
    P = np.asarray(positions, float)
    return open_twist(P, np.asarray(frames)[:, :, 0], axis), float(writhe(closed_polygon(P, axis)))


def linking_number(positions, frames, geometry):
    """Lk = Tw + Wr (see the module docstring); NaN where it is not defined."""
    g = geometry
    if not g.has_lk:
        return float("nan")
    if g.circular:
        return float(twist(positions, frames[:, :, 0]) + writhe(positions))
    return float(sum(twist_writhe_open(positions, frames, g.closure_axis)))


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
