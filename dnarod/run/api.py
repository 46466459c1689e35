"""``run(spec, outdir)``: one simulation run of either engine, with resume, into a run folder.

A run folder holds ``run.json`` (the spec and its fingerprint, written atomically at the start),
``trajectory.dtraj``, ``energies.csv``, ``checkpoint.npz`` (always written at the end),
``final_model.npz`` and, with ``export``, ``trajectory.pdb`` + ``trajectory.dcd`` (and
``trajectory.xtc`` unless ``xtc=False``), re-exported from the ``.dtraj`` at the end of every run.

Nothing is lost or silently changed: a new run refuses a folder holding a run unless
``overwrite`` (which removes only this layer's own files) and any other non-empty folder (``-o /``, a
project folder; :func:`run_folder_markers`); ``resume`` refuses any change of what defines the run
(:func:`dnarod.run.spec.fingerprint`), reads the checkpoint before touching any file, and a time already
reached changes nothing. While a run writes, its folder is locked (:func:`dnarod.core.io.folder_lock`,
``.dnarod.lock``, removed when the run ends).
"""
from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dnarod.core.errors import ParameterError
from dnarod.core.io import check_dir_path, check_output_folder, folder_lock, jsonable, write_text_atomic
from dnarod.run.spec import RunSpec, compare_fingerprints, fingerprint
from dnarod.core.io import read_checkpoint
from dnarod.physics.modes import DEFAULT_OMEGA_DT, MAX_OMEGA_DT

#: Files a run folder may hold (``overwrite`` removes exactly these).
RUN_FILES = {"run_json": "run.json", "trajectory": "trajectory.dtraj", "energies": "energies.csv",
             "checkpoint": "checkpoint.npz", "final_model": "final_model.npz", "pdb": "trajectory.pdb",
             "dcd": "trajectory.dcd", "xtc": "trajectory.xtc"}
CHECKPOINT_FORMATS = {"openmm": "dnarod-openmm-checkpoint", "lax": "dnarod-lax-checkpoint",
                      "mc": "dnarod-mc-checkpoint"}
#: Mean elastic energy per step of the start pose (kT) above which a run warns / is refused.
WARN_KT_PER_STEP = 20.0
REFUSE_KT_PER_STEP = 100.0


@dataclass
class RunResult:
    """Outcome of :func:`run`.

    Attributes
    ----------
    outdir : Path
    files : dict
        Name -> Path of every file of the run folder that exists after the run.
    summary : dict
        steps, simulated_ps, dt_ps, omega_max, wall_s, cpu_s, ns_per_day, mean_temperature_K, message, ...
    resumed_from : int or None
        Checkpoint step the run continued from.
    """

    outdir: Path
    files: dict = field(default_factory=dict)
    summary: dict = field(default_factory=dict)
    resumed_from: int | None = None


# ----------------------------------------------------------------------------------------------
# building blocks (public: the CLI and the ensemble layer use them)
# ----------------------------------------------------------------------------------------------
def source_model(spec):
    """The model named by ``spec.source`` (structure, model file, sequence, sequence file, node count)."""
    from dnarod.structure.inputs import load_model

    return load_model(spec.source, spec.forcefield, spec.circular, spec.ring, spec.delta_lk, spec.duplex,
                      spec.intrinsic)


def start_model(spec, model, seed):
    """The start pose: the source's, an exact equilibrium sample, or the static minimum under the loads."""
    if spec.start == "intrinsic":
        return model
    if spec.start == "equilibrium":
        try:
            from dnarod.physics.thermal import equilibrium_sample
        except ImportError:
            raise ParameterError("start='equilibrium' needs dnarod.physics.thermal.equilibrium_sample, not in this "
                                 "version") from None
        return equilibrium_sample(model, spec.temperature if spec.temperature > 0 else 300.0, seed=seed,
                                  align=_pull_direction(spec.loads, model.n_nodes))
    try:
        from dnarod.physics.statics import solve_static
    except ImportError:
        if spec.engine != "openmm":
            raise ParameterError("--minimize needs dnarod.physics.statics.solve_static (not in this version) for the lax "
                                 "engine") from None
        return None  # the OpenMM engine minimises its context
    solved, _ = solve_static(model, tuple(spec.loads))
    return solved


def _pull_direction(loads, n_nodes):
    """Net pulling force on the last node (kJ/mol/nm, (3,)) or None: an equilibrium start of a pulled
    chain is turned so that its end-to-end vector points along it (else a long chain may start
    pointing away from the force)."""
    from dnarod.physics.loads import PullingForce

    f = sum((np.asarray(ld.force, float) for ld in loads
             if isinstance(ld, PullingForce) and int(ld.node) % n_nodes == n_nodes - 1), np.zeros(3))
    return f if np.linalg.norm(f) > 0 else None


