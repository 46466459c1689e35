"""The protocol objects: what a protocol is, in one place (its settings schema, how a member runs, its curve's plot
columns and the measured references drawn beside it), for :mod:`dnarod.workflows.ensemble` (the ``execute`` hook:
one member = one equilibrium sample) and :mod:`dnarod.workflows.protocols.curves`.

A spec names one by its name (``protocol = "magnetic-tweezers"``; :data:`PROTOCOLS`). Settings read from the
ensemble's canonical keys: ``source`` (a node count or a sequence), ``forcefield``, ``force_pN``,
``turns``, ``rotation_clamp_kJ_mol`` (clamp stiffness), ``time_ns`` (production), ``temperature_K``,
``salt_M``, ``seed``, ``excluded_volume``, ``electrostatics``, ``charge``, ``cutoff_debye``, ``platform``,
``delta_lk`` (rings);
plus the protocol keys ``equilibration_ns``, ``sample_ps`` and ``friction_mode`` ("auto": critical
damping of the slowest bending mode; "fixed": the spec's ``friction_per_ps``).
"""
from __future__ import annotations

from dataclasses import dataclass

from dnarod.core.errors import DnarodError
from dnarod.workflows.protocols import references as ref


@dataclass(frozen=True)
class Plot:
    """A protocol curve's axes: the x column, the y columns (each with ``<y>_err``), labels, log x."""

    x: str
    ys: tuple
    x_label: str
    y_label: str
    log_x: bool = False


def _source(settings):
    src = settings.get("source")
    if src is None:
        raise DnarodError("source: give a node count or a sequence")
    s = str(src).strip()
    if s.isdigit():
        return {"n_bp": int(s)}
    return {"sequence": s}


def _member_platform(settings):
    """``platform``/``threads`` of a member from the spec (:func:`dnarod.engines.openmm.platforms.member_platform`)."""
    from dnarod.engines.openmm.platforms import member_platform

    return member_platform(settings.get("platform"), settings.get("threads"))


def member_seed(seed, *key):
    """A distinct, reproducible seed for one member: from the curve's ``seed`` and the member's ``key``.

    Members of one curve share the base seed; run with it unchanged, members that continue each other's poses
    (:func:`dnarod.workflows.protocols.tweezers.run_member` with ``start_pose``) would restart the same noise
    stream, and two members of a static curve would draw the same noise. The member's seed is the first four bytes of the SHA-256 of
    ``[seed, *key]`` (JSON; floats as ``repr``) in [1, 2^31 - 1]: the same base seed and key always give the
    same seed (so a member's cache key and resume are reproducible), different keys different streams.

    Parameters
    ----------
    seed : int
        The curve's (base) seed.
    *key : str, int or float
        What tells the member apart (protocol kind, force in pN, turns, how it starts, ...).

    Returns
    -------
    int
    """
    import hashlib
    import json

    parts = [int(seed)] + [repr(float(k)) if isinstance(k, (int, float)) and not isinstance(k, bool) else str(k)
                           for k in key]
    h = hashlib.sha256(json.dumps(parts).encode()).digest()
    return 1 + int.from_bytes(h[:4], "big") % (2**31 - 1)


def protocol_keys():
    from dnarod.workflows.ensemble.schema import Key

    return {k.name: k for k in [
        Key("equilibration_ns", float, None, "equilibration before sampling, ns (default 5 slowest bending "
            "relaxation times)", ">0"),
        Key("sample_ps", float, None, "time between samples, ps (default min(tau_1/10, time/200) in [1, 200] ps)",
            ">0"),
        Key("friction_mode", str, "auto", "auto: critical damping of the slowest bending mode; fixed: "
            "friction_per_ps", "auto|fixed"),
    ]}


@dataclass(frozen=True)
class TweezersProtocol:
    """A tweezers protocol: ``kind`` "force_extension" (torsionally free end), "magnetic_tweezers" or "torque_turns"
    (rotation clamp); ``name`` its registered name, ``plot`` its curve's axes, ``references`` the functions drawing
    measured values beside the curve (:mod:`dnarod.workflows.protocols.references`), ``missing`` what no source
    gave (said on the plot)."""

    kind: str
    name: str
    plot: Plot
    references: tuple = ()
    missing: str | None = None

    def missing_note(self):
        return _missing_note(self)

    @property
    def keys(self):
        return protocol_keys()

    def member_settings(self, settings):
        clamp = self.kind != "force_extension"
        turns = settings.get("turns") or 0.0
        if not clamp and turns:
            raise DnarodError(f"turns = {turns} without a rotation clamp: the force-extension protocol leaves the bead "
                              f"end torsionally free; use the magnetic-tweezers or torque-turns protocol")
        out = dict(_source(settings), forcefield=settings.get("forcefield") or "dna-default",
                   force_pN=settings.get("force_pN"), turns=float(turns) if clamp else None,
                   time_ns=settings.get("time_ns"), equilibration_ns=settings.get("equilibration_ns"),
                   temperature_K=settings.get("temperature_K"), salt_M=settings.get("salt_M"),
                   seed=member_seed(settings.get("seed") if settings.get("seed") is not None else 1, self.kind,
                                    settings.get("force_pN"), float(turns) if clamp else 0.0),
                   excluded_volume=settings.get("excluded_volume", True),
                   electrostatics=settings.get("electrostatics", True),
                   charge=settings.get("charge"), cutoff_debye=settings.get("cutoff_debye"),
                   sample_ps=settings.get("sample_ps"), **_member_platform(settings))
        if clamp and settings.get("rotation_clamp_kJ_mol"):
            out["clamp_k_kJ_mol"] = settings["rotation_clamp_kJ_mol"]
        if settings.get("friction_mode", "auto") == "fixed":
            out["friction_per_ps"] = settings.get("friction_per_ps")
        return out

    def check(self, settings):
        """Refuse a member's settings as the protocol commands do (:func:`dnarod.workflows.protocols.curves._members`);
        the ensemble calls it for every member before any runs."""
        from dnarod.workflows.protocols.curves import _members

        _members(self.kind, {}, dict(settings))

    def execute(self, settings, member_dir, analysis=None):
        from dnarod.workflows.protocols.tweezers import run_member

        return flat_row(run_member(self.member_settings(settings), member_dir))


