"""What defines a run: :class:`RunSpec`, its checks, and the fingerprint a resume must match.

Units: time ns (``time_ns``) or ps (``dt``, intervals), temperature K, friction 1/ps, salt mol/L.
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace

import numpy as np

from dnarod.core.errors import ParameterError
from dnarod.core.model import model_fingerprint, RodModel
from dnarod.physics.nonbonded import scales_temperature, NonbondedSettings, member_nonbonded, nonbonded_record
from dnarod.run.loop import CHECKPOINT_WALL_S
from dnarod.core.io import jsonable

ENGINES = ("openmm", "lax", "mc")
STARTS = ("intrinsic", "equilibrium", "minimized")
ELASTIC = ("auto", "plugin", "fast", "portable")
#: Largest accepted monovalent salt, mol/L (saturated NaCl is ~6 M).
MAX_SALT = 6.0
#: Highest accepted temperature, K: the model's solvent (its Langevin friction, the dielectric constant 78.5 of the
#: Debye-Hueckel screening) is liquid water, which boils at 373.15 K (100 degC) at 1 atm; far above it the runs blow
#: up (a member at 1e9 K failed at its first step), so more is a typo.
MAX_TEMPERATURE = 373.15


def _finite(name: str, v: Any, cond: Callable[[float], bool], what: str, option: str | None = None) -> float:
    """``v`` as a finite float satisfying ``cond``, else one line naming the option (``--name`` by default)."""
    opt = option or "--" + name.replace("_", "-")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ParameterError(f"{opt} {v!r}: must be a number ({what})") from None
    if not (math.isfinite(x) and cond(x)):
        raise ParameterError(f"{opt} {v:g}: must be {what}")
    return x


def _integer(opt: str, v: Any, cond: Callable[[int], bool], what: str) -> int:
    """``v`` as an integer satisfying ``cond`` (a whole float or numeric string counts), else one line."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer, float, np.floating, str)):
        raise ParameterError(f"{opt} {v!r}: must be an integer ({what})")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ParameterError(f"{opt} {v!r}: must be an integer ({what})") from None
    if not (math.isfinite(x) and x == int(x) and cond(int(x))):
        raise ParameterError(f"{opt} {v}: must be an integer {what}")
    return int(x)


