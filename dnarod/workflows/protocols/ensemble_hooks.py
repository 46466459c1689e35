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

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import hashlib
import json
from pathlib import Path
from typing import Any

from dnarod.core.errors import DnarodError
from dnarod.workflows.protocols import references as ref
from dnarod.workflows.ensemble.schema import Key
from dnarod.workflows.protocols.settings import expand_members, protocol_keys
from dnarod.physics import experiments as ex
from dnarod.workflows.protocols.tweezers import run_member
from dnarod.workflows.protocols.rings import run_ring_member


@dataclass(frozen=True)
class Plot:
    """A protocol curve's axes: the x column, the y columns (each with ``<y>_err``), labels, log x."""

    x: str
    ys: tuple[str, ...]
    x_label: str
    y_label: str
    log_x: bool = False


def _source(settings: Mapping[str, Any]) -> dict[str, Any]:
    src = settings.get("source")
    if src is None:
        raise DnarodError("source: give a node count or a sequence")
    s = str(src).strip()
    if s.isdigit():
        return {"n_bp": int(s)}
    return {"sequence": s}


def _member_platform(settings: Mapping[str, Any]) -> dict[str, Any]:
    """``platform``/``threads`` of a member from the spec (:func:`dnarod.engines.openmm.platforms.member_platform`)."""
    from dnarod.engines.openmm.platforms import member_platform  # loads OpenMM

    return member_platform(settings.get("platform"), settings.get("threads"))


def member_seed(seed: int, *key: object) -> int:
    """A distinct, reproducible seed for one member: from the curve's ``seed`` and the member's ``key``.

    Members of one curve share the base seed; run with it unchanged, members that continue each other's poses
    (:func:`dnarod.workflows.protocols.tweezers.run_member` with ``start_pose``) would restart the same noise
    stream, and two members of a static curve would draw the same noise. The member's seed is the first four bytes of
    the SHA-256 of ``[seed, *key]`` (JSON; floats as ``repr``) in [1, 2^31 - 1]: the same base seed and key always give
    the same seed (so a member's cache key and resume are reproducible), different keys different streams.

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
    parts = [int(seed)] + [repr(float(k)) if isinstance(k, (int, float)) and not isinstance(k, bool) else str(k)
                           for k in key]
    h = hashlib.sha256(json.dumps(parts).encode()).digest()
    return 1 + int.from_bytes(h[:4], "big") % (2**31 - 1)


def _member_settings(settings: Mapping[str, Any], seed: int, **specific: Any) -> dict[str, Any]:
    """A member's settings from the spec: the source, force field, times, temperature, salt, non-bonded terms,
    sampling interval, platform and friction every protocol reads, plus the protocol's own (``specific``)."""
    out = dict(_source(settings), forcefield=settings.get("forcefield") or "dna-default", **specific,
               time_ns=settings.get("time_ns"), equilibration_ns=settings.get("equilibration_ns"),
               temperature_K=settings.get("temperature_K"), salt_M=settings.get("salt_M"), seed=seed,
               excluded_volume=settings.get("excluded_volume", True),
               electrostatics=settings.get("electrostatics", True),
               charge=settings.get("charge"), cutoff_debye=settings.get("cutoff_debye"),
               sample_ps=settings.get("sample_ps"), **_member_platform(settings))
    if settings.get("friction_mode", "auto") == "fixed":
        out["friction_per_ps"] = settings.get("friction_per_ps")
    return out