def default_omega_max(model, loads=()):
    """Fastest normal-mode frequency of a pose under its loads, rad/ps (:func:`dnarod.physics.modes.omega_max`)."""
    from dnarod.physics.modes import omega_max

    return float(omega_max(model, loads=tuple(loads)))


def choose_dt(spec, model, omega):
    """Time step, ps: ``spec.dt`` (checked against the stability limit) or ``0.4 / omega_max``."""
    limit = MAX_OMEGA_DT / omega
    if spec.dt is None:
        return DEFAULT_OMEGA_DT / omega
    if spec.dt > limit:
        raise ParameterError(f"--dt {spec.dt:g} ps is above the stability limit {limit:.4g} ps of this model "
                             f"(fastest mode omega_max = {omega:.4g} rad/ps, limit 1.8/omega_max); use dt <= "
                             f"{DEFAULT_OMEGA_DT / omega:.3g} ps (the default)")
    return float(spec.dt)


def check_start_pose(model, temperature):
    """Refuse (or warn about) a start pose the rod model cannot run: steps near the Cayley limit or
    storing far more elastic energy than equipartition (a tiny ring), which heats the run up."""
    from dnarod.core.energy import loads as elastic_loads
    from dnarod.core.rotations import MAX_CAYLEY_ANGLE
    from dnarod.core.units import kT

    if model.n_steps == 0:
        raise ParameterError("the model has a single node: a chain needs at least 2")
    Om, _ = model.strains()
    ang = 2 * np.arctan(np.linalg.norm(Om, axis=1) * model.ds / 2)
    k = int(np.argmax(ang))
    kind = "ring" if model.closure is not None else "chain"
    if ang[k] > 0.8 * MAX_CAYLEY_ANGLE:
        hint = ("use a longer ring" if kind == "ring" else
                "a longer chain does not help: the step is a kink or not a stacked step (a structure's steps are "
                "numbered the same way by 'dnarod steps'); fix the pose or build the model from another duplex")
        raise ParameterError(f"step {k + 1} of this {model.n_nodes}-node {kind} (steps numbered from 1) rotates by "
                             f"{np.degrees(ang[k]):.0f} deg, near the Cayley-chart limit "
                             f"({np.degrees(MAX_CAYLEY_ANGLE):.0f} deg) of the rod model; {hint}")
    E = elastic_loads(model.positions, model.frames, model.params, model.ds, model.closure)[0]
    per = E / model.n_steps / kT(temperature if temperature > 0 else 300.0)
    if per > WARN_KT_PER_STEP:
        n_ok = int(math.ceil(model.n_nodes * math.sqrt(per / WARN_KT_PER_STEP)))
        msg = (f"the start pose of this {model.n_nodes}-node {kind} stores {per:.0f} kT of elastic energy per step "
               f"(equipartition gives 3 kT): the strains are far outside the rod model's range and the run heats up "
               f"(kinetic blow-up); use at least ~{n_ok} nodes")
        if per > REFUSE_KT_PER_STEP:
            raise ParameterError(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=3)


def preflight(spec, model=None):
    """The checks :func:`run` makes before it writes anything, without running: the settings
    (:meth:`RunSpec.check`), the source, the start pose, an equilibrium start on a closed model, the time
    step against the stability limit and the number of steps. An ensemble calls it for every distinct
    member on the client, so a member refused by the run layer is refused before any member runs.

    The time step is checked on the source pose under the loads (:func:`run` uses the start pose, which for
    ``start="minimized"`` or ``"equilibrium"`` differs a little): a ``dt`` within 5 % of the limit is left
    to the run.

    Returns
    -------
    RodModel
        The source model (for a cache).

    Raises
    ------
    ParameterError
        The first refusal, with the message :func:`run` would give.
    """
    spec.check()
    if model is None:
        model = source_model(spec)
    check_start_pose(model, spec.temperature)
    if spec.start == "equilibrium" and model.closure is not None:
        raise ParameterError("start 'equilibrium' samples the free open chain exactly; this model is circular "
                             "(a ring or a periodic chain): use start 'intrinsic' or 'minimized'")
    if spec.engine == "mc":  # no time step: one sweep counts as 1 ps (dnarod.engines.mc)
        intervals(spec, 1.0)
        return model
    omega = default_omega_max(model, spec.loads)
    check_load_stiffness(spec, model, omega)
    if spec.dt is not None and spec.dt > 1.05 * MAX_OMEGA_DT / omega:
        choose_dt(spec, model, omega)              # raises, naming the limit
    intervals(spec, spec.dt if spec.dt is not None else _default_dt(omega))
    return model