def flat_row(result):
    """A member's result as the ensemble's row of scalars: a nested record (``nonbonded``: charge model, e per
    node, cut-off) becomes ``nonbonded_<key>`` columns; ``protocol_result.json`` keeps it nested."""
    out = {}
    for k, v in result.items():
        if isinstance(v, dict):
            out.update({f"{k}_{k2}": v2 for k2, v2 in v.items()})
        else:
            out[k] = v
    return out


@dataclass(frozen=True)
class RingProtocol:
    """Closed rings with a linking difference ``delta_lk`` (attributes as :class:`TweezersProtocol`)."""

    kind: str = "rings"
    name: str = "rings"
    plot: Plot = Plot("delta_lk", ("Wr", "Tw_minus_Tw0"), "linking difference", "turns")
    references: tuple = (ref.writhe_fraction,)
    missing: str | None = "writhe fraction"

    def missing_note(self):
        from dnarod.physics import experiments as ex

        return None if ex.writhe_fraction_reference() else _missing_note(self)

    @property
    def keys(self):
        return protocol_keys()

    def member_settings(self, settings):
        out = dict(_source(settings), forcefield=settings.get("forcefield") or "dna-default",
                   delta_lk=int(settings.get("delta_lk") or 0), time_ns=settings.get("time_ns"),
                   equilibration_ns=settings.get("equilibration_ns"), temperature_K=settings.get("temperature_K"),
                   salt_M=settings.get("salt_M"), seed=settings.get("seed") if settings.get("seed") is not None else 1,
                   excluded_volume=settings.get("excluded_volume", True),
                   electrostatics=settings.get("electrostatics", True),
                   charge=settings.get("charge"), cutoff_debye=settings.get("cutoff_debye"),
                   sample_ps=settings.get("sample_ps"), **_member_platform(settings))
        if settings.get("friction_mode", "auto") == "fixed":
            out["friction_per_ps"] = settings.get("friction_per_ps")
        return out

    def check(self, settings):
        """Refuse a member's settings as the protocol commands do (:func:`dnarod.workflows.protocols.curves._members`);
        the ensemble calls it for every member before any runs."""
        from dnarod.workflows.protocols.curves import _members

        _members(self.kind, {}, dict(settings))

    def execute(self, settings, member_dir, analysis=None):
        from dnarod.workflows.protocols.rings import run_ring_member

        return flat_row(run_ring_member(self.member_settings(settings), member_dir))


def _missing_note(proto):
    """The note a plot carries when no measured value of what the protocol measures could be read."""
    if proto.missing is None:
        return None
    if proto.kind == "torque_turns":
        from dnarod.physics import experiments as ex

        if ex.buckling_torque_reference():
            return None
    return f"no measured {proto.missing} could be read (data/README.md)"


FORCE_EXTENSION = TweezersProtocol(
    "force_extension", "force-extension",
    Plot("force_pN", ("relative_extension",), "force (pN)", "extension / contour length", log_x=True),
    (ref.wlc_persistence_lengths, ref.ewlc_curves))
# no measured hat-curve points could be read; the zero-turn extension is compared with the force-extension relation
# of the measured persistence lengths and with the curve drawn over lambda-DNA data
MAGNETIC_TWEEZERS = TweezersProtocol(
    "magnetic_tweezers", "magnetic-tweezers",
    Plot("turns", ("relative_extension",), "turns", "extension / contour length"),
    (ref.persistence_length_bar, ref.ewlc_at_zero_turns), missing="hat-curve points")
# no buckling torque or plateau could be read; the B->P transition torque bounds what B-DNA represents
TORQUE_TURNS = TweezersProtocol(
    "torque_turns", "torque-turns",
    Plot("turns", ("twist_torque_pN_nm", "clamp_torque_pN_nm"), "turns", "torque (pN nm)"),
    (ref.rotor_bead_twist_slopes, ref.other_twist_slopes, ref.transition_torques, ref.buckling_torques),
    missing="buckling torque or post-buckling plateau")
RINGS = RingProtocol()

#: The protocols by name (the names ensemble specs and the ``dnarod protocol`` commands use).
PROTOCOLS = {p.name: p for p in (FORCE_EXTENSION, MAGNETIC_TWEEZERS, TORQUE_TURNS, RINGS)}


def protocol_of(kind):
    """The protocol object of ``kind`` ("force_extension", "magnetic_tweezers", "torque_turns", "rings") or of its
    name ("force-extension", ...); one line naming the known ones otherwise."""
    for p in PROTOCOLS.values():
        if kind in (p.kind, p.name):
            return p
    raise DnarodError(f"unknown protocol {kind!r}; choose one of {', '.join(PROTOCOLS)}")