class _MemberProtocol:
    """What the protocols share: their spec keys, the settings check and running a member into a row."""

    kind: str
    #: the member function (:func:`dnarod.workflows.protocols.tweezers.run_member` or
    #: :func:`dnarod.workflows.protocols.rings.run_ring_member`)
    run: Callable[[dict[str, Any], Path], dict[str, Any]]

    @property
    def keys(self) -> dict[str, Key]:
        """The protocol's own spec keys (:func:`protocol_keys`)."""
        return protocol_keys()

    def member_settings(self, settings: Mapping[str, Any]) -> dict[str, Any]:
        raise NotImplementedError

    def check(self, settings: Mapping[str, Any]) -> None:
        """Refuse a member's settings as the protocol commands do
        (:func:`dnarod.workflows.protocols.settings.expand_members`); the ensemble calls it for every member before any
        runs."""
        expand_members(self.kind, {}, dict(settings))

    def execute(self, settings: Mapping[str, Any], member_dir: str | Path,
                analysis: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Run one member (one equilibrium sample) into ``member_dir``; returns its row of scalars."""
        return flat_row(type(self).run(self.member_settings(settings), Path(member_dir)))


@dataclass(frozen=True)
class TweezersProtocol(_MemberProtocol):
    """A tweezers protocol: ``kind`` "force_extension" (torsionally free end), "magnetic_tweezers" or "torque_turns"
    (rotation clamp); ``name`` its registered name, ``plot`` its curve's axes, ``references`` the functions drawing
    measured values beside the curve (:mod:`dnarod.workflows.protocols.references`), ``missing`` what no source
    gave (said on the plot)."""

    kind: str
    name: str
    plot: Plot
    references: tuple[Callable[..., Any], ...] = ()
    missing: str | None = None
    run = staticmethod(run_member)

    def missing_note(self) -> str | None:
        """The note the curve's plot carries when no measured value could be read, or None."""
        return _missing_note(self)

    def member_settings(self, settings: Mapping[str, Any]) -> dict[str, Any]:
        """The member's settings (:func:`dnarod.workflows.protocols.tweezers.run_member`) from the spec's."""
        clamp = self.kind != "force_extension"
        turns = settings.get("turns") or 0.0
        if not clamp and turns:
            raise DnarodError(f"turns = {turns} without a rotation clamp: the force-extension protocol leaves the bead "
                              f"end torsionally free; use the magnetic-tweezers or torque-turns protocol")
        seed = member_seed(settings["seed"] if settings.get("seed") is not None else 1, self.kind,
                           settings.get("force_pN"), float(turns) if clamp else 0.0)
        out = _member_settings(settings, seed, force_pN=settings.get("force_pN"),
                               turns=float(turns) if clamp else None)
        if clamp and settings.get("rotation_clamp_kJ_mol"):
            out["clamp_k_kJ_mol"] = settings["rotation_clamp_kJ_mol"]
        return out


def flat_row(result: Mapping[str, Any]) -> dict[str, Any]:
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
class RingProtocol(_MemberProtocol):
    """Closed rings with a linking difference ``delta_lk`` (attributes as :class:`TweezersProtocol`)."""

    kind: str = "rings"
    name: str = "rings"
    plot: Plot = Plot("delta_lk", ("Wr", "Tw_minus_Tw0"), "linking difference", "turns")
    references: tuple[Callable[..., Any], ...] = (ref.writhe_fraction,)
    missing: str | None = "writhe fraction"
    run = staticmethod(run_ring_member)

    def missing_note(self) -> str | None:
        """The note the curve's plot carries when no measured writhe fraction could be read, or None."""
        return None if ex.writhe_fraction_reference() else _missing_note(self)

    def member_settings(self, settings: Mapping[str, Any]) -> dict[str, Any]:
        """The member's settings (:func:`dnarod.workflows.protocols.rings.run_ring_member`) from the spec's."""
        seed = settings["seed"] if settings.get("seed") is not None else 1
        return _member_settings(settings, seed, delta_lk=int(settings.get("delta_lk") or 0))


def _missing_note(proto: TweezersProtocol | RingProtocol) -> str | None:
    """The note a plot carries when no measured value of what the protocol measures could be read."""
    if proto.missing is None:
        return None
    if proto.kind == "torque_turns":
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


def protocol_of(kind: str) -> TweezersProtocol | RingProtocol:
    """The protocol object of ``kind`` ("force_extension", "magnetic_tweezers", "torque_turns", "rings") or of its
    name ("force-extension", ...); one line naming the known ones otherwise."""
    for p in PROTOCOLS.values():
        if kind in (p.kind, p.name):
            return p
    raise DnarodError(f"unknown protocol {kind!r}; choose one of {', '.join(PROTOCOLS)}")