@dataclass(frozen=True)
class RunSpec:
    """Everything that defines a simulation run, for both engines.

    Parameters
    ----------
    source : str, Path, int or RodModel
        PDB/mmCIF path, model ``.npz``, DNA sequence, FASTA/text sequence file, node count, or a model.
    forcefield : str
        Bundled force-field name or ``.toml`` path.
    engine : {"openmm", "lax", "mc"}
        OpenMM engine, the direct Lax-form integrator, or the Monte Carlo sampler
        (:class:`dnarod.engines.mc.engine.MCEngine`; its times count sweeps: 1 ps = 1 sweep, so ``time_ns=1`` is 1000
        sweeps; ``friction`` and ``dt`` do not apply).
    time_ns : float
        Total simulated time of the run, ns (a resumed run continues up to it).
    temperature : float
        K (thermostat and initial Maxwell velocities; 0 starts at rest).
    friction : float
        Langevin collision rate, 1/ps; ``0`` runs NVE (constant energy) from Maxwell velocities.
    dt : float or None
        Time step, ps; default ``0.4 / omega_max`` of the loaded model.
    seed : int or None
        Seed of the initial velocities and the noise; None draws one (recorded in ``run.json``).
    loads : tuple
        External loads (:mod:`dnarod.physics.loads` dataclasses), MD units.
    salt, excluded_volume, electrostatics
        Non-bonded interactions (OpenMM engine; the Lax engine has none and refuses them on).
    charge, cutoff_debye : str or float, float, optional
        Non-bonded charge model (``"calibrated"``, ``"manning"`` or e per base pair) and Debye-Hueckel cutoff
        (Debye lengths) of :class:`dnarod.physics.nonbonded.NonbondedSettings`; ``None``: its defaults. What they
        resolve to (model, e per node, cutoff in nm and Debye lengths) is recorded in the run's fingerprint.
    platform : str or None
        OpenMM platform (default CPU).
    circular, ring, delta_lk
        Closed chains from a sequence (periodic helix; planar ring with linking-number change).
    duplex : int or None
        Duplex of a structure file, 1-based (default the longest).
    intrinsic : {"sequence", "structure"}
        Intrinsic shape of a structure's model: the force field's for its sequence, or the
        structure's own step parameters (stiffness still from ``forcefield``).
    start : {"intrinsic", "equilibrium", "minimized"}
        Initial pose: the source's, an exact equilibrium sample of the free chain at ``temperature``
        (:func:`dnarod.physics.thermal.equilibrium_sample`), or the static minimum of the elastic energy under
        the loads (:func:`dnarod.physics.statics.solve_static`; non-bonded terms are not included).
    frame_interval_ps : float
        Time between trajectory frames (and energy rows), ps; rounded to whole steps.
    checkpoint_interval_ps : float or None
        Simulated time between checkpoints, ps (0: only at the end); None (default): checkpoints by wall
        time, every ``checkpoint_wall_s``. A checkpoint is always written at the end and on Ctrl-C.
    checkpoint_wall_s : float
        Wall-clock seconds between checkpoints when ``checkpoint_interval_ps`` is None (0: only at the end);
        default :data:`dnarod.run.loop.CHECKPOINT_WALL_S`. Not part of the run's fingerprint: a resumed run
        may change it.
    velocities : bool
        Also store velocities in the trajectory (doubles its size; checkpoints always keep them).
    export : bool
        Also write ``trajectory.pdb`` + ``trajectory.dcd`` (and ``.xtc`` with ``xtc``).
    xtc : bool
        With ``export``, also write ``trajectory.xtc`` (default; mdtraj reads frame times from XTC,
        not from DCD).
    elastic : {"auto", "plugin", "fast", "portable"}
        OpenMM elastic path.
    threads : int or None
        OpenMM CPU threads.
    """

    source: object = None
    forcefield: str = "dna-default"
    engine: str = "openmm"
    time_ns: float = 1.0
    temperature: float = 300.0
    friction: float = 1.0
    dt: float | None = None
    seed: int | None = None
    loads: tuple[Any, ...] = ()
    salt: float = 0.15
    excluded_volume: bool = True
    electrostatics: bool = True
    charge: object = None
    cutoff_debye: float | None = None
    platform: str | None = None
    circular: bool = False
    ring: bool = False
    delta_lk: int = 0
    duplex: int | None = None
    intrinsic: str = "sequence"
    start: str = "intrinsic"
    frame_interval_ps: float = 1.0
    checkpoint_interval_ps: float | None = None
    checkpoint_wall_s: float = CHECKPOINT_WALL_S
    velocities: bool = False
    export: bool = True
    xtc: bool = True
    elastic: str = "auto"
    threads: int | None = None
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    # ------------------------------------------------------------------------------------
    @property
    def ensemble(self) -> str:
        """``"langevin"`` (friction > 0) or ``"nve"`` (friction 0)."""
        return "langevin" if self.friction > 0 else "nve"

    @property
    def nonbonded(self) -> bool:
        """Whether any non-bonded term (excluded volume, electrostatics) is on."""
        return bool(self.excluded_volume or self.electrostatics)

    def replace(self, **kw: Any) -> RunSpec:
        """A copy with the given fields changed (``dataclasses.replace``)."""
        return replace(self, **kw)

    def check(self) -> RunSpec:
        """Refuse absurd values with one line naming the option (:class:`ParameterError`); returns self.

        The checks run in groups, in this order (the first bad value is the one named): choices, quantities,
        non-bonded options, engine options, counts, names, types.
        """
        self._check_choices()
        self._check_quantities()
        self._check_nonbonded_options()
        self._check_engine_options()
        self._check_counts()
        self._check_names()
        self._check_types()
        return self

    def _check_choices(self) -> None:
        if self.source is None:
            raise ParameterError("no source: give a structure, model, sequence, sequence file or node count")
        if self.engine not in ENGINES:
            raise ParameterError(f"--engine {self.engine!r}: choose one of {', '.join(ENGINES)}")
        if self.start not in STARTS:
            raise ParameterError(f"start {self.start!r}: choose one of {', '.join(STARTS)}")

    def _check_quantities(self) -> None:
        _finite("time_ns", self.time_ns, lambda x: x > 0, "a positive simulated time in ns", "--time")
        _finite("temperature", self.temperature, lambda x: 0 <= x <= MAX_TEMPERATURE,
                f"from 0 to {MAX_TEMPERATURE:g} K (the model's solvent is liquid water)", "--temperature")
        _finite("friction", self.friction, lambda x: x >= 0,
                ">= 0 1/ps (0 runs NVE; a negative friction would pump energy in)")
        if self.dt is not None:
            _finite("dt", self.dt, lambda x: x > 0, "a positive time step in ps")
        _finite("frame_interval_ps", self.frame_interval_ps, lambda x: x > 0, "a positive time in ps",
                "--frame-interval")
        if self.checkpoint_interval_ps is not None:
            _finite("checkpoint_interval_ps", self.checkpoint_interval_ps, lambda x: x >= 0,
                    ">= 0 ps (0: only at the end)", "--checkpoint-interval")
        _finite("checkpoint_wall_s", self.checkpoint_wall_s, lambda x: x >= 0,
                ">= 0 s of wall time (0: only at the end)", "--checkpoint-wall")
        _finite("salt", self.salt, lambda x: 0 < x <= MAX_SALT,
                f"a salt concentration in mol/L above 0 and at most {MAX_SALT:g} (Debye-Hueckel screening is "
                f"meaningless beyond)")

    def _check_nonbonded_options(self) -> None:
        if self.charge is not None or self.cutoff_debye is not None:
            given = "--charge" if self.charge is not None else "--cutoff-debye"
            if self.engine == "lax":
                raise ParameterError(f"{given} sets the Debye-Hueckel electrostatics; the lax engine has none (drop "
                                     f"{given} or use --engine openmm)")
            if not self.electrostatics:
                raise ParameterError(f"{given} sets the Debye-Hueckel electrostatics, which are off; drop it or turn "
                                     f"electrostatics on")
            if self.cutoff_debye is not None:
                _finite("cutoff_debye", self.cutoff_debye, lambda x: x > 0, "a positive number of Debye lengths")
            self.nonbonded_settings(check=True)

    def _check_engine_options(self) -> None:
        if self.threads is not None and self.platform not in (None, "CPU"):
            raise ParameterError(f"--threads applies to OpenMM's CPU platform, not --platform {self.platform}; drop "
                                 f"one of them")
        if self.engine == "lax":
            if self.nonbonded:
                raise ParameterError("the lax engine has no excluded volume or electrostatics: pass "
                                     "--no-excluded-volume --no-electrostatics (or use --engine openmm)")
            if self.platform not in (None, "CPU"):
                raise ParameterError(f"--platform {self.platform}: the lax engine runs on the CPU (numba)")
            # options of the OpenMM engine that the lax engine would silently ignore
            if self.threads is not None:
                raise ParameterError(f"--threads {self.threads}: sets OpenMM's CPU threads; the lax engine ignores it "
                                     f"(drop --threads or use --engine openmm)")
            if self.elastic != "auto":
                raise ParameterError(f"--elastic {self.elastic}: chooses the OpenMM engine's elastic path; the lax "
                                     f"engine ignores it (drop --elastic or use --engine openmm)")
        if self.engine == "mc":
            if self.temperature <= 0:
                raise ParameterError("--engine mc samples the equilibrium at a temperature > 0 K (give -T)")
            if self.platform not in (None, "CPU"):
                raise ParameterError(f"--platform {self.platform}: the mc engine runs on the CPU (numba)")
            if self.threads is not None or self.elastic != "auto":
                raise ParameterError("--threads/--elastic choose OpenMM's paths; the mc engine ignores them (drop them "
                                     "or use --engine openmm)")
            if self.dt is not None and float(self.dt) != 1.0:
                raise ParameterError(f"--dt {self.dt:g}: the mc engine has no time step (one sweep counts as 1 ps)")
            if self.velocities:
                raise ParameterError("--velocities: the mc engine has no velocities (drop --velocities or use an MD "
                                     "engine)")

    def _check_counts(self) -> None:
        if self.duplex is not None:
            _integer("--duplex", self.duplex, lambda k: k >= 1, "from 1 (duplexes are numbered from 1)")
        if self.intrinsic not in ("sequence", "structure"):
            raise ParameterError(f"--intrinsic {self.intrinsic!r}: choose 'sequence' or 'structure'")
        if self.threads is not None:
            most = 4 * (os.cpu_count() or 1)
            _integer("--threads", self.threads, lambda k: 1 <= k <= most, f"from 1 to {most} (4 per core here)")
        if self.seed is not None:
            _integer("--seed", self.seed, lambda k: 0 <= k < 2**31, "in [0, 2^31)")
        _integer("--delta-lk", self.delta_lk, lambda k: True, "(the linking number of a closed ring is an integer)")

    def _check_names(self) -> None:
        if not isinstance(self.forcefield, (str, Path)):
            raise ParameterError(f"--forcefield {self.forcefield!r}: give a bundled force-field name or a .toml path")
        if self.elastic not in ELASTIC:
            raise ParameterError(f"--elastic {self.elastic!r}: choose one of {', '.join(ELASTIC)}")
        if self.platform is not None and not isinstance(self.platform, str):
            raise ParameterError(f"--platform {self.platform!r}: give an OpenMM platform name (CPU, Reference, "
                                 f"CUDA, HIP, OpenCL)")
        if self.engine == "openmm" and self.platform is not None:
            from dnarod.engines.openmm.platforms import platform_names  # loads OpenMM

            names = platform_names()
            if self.platform not in names:
                near = [n for n in names if n.lower() == self.platform.lower()]
                hint = f"; did you mean {near[0]}?" if near else ""
                raise ParameterError(f"--platform {self.platform}: OpenMM platform not installed here (available: "
                                     f"{', '.join(names)}){hint}")

    def _check_types(self) -> None:
        for name in ("circular", "ring", "velocities", "export", "xtc", "excluded_volume", "electrostatics"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ParameterError(f"{name} {getattr(self, name)!r}: must be True or False")
        if not isinstance(self.loads, (tuple, list)):
            raise ParameterError(f"loads {self.loads!r}: give a tuple of dnarod.physics.loads objects")
        for ld in self.loads:
            if not is_dataclass(ld) or isinstance(ld, type):
                raise ParameterError(f"loads: {ld!r} is not a dnarod.physics.loads object (PullingForce, Torque, "
                                     f"Clamp, RotationClamp, Trap, ...)")
        if not isinstance(self.extra, dict):
            raise ParameterError(f"extra {self.extra!r}: must be a dict")

    def nonbonded_settings(self, check: bool = False) -> NonbondedSettings | bool:
        """The :class:`dnarod.physics.nonbonded.NonbondedSettings` of the run, or ``False`` when both terms are off
        (``check``: refuse a bad charge or cutoff with one line, :class:`ParameterError`)."""
        if not self.nonbonded:
            return False

        extra: dict[str, Any] = {k: v for k, v in (("charge", self.charge), ("cutoff_debye", self.cutoff_debye))
                                 if v is not None}
        if check:
            return member_nonbonded(dict(excluded_volume=self.excluded_volume, electrostatics=self.electrostatics,
                                         salt_M=self.salt, temperature_K=scales_temperature(self.temperature), **extra))
        return NonbondedSettings(excluded_volume=self.excluded_volume, electrostatics=self.electrostatics,
                                 salt=self.salt, **extra)

    def to_json(self) -> dict[str, Any]:
        """JSON-safe dict of the spec (loads as ``{"type": ..., fields...}``; a model source as its name)."""
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("loads", "extra", "source")}
        d["source"] = _source_text(self.source)
        d["loads"] = [load_json(x) for x in self.loads]
        d["extra"] = dict(self.extra)
        return jsonable(d)