def _default_dt(omega):
    return DEFAULT_OMEGA_DT / omega


def check_load_stiffness(spec, model, omega=None):
    """:func:`dnarod.physics.loads.check_load_stiffness` of ``spec.loads`` on ``model`` (``omega``: the fastest mode with
    the loads, rad/ps, if known), naming the ``simulate`` options."""
    from dnarod.physics.modes import check_load_stiffness as check

    check(model, spec.loads, omega=omega)


def make_engine(spec, model, dt, seed, omega):
    """The engine of ``spec.engine`` for ``model`` (start pose), time step ``dt`` ps and ``seed``."""
    duration_ps = spec.time_ns * 1000.0
    if spec.engine == "mc":
        from dnarod.engines.mc import MCEngine

        return MCEngine(model, spec.temperature, spec.loads, nonbonded=spec.nonbonded_settings(), seed=seed,
                        duration_ps=duration_ps)
    if spec.engine == "lax":
        from dnarod.engines.lax.engine import LaxEngine

        return LaxEngine(model, dt, spec.temperature, spec.friction, seed, spec.loads, duration_ps, omega)
    from dnarod.engines.openmm.simulation import RodSimulation

    nb = spec.nonbonded_settings()
    return RodSimulation(model, integrator="langevin" if spec.friction > 0 else "verlet",
                         temperature=spec.temperature, dt=dt, friction=spec.friction,
                         platform=spec.platform, elastic=spec.elastic, nonbonded=nb, loads=spec.loads,
                         seed=seed, threads=spec.threads, omega_max=omega)


#: Most steps a run accepts: 10^12 steps take years at any speed this code reaches; more is a typo
#: (a --time in ps, a --dt in fs) that would otherwise run "forever" without a word.
MAX_STEPS = 10**12


def intervals(spec, dt):
    """(n_steps, frame interval, checkpoint interval) in steps."""
    steps = spec.time_ns * 1000.0 / dt
    if not steps <= MAX_STEPS:
        raise ParameterError(f"--time {spec.time_ns:g} ns at --dt {dt:g} ps is {steps:.3g} steps, more than "
                             f"{MAX_STEPS:.0e}; give a shorter --time (ns) or a larger --dt (ps)")
    n_steps = max(1, int(round(steps)))
    fi = max(1, int(round(spec.frame_interval_ps / dt)))
    ci = 10 * fi if spec.checkpoint_interval_ps is None else int(round(spec.checkpoint_interval_ps / dt))
    return n_steps, fi, ci


def run_folder_markers():
    """Names that mark a folder as a run's (any of them): the run files, and the record of an ensemble member
    (:data:`dnarod.core.io.RESULT`, ``MEMBER``, ``LOG``), whose folder is a run folder. A new run refuses any other
    non-empty folder (:func:`dnarod.core.io.check_output_folder`)."""
    from dnarod.core.io import LOG, MEMBER, RESULT

    return (*RUN_FILES.values(), MEMBER, LOG, RESULT)


def run_files(outdir):
    """Name -> Path of the run-folder files that exist."""
    outdir = Path(outdir)
    return {k: outdir / v for k, v in RUN_FILES.items() if (outdir / v).exists()}


def _observables(spec, model):
    """Per-frame observables of the loads for the energies CSV (:mod:`dnarod.physics.observables`), or None."""
    try:
        from dnarod.physics.observables import csv_observables
    except ImportError:
        return None
    return csv_observables(model, tuple(spec.loads), duration_ps=spec.time_ns * 1000.0)


def _run_id(fp):
    import hashlib

    return hashlib.sha256(json.dumps(jsonable(fp), sort_keys=True).encode()).hexdigest()[:20]


