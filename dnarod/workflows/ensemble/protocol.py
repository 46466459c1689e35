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

They run on dask workers, so they must be importable (module-level) and picklable.

A spec names a protocol from dnarod's registry, never by import: a name registered in this process
(:func:`register_protocol`: ``null`` here; the protocols of :mod:`dnarod.workflows.protocols` when that
package is imported), or an entry point that an installed package declares in the group
``dnarod.protocols`` (dnarod declares its own single-molecule protocols there, in ``pyproject.toml``).
The ``"module:attribute"`` form of an entry point's value (e.g. ``"dnarod.workflows.protocols:RINGS"``)
is accepted for the same object; any other ``"module:name"`` is refused without importing anything.
Python code may pass a protocol object itself (``Ensemble(..., protocol=obj)``).
"""
from __future__ import annotations

from types import SimpleNamespace
import inspect
from importlib.metadata import entry_points


from dnarod.workflows.ensemble.schema import SpecError, Key
from dnarod.run import RunSpec, run
from dnarod.workflows.ensemble.reduce import reduce_run
from dnarod.physics.loads import tweezers

#: Protocols registered in this process: name -> object.
PROTOCOLS = {}
#: Other names of registered protocols (their ``"module:attribute"``): name -> registered name.
ALIASES = {}
#: The entry-point group in which installed packages declare protocols (name = "module:attribute").
ENTRY_POINT_GROUP = "dnarod.protocols"


def register_protocol(name, protocol, aliases=()):
    """Register the protocol object ``protocol`` as ``name`` (and as each of ``aliases``) for ensemble specs."""
    if isinstance(protocol, str):
        raise TypeError(f"register_protocol({name!r}, {protocol!r}): give the protocol object, not its import path")
    PROTOCOLS[name] = _check_hooks(protocol, name)
    for a in aliases:
        ALIASES[a] = name


def _entry_points():
    """The entry points of :data:`ENTRY_POINT_GROUP` (none if the package metadata cannot be read)."""
    try:
        return list(entry_points(group=ENTRY_POINT_GROUP))
    except Exception:  # noqa: BLE001 -- broken metadata of some installed package: no entry points
        return []


def known_protocols():
    """The protocol names a spec may give: registered here or declared as entry points (sorted)."""
    return sorted(set(PROTOCOLS) | {ep.name for ep in _entry_points()})


def _run_api():
    """``(RunSpec, run)`` of the run layer."""
    return RunSpec, run


def build_runspec(settings, model_cache=None):
    """The :class:`dnarod.run.RunSpec` of a member's settings (keys with units -> MD units).

    Loads: ``clamp_first`` -> ``Clamp(0)``; ``force_pN`` -> ``PullingForce`` on the last node
    along the initial end-to-end axis (and the opposite force on node 0 unless clamped);
    ``torque_pN_nm`` -> ``Torque`` on the last node about that axis; ``rotation_clamp_kJ_mol``
    with ``turns`` -> ``RotationClamp`` of the last node turned ``turns`` times over the run, counted from the
    torque-free state at ``temperature_K`` (its target starts turned by the 0 K offset). ``model_cache`` (a
    dict) keeps the models loaded for the loads, so checking many members of one source loads it once.
    """
    from dnarod.structure.inputs import load_model  # loads scipy.spatial: not at the CLI's start-up
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

        # turns count from the torque-free state at the member's temperature (the clamp starts turned by the 0 K
        # offset, dnarod.physics.loads.torque_free_offset)
        from dnarod.physics.loads import torque_free_offset

        offset = torque_free_offset(model, s.get("temperature_K", 300.0)) if rclamp is not None else 0.0
        loads = list(tweezers(model, force or None, torque or None, rclamp, s.get("turns", 0.0),
                              anchor="surface" if s.get("clamp_first") else "ends",
                              axis=s.get("axis", "end-to-end"), turns_offset=offset))
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
    return reduce_run(member_dir, settings, analysis)


#: The protocol used when a spec names none.
DEFAULT = SimpleNamespace(build=build_runspec, reduce=_default_reduce)


def resolve_protocol(protocol):
    """A protocol object from None (the default), an object, or a name from the registry (see the module's doc).

    A name that is neither registered nor an entry point is refused in one line listing the known names,
    without importing anything.
    """
    if protocol is None:
        return DEFAULT
    if not isinstance(protocol, str):
        return _check_hooks(protocol, protocol)
    name = ALIASES.get(protocol, protocol)
    if name in PROTOCOLS:
        return PROTOCOLS[name]
    eps = _entry_points()
    found = [ep for ep in eps if ep.name == protocol] or [ep for ep in eps if ep.value.strip() == protocol]
    if not found:
        raise SpecError(f"[ensemble] protocol {protocol!r}: not a registered name; known protocols: "
                        f"{', '.join(known_protocols()) or 'none'} (a package adds one as an entry point in the group "
                        f"{ENTRY_POINT_GROUP!r}; specs never import modules by name)")
    ep = found[0]
    try:
        obj = ep.load()
    except Exception as exc:  # noqa: BLE001 -- whatever the declared module raises on import
        raise SpecError(f"[ensemble] protocol {protocol!r}: the entry point {ep.name} = {ep.value} (package "
                        f"{getattr(ep.dist, 'name', '?')}) cannot be loaded: "
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
register_protocol("null", NULL, aliases=("dnarod.workflows.ensemble.protocol:NULL",))
# dnarod's single-molecule protocols (force-extension, magnetic-tweezers, torque-turns, rings) are entry points
# of dnarod (pyproject.toml), and registered by dnarod.workflows.protocols when it is imported
