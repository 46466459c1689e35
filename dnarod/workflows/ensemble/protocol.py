"""What a member does: build its run, and reduce the run to a row of observables.

A *protocol* is any object (a module, a class instance, a namespace) with some of:

``build(settings) -> dnarod.run.RunSpec``
    The run of one member from its settings (default :func:`build_runspec`).
``reduce(member_dir, settings, analysis) -> dict``
    Scalars (float, int, str, bool) of the finished run in ``member_dir``; they become the
    member's columns in the results table (default :func:`dnarod.workflows.ensemble.reduce.reduce_run`).
``execute(settings, member_dir, analysis) -> dict``
    Optional: do everything (several runs, say) and return the row; then ``build`` and
    ``reduce`` are not used. It must resume from what ``member_dir`` holds.
``keys`` / ``analysis_keys``
    Optional dicts name -> :class:`dnarod.workflows.ensemble.schema.Key` of extra settings it reads.

They run on dask workers, so they must be importable (module-level) and picklable. A spec names
a protocol as ``"package.module:attribute"`` or by a name registered in :data:`PROTOCOLS`.
"""
from __future__ import annotations

import importlib
from types import SimpleNamespace


from dnarod.workflows.ensemble.schema import SpecError

#: Registered protocol names -> "module:attribute".
PROTOCOLS = {}


def register_protocol(name, target):
    """Register ``name`` for ``target`` (a "module:attribute" string)."""
    PROTOCOLS[name] = target


def _run_api():
    """``(RunSpec, run)`` of the run layer."""
    from dnarod.run import RunSpec, run

    return RunSpec, run


def _loads_module():
    try:
        return importlib.import_module("dnarod.physics.loads")
    except ImportError:
        return importlib.import_module("dnarod.engines.openmm.loads")


def build_runspec(settings, model_cache=None):
    """The :class:`dnarod.run.RunSpec` of a member's settings (keys with units -> MD units).

    Loads: ``clamp_first`` -> ``Clamp(0)``; ``force_pN`` -> ``PullingForce`` on the last node
    along the initial end-to-end axis (and the opposite force on node 0 unless clamped);
    ``torque_pN_nm`` -> ``Torque`` on the last node about that axis; ``rotation_clamp_kJ_mol``
    with ``turns`` -> ``RotationClamp`` of the last node turned ``turns`` times over the run. ``model_cache`` (a
    dict) keeps the models loaded for the loads, so checking many members of one source loads it once.
    """
    from dnarod.structure.inputs import load_model
    RunSpec, _ = _run_api()
    s = settings
    loads = []
    force, torque, rclamp = s.get("force_pN", 0.0), s.get("torque_pN_nm", 0.0), s.get("rotation_clamp_kJ_mol")
    if s.get("clamp_first") or force or torque or rclamp is not None:
        key = (s["source"], s.get("forcefield", "dna-default"), bool(s.get("circular", False)),
               bool(s.get("ring", False)), s.get("delta_lk", 0))
        model = None if model_cache is None else model_cache.get(key)
        if model is None:
            model = load_model(*key)
            if model_cache is not None:
                model_cache[key] = model
        # the one tweezers set-up (dnarod.physics.loads.tweezers), with the command line's checks (overstretching, a
        # torque with no equilibrium, turns without a clamp, loads on a closed ring)
        from dnarod.physics.loads import tweezers

        loads = list(tweezers(model, force or None, torque or None, rclamp, s.get("turns", 0.0),
                              anchor="surface" if s.get("clamp_first") else "ends",
                              axis=s.get("axis", "end-to-end")))
    kw = dict(source=s["source"], forcefield=s.get("forcefield", "dna-default"), engine=s.get("engine", "openmm"),
              time_ns=s.get("time_ns", 1.0), temperature=s.get("temperature_K", 300.0),
              friction=s.get("friction_per_ps", 1.0), dt=s.get("dt_ps"), seed=s.get("seed"), loads=tuple(loads),
              salt=s.get("salt_M", 0.15), excluded_volume=s.get("excluded_volume", True),
              electrostatics=s.get("electrostatics", True), charge=s.get("charge"),
              cutoff_debye=s.get("cutoff_debye"), platform=s.get("platform"),
              circular=s.get("circular", False), ring=s.get("ring", False), delta_lk=s.get("delta_lk", 0),
              start=s.get("start", "intrinsic"), frame_interval_ps=s.get("frame_interval_ps", 1.0),
              velocities=s.get("velocities", False), export=s.get("export", False))
    if s.get("checkpoint_interval_ps") is not None:
        kw["checkpoint_interval_ps"] = s["checkpoint_interval_ps"]
    return RunSpec(**kw)