# ----------------------------------------------------------------------------------------------
def run(spec, outdir, resume=False, overwrite=False, progress=True):
    """Run ``spec`` into the folder ``outdir`` (created), or continue it with ``resume``.

    Parameters
    ----------
    spec : RunSpec
    outdir : str or Path
    resume : bool
        Continue from ``outdir/checkpoint.npz`` up to ``spec.time_ns``. Refused, with one line naming
        it, if anything that defines the run differs from ``outdir/run.json``. If the checkpoint is
        already at or beyond the requested time, nothing changes and the result says so.
    overwrite : bool
        Start a new run in a folder that already holds one (its run files are removed first).
    progress : bool
        tqdm progress bar on stderr.

    Returns
    -------
    RunResult

    Raises
    ------
    ParameterError
        Bad settings, a folder holding a run (without ``overwrite``/``resume``) or holding anything but a run
        (:func:`run_folder_markers`), a refused resume,
        a corrupt or foreign checkpoint (nothing written is changed).
    SimulationError
        A blow-up, naming the step, node and term (everything written before stays on disk).
    """
    if not isinstance(spec, RunSpec):
        raise ParameterError(f"spec must be a dnarod.run.RunSpec, got {type(spec).__name__}")
    spec.check()
    if resume and overwrite:
        raise ParameterError("choose --resume (continue the run) or --overwrite (replace it), not both")
    if not isinstance(outdir, (str, Path)) or not str(outdir).strip():
        raise ParameterError(f"output folder {outdir!r}: give a folder path (-o DIR)")
    outdir = Path(outdir)
    check_dir_path(outdir, what="output folder")
    paths = {k: outdir / v for k, v in RUN_FILES.items()}
    if resume:
        return _resume(spec, outdir, paths, progress)
    check_output_folder(outdir, run_folder_markers(), "run")
    present = [p for p in paths.values() if p.exists()]
    if present and not overwrite:
        raise ParameterError(f"{outdir} already holds a run ({present[0].name}); continue it with --resume, "
                             f"replace it with --overwrite, or choose another folder with -o")
    model = source_model(spec)
    check_start_pose(model, spec.temperature)
    seed = int(np.random.SeedSequence().entropy % 2**31) if spec.seed is None else int(spec.seed)
    start = start_model(spec, model, seed)
    if spec.engine == "mc":  # no time step: one sweep counts as 1 ps (dnarod.engines.mc)
        omega, dt = None, 1.0
    else:
        omega = default_omega_max(start if start is not None else model, spec.loads)
        check_load_stiffness(spec, model)
        dt = choose_dt(spec, model, omega)
    intervals(spec, dt)  # refuses an absurd number of steps before anything is written
    fp = fingerprint(spec, model, dt, seed)
    run_id = _run_id(fp)
    engine = make_engine(spec, start if start is not None else model, dt, seed, omega)
    if start is None:  # OpenMM energy minimisation of the context (no static solver available)
        engine.minimize()
    with folder_lock(outdir):  # a second process writing into outdir is refused, not interleaved
        present_now = [p for p in paths.values() if p.exists()]
        if not overwrite and present_now:  # another process started a run here while this one was set up
            raise ParameterError(f"{outdir} already holds a run ({present_now[0].name}); continue it with --resume, "
                                 f"replace it with --overwrite, or choose another folder with -o")
        for p in present_now:  # overwrite: only now, when the new run is known to start
            p.unlink()
        meta = dict(format="dnarod-run", version=1, run_id=run_id, spec=spec.to_json(), fingerprint=fp, seed=seed,
                    dt_ps=dt, omega_max=omega, segments=[])
        write_text_atomic(paths["run_json"], json.dumps(jsonable(meta), indent=1) + "\n")
        return _execute(spec, outdir, paths, engine, model, meta, resume_step=None, progress=progress)