def _source_text(source: Any) -> str:
    if isinstance(source, RodModel):
        return f"<RodModel {source.n_nodes} nodes>"
    return str(source)


def load_json(load: Any) -> dict[str, Any]:
    """A load dataclass as a JSON-safe dict ``{"type": class name, field: value}``."""
    try:
        d = asdict(load)
    except TypeError:
        d = dict(vars(load))
    return jsonable({"type": type(load).__name__, **d})


def fingerprint(spec: RunSpec, model: RodModel, dt: float, seed: int) -> dict[str, Any]:
    """Everything a resumed run must share with the run it continues (name -> JSON value).

    Model (sequence, parameters, masses, starting pose via :func:`model_fingerprint`), engine,
    ensemble, temperature, friction, time step, loads, seed, non-bonded settings, start and
    frame interval. The total time may grow on resume, except when a load turns with the run
    (``RotationClamp(turns=...)``), whose rate depends on it.
    """
    loads = [load_json(x) for x in spec.loads]
    fp = {
        "sequence": model.sequence or None, "n_nodes": int(model.n_nodes), "model": model_fingerprint(model),
        "engine": spec.engine, "ensemble": spec.ensemble,
        "temperature_K": float(spec.temperature), "friction_per_ps": float(spec.friction),
        "dt_ps": float(dt), "loads": loads, "seed": int(seed),
        "nonbonded": _nonbonded_fingerprint(spec, model),
        "frame_interval_ps": float(spec.frame_interval_ps), "velocities": bool(spec.velocities),
    }
    if any(float(getattr(x, "turns", 0.0) or 0.0) != 0.0 for x in spec.loads):
        fp["time_ns"] = float(spec.time_ns)
    return fp