def _default_reduce(member_dir, settings, analysis):
    from dnarod.workflows.ensemble.reduce import reduce_run

    return reduce_run(member_dir, settings, analysis)


#: The protocol used when a spec names none.
DEFAULT = SimpleNamespace(build=build_runspec, reduce=_default_reduce)


def resolve_protocol(protocol):
    """A protocol object from None (the default), an object, a registered name or "module:attribute"."""
    if protocol is None:
        return DEFAULT
    if not isinstance(protocol, str):
        return _check_hooks(protocol, protocol)
    target = PROTOCOLS.get(protocol, protocol)
    if ":" not in target:
        names = ", ".join(sorted(PROTOCOLS)) or "none"
        raise SpecError(f"[ensemble] protocol {protocol!r}: not a registered name ({names}) nor "
                        f"'package.module:attribute'")
    mod, _, attr = target.partition(":")
    try:
        obj = importlib.import_module(mod)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except Exception as exc:  # ImportError, AttributeError, or whatever the module raises on import
        raise SpecError(f"[ensemble] protocol {protocol!r}: cannot import {target}: "
                        f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
    return _check_hooks(obj, protocol)


#: The hooks a protocol object may have (at least one of them).
HOOKS = ("build", "reduce", "execute")


def _check_hooks(obj, name):
    """Refuse an object that is not a protocol: none of :data:`HOOKS`, or a hook that is not callable (it
    would silently run the default protocol, or fail in every member)."""
    present = [h for h in HOOKS if hasattr(obj, h)]
    if not present:
        raise SpecError(f"[ensemble] protocol {name!r}: {type(obj).__name__} {getattr(obj, '__name__', '')!s} has "
                        f"none of build, reduce, execute; name an object with the protocol hooks (see "
                        f"dnarod.workflows.ensemble.protocol)".replace("  ", " "))
    for h in present:
        if not callable(getattr(obj, h)):
            raise SpecError(f"[ensemble] protocol {name!r}: its {h} is not callable")
    return obj


def _as_keys(keys):
    from dnarod.workflows.ensemble.schema import Key

    out = {}
    for name, k in dict(keys or {}).items():
        out[name] = k if isinstance(k, Key) else Key(name, k, None, "protocol setting")
    return out


def protocol_keys(protocol):
    """Extra keys a protocol accepts: ``{"run": {...}, "analysis": {...}}`` of
    :class:`~dnarod.workflows.ensemble.schema.Key`.

    A protocol's ``keys`` / ``analysis_keys`` map names to :class:`~dnarod.workflows.ensemble.schema.Key`
    or simply to a type (float, int, bool, str).
    """
    return {"run": _as_keys(getattr(protocol, "keys", None)),
            "analysis": _as_keys(getattr(protocol, "analysis_keys", None)),
            "needs_source": not hasattr(protocol, "execute")}


def call_hook(fn, *args):
    """Call a protocol hook with ``(settings, member_dir, analysis)``-style arguments, dropping the
    trailing ``analysis`` for hooks written with two parameters."""
    import inspect

    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return fn(*args)
    if any(p.kind is p.VAR_POSITIONAL for p in params):
        return fn(*args)
    n = sum(1 for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD))
    return fn(*args[:max(n, 1)])


def _null_execute(settings, member_dir, analysis):
    """No simulation: echo the numeric settings (for measuring the ensemble machinery itself)."""
    return {f"echo_{k}": v for k, v in settings.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}


#: A protocol that runs nothing: its members measure scheduling overhead and client memory.
NULL = SimpleNamespace(execute=_null_execute)
register_protocol("null", "dnarod.workflows.ensemble.protocol:NULL")
# the single-molecule protocols of dnarod.workflows.protocols, by name (imported only when a spec names them)
for _name, _attr in (("force-extension", "FORCE_EXTENSION"), ("magnetic-tweezers", "MAGNETIC_TWEEZERS"),
                     ("torque-turns", "TORQUE_TURNS"), ("rings", "RINGS")):
    register_protocol(_name, f"dnarod.workflows.protocols:{_attr}")