def _resume(spec, outdir, paths, progress):
    if not paths["run_json"].exists():
        raise ParameterError(f"cannot resume: {paths['run_json']} does not exist (no run was started in {outdir}); "
                             f"drop --resume to start one")
    try:
        run_json_text = paths["run_json"].read_text()
        meta = json.loads(run_json_text)
        old_fp, seed, dt = meta["fingerprint"], int(meta["seed"]), float(meta["dt_ps"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ParameterError(f"{paths['run_json']}: not a readable dnarod run file ({type(exc).__name__}); "
                             f"start a new run with --overwrite") from None
    model = source_model(spec)
    spec_dt = dt if spec.dt is None else float(spec.dt)
    spec_seed = seed if spec.seed is None else int(spec.seed)
    compare_fingerprints(old_fp, fingerprint(spec, model, spec_dt, spec_seed), paths["run_json"])
    # read the checkpoint before anything is touched: a corrupt or foreign file changes nothing
    ck_meta, _ = read_checkpoint(paths["checkpoint"], CHECKPOINT_FORMATS[spec.engine], ())
    if (ck_meta.get("extra") or {}).get("run") != meta.get("run_id"):
        raise ParameterError(f"{paths['checkpoint']}: checkpoint of another run (not the one in "
                             f"{paths['run_json']}); start a new run with --overwrite")
    step = int(ck_meta["step"])
    n_steps, fi, ci = intervals(spec, dt)
    if step >= n_steps:
        if not paths["final_model"].exists():
            # killed between the run's last checkpoint and its final model: the end state is the checkpoint's
            engine = make_engine(spec, model, dt, seed, meta.get("omega_max"))
            with folder_lock(outdir):
                engine.load_checkpoint(paths["checkpoint"])
                engine.current_model().save(paths["final_model"])
        files = run_files(outdir)
        msg = (f"the run in {outdir} is already at step {step} ({step * dt / 1000:.6g} ns) >= the requested "
               f"{spec.time_ns:g} ns; nothing to do (nothing changed)")
        return RunResult(outdir, files, dict(steps=step, steps_this_run=0, simulated_ps=step * dt, dt_ps=dt,
                                             omega_max=meta.get("omega_max"), already_done=True, message=msg,
                                             seed=seed, engine=spec.engine), resumed_from=step)
    start = start_model(spec, model, seed)
    engine = make_engine(spec, start if start is not None else model, dt, seed, meta.get("omega_max"))
    with folder_lock(outdir):  # not while another process still runs (or resumes) in outdir
        if paths["run_json"].read_text() != run_json_text:
            raise ParameterError(f"cannot resume: {paths['run_json']} changed while this resume was set up (another "
                                 f"process wrote the run); run the command again")
        engine.load_checkpoint(paths["checkpoint"])
        meta["spec"] = spec.to_json()
        write_text_atomic(paths["run_json"], json.dumps(jsonable(meta), indent=1) + "\n")
        return _execute(spec, outdir, paths, engine, model, meta, resume_step=engine.step, progress=progress)


def _execute(spec, outdir, paths, engine, model, meta, resume_step, progress):
    from dnarod.run.loop import simulate_engine

    dt = engine.dt
    n_steps, fi, ci = intervals(spec, dt)
    if fi > n_steps:
        warnings.warn(f"--frame-interval {spec.frame_interval_ps:g} ps is longer than the run ({n_steps * dt:.4g} ps): "
                      f"the trajectory holds only the start frame (the end state is in final_model.npz)",
                      RuntimeWarning, stacklevel=3)
    traj_meta = dict(engine=spec.engine, dt_ps=dt, temperature_K=spec.temperature, friction_per_ps=spec.friction,
                     ensemble=spec.ensemble, seed=meta["seed"], sequence=(model.sequence or "")[:2000] or None,
                     circular=model.closure is not None, frame_interval_steps=fi,
                     inertia_convention="J = m l^2 (1/2, 1/2, 1) about d1,d2,d3; omega body frame")
    if spec.engine == "openmm":
        traj_meta.update(platform=engine.platform_name, elastic=engine.rs.elastic)
    # the checkpoint was already loaded (resume) or the folder emptied (new run)
    out = simulate_engine(engine, n_steps, outdir, fi, fi, ci, resume=resume_step is not None, overwrite=True,
                          velocities=spec.velocities, metadata=traj_meta, observables=_observables(spec, engine.model),
                          progress=progress, duration_ps=spec.time_ns * 1000.0,
                          checkpoint_extra=dict(run=meta["run_id"]), restored=True)
    if spec.export:
        from dnarod.structure.export import export_trajectory

        export_trajectory(paths["trajectory"], paths["pdb"], paths["dcd"], sequence=model.sequence,
                          xtc_path=paths["xtc"] if spec.xtc else None)
    meta["segments"].append(dict(from_step=resume_step or 0, to_step=out["steps"], wall_s=out["wall_s"],
                                 cpu_s=out["cpu_s"]))
    write_text_atomic(paths["run_json"], json.dumps(jsonable(meta), indent=1) + "\n")
    done = out["steps_this_run"]
    wall = out["wall_s"]
    temps = out["temperatures"]
    summary = dict(engine=spec.engine, n_nodes=model.n_nodes, steps=out["steps"], steps_this_run=done,
                   simulated_ps=out["steps"] * dt, dt_ps=dt, omega_max=getattr(engine, "omega_max", None),
                   frame_interval_steps=fi, wall_s=wall, cpu_s=out["cpu_s"],
                   ns_per_day=done * dt * 1e-3 / wall * 86400 if wall > 0 else float("nan"),
                   mean_temperature_K=float(np.mean(temps)) if temps else float("nan"), seed=meta["seed"],
                   already_done=False, message=None, selection=(model.metadata or {}).get("selection"))
    if spec.engine == "mc":
        summary.update(acceptance=engine.acceptance(), amplitudes=engine.amplitudes())
    if spec.engine == "openmm":
        summary.update(elastic_path=engine.rs.elastic, platform=engine.platform_name,
                       platform_reason=getattr(engine, "platform_reason", None),
                       nonbonded=engine.rs.nonbonded or None, context_s=engine.context_time)
    return RunResult(outdir, run_files(outdir), summary, resumed_from=resume_step)