#: Entries of a run's non-bonded fingerprint that say which charge and cutoff it ran with (recorded since they
#: became choosable; a run folder without them ran with the default of its day, which changed on 2026-12-02).
CHARGE_ENTRIES = ("charge_model", "charge_e_per_node", "cutoff_debye", "cutoff_nm")


def _nonbonded_fingerprint(spec: RunSpec, model: RodModel) -> dict[str, Any]:
    """The non-bonded entries of a fingerprint: on/off and salt, and with electrostatics the charge model, its
    charge per node (e), the cutoff in Debye lengths and nm (resolved at the run's temperature, 300 K at T = 0)."""
    fp = dict(excluded_volume=bool(spec.excluded_volume), electrostatics=bool(spec.electrostatics),
              salt_mol_L=float(spec.salt) if spec.nonbonded else None)
    if spec.engine == "openmm" and spec.electrostatics:
        rec = nonbonded_record(spec.nonbonded_settings(), model.ds, scales_temperature(spec.temperature))
        fp.update({k: rec[k] for k in CHARGE_ENTRIES})
    return fp


def compare_fingerprints(old: dict[str, Any], new: dict[str, Any], where: str | Path) -> None:
    """Raise :class:`ParameterError` naming the first entry that differs (``where``: the run.json path)."""
    names = {"model": "model (sequence, parameters, masses or starting pose)", "dt_ps": "time step (--dt)",
             "temperature_K": "temperature (-T)", "friction_per_ps": "friction (--friction)",
             "seed": "seed (--seed)", "loads": "loads", "engine": "engine (--engine)",
             "frame_interval_ps": "frame interval (--frame-interval)", "velocities": "velocities (--velocities)",
             "nonbonded": "non-bonded settings (--salt/--excluded-volume/--electrostatics/--charge/--cutoff-debye)",
             "sequence": "sequence", "n_nodes": "number of nodes", "ensemble": "ensemble (--friction 0 = NVE)",
             "time_ns": "total time (--time), over which the rotation clamp spreads its --turns"}
    nb_old, nb_new = old.get("nonbonded"), new.get("nonbonded")
    if (isinstance(nb_old, dict) and isinstance(nb_new, dict) and nb_old.get("electrostatics")
            and "charge_model" not in nb_old and "charge_model" in nb_new):
        raise ParameterError(f"cannot resume: {where} does not record the non-bonded charge it ran with (written "
                             f"before runs recorded it; the default was Manning's 0.48 e/bp with a 5-Debye-length "
                             f"cutoff until 2026-12-02, the calibrated charge (3.01 e/bp at 0.15 M) with 12 since), "
                             f"so continuing could mix two models; start a new run (-o NEWDIR, or --overwrite)")
    for key in list(old) + [k for k in new if k not in old]:
        a, b = old.get(key), new.get(key)
        if not _same(a, b):
            what = names.get(key, key)
            show = lambda v: (str(v)[:60] + "...") if len(str(v)) > 60 else str(v)  # noqa: E731
            change = f"was {show(a)}, now {show(b)}"
            if isinstance(a, dict) and isinstance(b, dict):  # name the entry that differs (a charge model, a salt)
                sub = next(k for k in list(a) + [k for k in b if k not in a] if not _same(a.get(k), b.get(k)))
                change = f"{sub} was {show(a.get(sub))}, now {show(b.get(sub))}"
            raise ParameterError(f"cannot resume: the {what} changed since the run in {where} "
                                 f"({change}); resume with the same settings or start a new "
                                 f"run (-o NEWDIR, or --overwrite)")


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        try:
            return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=0.0)
        except (TypeError, ValueError):
            return False
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b
