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
from typing import Any
import hashlib
import sys

import numpy as np

from dnarod.core.seeds import resolve_seed
from dnarod.core.errors import ParameterError, step_name
from dnarod.core.io import (FULL_DISK_ERRNOS, STAGE_PREFIX, WriteError, check_dir_path, check_free_space,
                            check_output_folder, folder_lock, jsonable, staged_folder, write_failure, write_text_atomic,
                            LOG, MEMBER, RESULT)
from dnarod.run.spec import RunSpec, compare_fingerprints, fingerprint
from dnarod.core.io import read_checkpoint
from dnarod.physics.modes import DEFAULT_OMEGA_DT, MAX_OMEGA_DT, omega_max
from dnarod.physics.modes import check_load_stiffness as _check_load_stiffness
from dnarod.physics.loads import PullingForce
from dnarod.core.energy import loads as elastic_loads
from dnarod.core.rotations import MAX_CAYLEY_ANGLE
from dnarod.core.units import kT
from dnarod.core.trajectory import HEADER_SIZE, bytes_per_node_frame
from dnarod.run.loop import simulate_engine
from dnarod.core.model import RodModel
from dnarod.run.engine import Engine
from dnarod.physics.observables import csv_observables
from dnarod.physics.statics import solve_static
from dnarod.physics.thermal import equilibrium_sample

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
    files: dict[str, Path] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    resumed_from: int | None = None


# ----------------------------------------------------------------------------------------------
# building blocks (public: the CLI and the ensemble layer use them)
# ----------------------------------------------------------------------------------------------
def source_model(spec: RunSpec) -> RodModel:
    """The model named by ``spec.source`` (structure, model file, sequence, sequence file, node count)."""
    from dnarod.structure.inputs import load_model  # loads scipy.spatial: not at the CLI's start-up

    return load_model(spec.source, spec.forcefield, spec.circular, spec.ring, spec.delta_lk, spec.duplex,
                      spec.intrinsic)


def start_model(spec: RunSpec, model: RodModel, seed: int | None) -> RodModel:
    """The start pose: the source's, an exact equilibrium sample, or the static minimum under the loads."""
    if spec.start == "intrinsic":
        return model
    if spec.start == "equilibrium":
        return equilibrium_sample(model, spec.temperature if spec.temperature > 0 else 300.0, seed=seed,
                                  align=_pull_direction(spec.loads, model.n_nodes))
    solved, _ = solve_static(model, tuple(spec.loads))
    return solved


def _pull_direction(loads: Any, n_nodes: int) -> np.ndarray | None:
    """Net pulling force on the last node (kJ/mol/nm, (3,)) or None: an equilibrium start of a pulled
    chain is turned so that its end-to-end vector points along it (else a long chain may start
    pointing away from the force)."""
    f = sum((np.asarray(ld.force, float) for ld in loads
             if isinstance(ld, PullingForce) and int(ld.node) % n_nodes == n_nodes - 1), np.zeros(3))
    return f if np.linalg.norm(f) > 0 else None


def default_omega_max(model: RodModel, loads: Any = ()) -> float:
    """Fastest normal-mode frequency of a pose under its loads, rad/ps (:func:`dnarod.physics.modes.omega_max`)."""
    return float(omega_max(model, loads=tuple(loads)))


def choose_dt(spec: RunSpec, model: RodModel, omega: float) -> float:
    """Time step, ps: ``spec.dt`` (checked against the stability limit) or ``0.4 / omega_max``."""
    limit = MAX_OMEGA_DT / omega
    if spec.dt is None:
        return DEFAULT_OMEGA_DT / omega
    if spec.dt > limit:
        raise ParameterError(f"--dt {spec.dt:g} ps is above the stability limit {limit:.4g} ps of this model "
                             f"(fastest mode omega_max = {omega:.4g} rad/ps, limit 1.8/omega_max); use dt <= "
                             f"{DEFAULT_OMEGA_DT / omega:.3g} ps (the default)")
    return float(spec.dt)


def check_start_pose(model: RodModel, temperature: float) -> None:
    """Refuse (or warn about) a start pose the rod model cannot run: steps near the Cayley limit or
    storing far more elastic energy than equipartition (a tiny ring), which heats the run up."""
    if model.n_steps == 0:
        raise ParameterError("the model has a single node: a chain needs at least 2")
    Om, _ = model.strains()
    ang = 2 * np.arctan(np.linalg.norm(Om, axis=1) * model.ds / 2)
    k = int(np.argmax(ang))
    kind = "ring" if model.closure is not None else "chain"
    if ang[k] > 0.8 * MAX_CAYLEY_ANGLE:
        head = (f"{step_name(k, model.n_nodes)} of this {model.n_nodes}-node {kind} rotates by "
                f"{np.degrees(ang[k]):.0f} deg, near the Cayley-chart limit ({np.degrees(MAX_CAYLEY_ANGLE):.0f} deg) "
                f"of the rod model")
        if np.median(ang) > 0.5 * MAX_CAYLEY_ANGLE:  # every step turns far: the whole chain is too short for its shape
            raise ParameterError(f"{head}: every step turns by {np.degrees(np.median(ang)):.0f} deg or more (a ring "
                                 f"or a supercoil too tight for so few base pairs); use a longer {kind}")
        n_bad = int(np.sum(ang > 0.8 * MAX_CAYLEY_ANGLE))
        raise ParameterError(f"{head}, while its median step turns by {np.degrees(np.median(ang)):.0f} deg: "
                             f"{'a local feature' if n_bad == 1 else f'{n_bad} local features'} of the input the "
                             f"rod model cannot represent (a B-Z junction, a kink, a flipped base pair or a break in "
                             f"the pairing), not cured by a longer {kind}; simulate the sequence (its intrinsic "
                             f"shape) instead, or a duplex or stretch of the structure without it")
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


def preflight(spec: RunSpec, model: RodModel | None = None) -> RodModel:
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
    from dnarod.run.resources import check_memory, node_count_hint  # loads scipy.spatial

    spec.check()
    if model is None:
        check_memory(node_count_hint(spec.source), spec.engine)
        model = source_model(spec)
    check_memory(model.n_nodes, spec.engine)
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


def _default_dt(omega: float) -> float:
    return DEFAULT_OMEGA_DT / omega


def check_load_stiffness(spec: RunSpec, model: RodModel, omega: float | None = None) -> None:
    """:func:`dnarod.physics.modes.check_load_stiffness` of ``spec.loads`` on ``model`` (``omega``: the fastest mode
    with the loads, rad/ps, if known), naming the ``simulate`` options."""
    _check_load_stiffness(model, spec.loads, omega=omega)


def make_engine(spec: RunSpec, model: RodModel, dt: float, seed: int, omega: float | None) -> Engine:
    """The engine of ``spec.engine`` for ``model`` (start pose), time step ``dt`` ps and ``seed``."""
    duration_ps = spec.time_ns * 1000.0
    if spec.engine == "mc":
        from dnarod.engines.mc import MCEngine

        return MCEngine(model, spec.temperature, spec.loads, nonbonded=spec.nonbonded_settings(), seed=seed,
                        duration_ps=duration_ps)
    if spec.engine == "lax":
        from dnarod.engines.lax.engine import LaxEngine  # loads scipy.integrate

        return LaxEngine(model, dt, spec.temperature, spec.friction, seed, spec.loads, duration_ps, omega)
    from dnarod.engines.openmm.simulation import RodSimulation  # loads OpenMM

    nb = spec.nonbonded_settings()
    return RodSimulation.create(model, integrator="langevin" if spec.friction > 0 else "verlet",
                         temperature=spec.temperature, dt=dt, friction=spec.friction,
                         platform=spec.platform, elastic=spec.elastic, nonbonded=nb, loads=spec.loads,
                         seed=seed, threads=spec.threads, omega_max=omega)


#: Most steps a run accepts: 10^12 steps take years at any speed this code reaches; more is a typo
#: (a --time in ps, a --dt in fs) that would otherwise run "forever" without a word.
MAX_STEPS = 10**12


def intervals(spec: RunSpec, dt: float) -> tuple[int, int, int]:
    """(n_steps, frame interval, checkpoint interval) in steps; the checkpoint interval is 0 (none on a step
    schedule: by wall time, ``spec.checkpoint_wall_s``) unless ``spec.checkpoint_interval_ps`` is given."""
    steps = spec.time_ns * 1000.0 / dt
    if not steps <= MAX_STEPS:
        raise ParameterError(f"--time {spec.time_ns:g} ns at --dt {dt:g} ps is {steps:.3g} steps, more than "
                             f"{MAX_STEPS:.0e}; give a shorter --time (ns) or a larger --dt (ps)")
    n_steps = max(1, int(round(steps)))
    fi = max(1, int(round(spec.frame_interval_ps / dt)))
    ci = 0 if spec.checkpoint_interval_ps is None else int(round(spec.checkpoint_interval_ps / dt))
    return n_steps, fi, ci


def estimate_run_bytes(spec: RunSpec, n_nodes: int, dt: float) -> int:
    """Disk space a run of ``spec`` takes (bytes, an estimate checked against the free space before it starts):
    the ``.dtraj`` frames (:func:`dnarod.core.trajectory.bytes_per_node_frame`), ``energies.csv`` rows, two
    checkpoints and the final model (a checkpoint is replaced atomically, so the old and the new one exist at
    once), and the exports."""
    n_steps, fi, _ = intervals(spec, dt)
    frames = n_steps // fi + 1
    total = HEADER_SIZE + frames * (16 + n_nodes * bytes_per_node_frame(spec.velocities))
    total += frames * 220                       # one energies.csv row (~9 numbers in repr, plus observables)
    # two checkpoints (OpenMM's state blob ~430 B/node, the lax engine's ~145) and final_model.npz (~525 B/node)
    total += 3 * 1024 + n_nodes * (2 * 450 + 530)
    if spec.export:
        from dnarod.structure.export import dcd_bytes  # loads scipy.spatial: not at the CLI's start-up

        dcd = dcd_bytes(frames, 3 * n_nodes)  # exact
        total += 270 * n_nodes + dcd  # PDB (3 beads of 88 B per node) and DCD
        if spec.xtc:
            total += int(0.45 * dcd)  # XTC compresses to 0.001 nm: ~0.4 of the DCD on chains of 20 to 2000 nodes
    return int(total)


def run_folder_markers() -> tuple[str, ...]:
    """Names that mark a folder as a run's (any of them): the run files, and the record of an ensemble member
    (:data:`dnarod.core.io.RESULT`, ``MEMBER``, ``LOG``), whose folder is a run folder. A new run refuses any other
    non-empty folder (:func:`dnarod.core.io.check_output_folder`)."""
    return (*RUN_FILES.values(), MEMBER, LOG, RESULT)


def run_files(outdir: str | Path) -> dict[str, Path]:
    """Name -> Path of the run-folder files that exist."""
    outdir = Path(outdir)
    return {k: outdir / v for k, v in RUN_FILES.items() if (outdir / v).exists()}


def _observables(spec, model):
    """Per-frame observables of the loads for the energies CSV (:mod:`dnarod.physics.observables`), or None."""
    return csv_observables(model, tuple(spec.loads), duration_ps=spec.time_ns * 1000.0)


def _run_id(fp):
    return hashlib.sha256(json.dumps(jsonable(fp), sort_keys=True).encode()).hexdigest()[:20]


# ----------------------------------------------------------------------------------------------
def run(spec: RunSpec, outdir: str | Path, resume: bool = False, overwrite: bool = False,
        progress: bool = True) -> RunResult:
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
    stage = _setup_start(spec, progress)
    model = source_model(spec)
    stage = _setup_model(spec, model, stage, progress)
    check_start_pose(model, spec.temperature)
    seed = resolve_seed(spec.seed)
    if spec.start != "intrinsic":
        stage(f"the {spec.start} start pose")
    start = start_model(spec, model, seed)
    if spec.engine == "mc":  # no time step: one sweep counts as 1 ps (dnarod.engines.mc)
        omega, dt = None, 1.0
    else:
        stage("the fastest normal mode (time step)")
        omega = default_omega_max(start if start is not None else model, spec.loads)
        check_load_stiffness(spec, model)
        dt = choose_dt(spec, model, omega)
    intervals(spec, dt)  # refuses an absurd number of steps before anything is written
    check_free_space(outdir, estimate_run_bytes(spec, model.n_nodes, dt), "this run")
    fp = fingerprint(spec, model, dt, seed)
    run_id = _run_id(fp)
    stage(f"the {spec.engine} engine")
    engine = make_engine(spec, start if start is not None else model, dt, seed, omega)
    if start is None:  # OpenMM energy minimisation of the context (no static solver available)
        engine.minimize()
    with folder_lock(outdir):  # a second process writing into outdir is refused, not interleaved
        present_now = [p for p in paths.values() if p.exists()]
        if not overwrite and present_now:  # another process started a run here while this one was set up
            raise ParameterError(f"{outdir} already holds a run ({present_now[0].name}); continue it with --resume, "
                                 f"replace it with --overwrite, or choose another folder with -o")
        meta = dict(format="dnarod-run", version=1, run_id=run_id, spec=spec.to_json(), fingerprint=fp, seed=seed,
                    dt_ps=dt, omega_max=omega, segments=[])
        if not present_now:
            _write_meta(paths, meta)
            return _execute(spec, outdir, paths, engine, model, meta, resume_step=None, progress=progress)
        # overwrite: the new run is made beside the old one (a hidden folder in outdir) and replaces its files only
        # when it is complete; a failure (a full disk, a blow-up, Ctrl-C) leaves the old run as it was
        with staged_folder(outdir, RUN_FILES.values(), what="run") as stage:
            spaths = {k: stage / v for k, v in RUN_FILES.items()}
            _write_meta(spaths, meta)
            result = _execute(spec, stage, spaths, engine, model, meta, resume_step=None, progress=progress)
        return RunResult(outdir, run_files(outdir), result.summary, result.resumed_from)


def _setup_start(spec, progress):
    """Before the model is built: refuse a node count this machine's memory cannot hold, say that the kernels
    compile (a first run after install), and return the set-up's stage printer (:class:`SetupStages`)."""
    from dnarod.run.resources import compile_notice  # loads scipy.spatial
    from dnarod.run.resources import SetupStages, check_memory, node_count_hint  # loads scipy.spatial

    n = node_count_hint(spec.source)
    check_memory(n, spec.engine)
    if progress:
        notice = compile_notice(spec.engine)
        if notice:
            sys.stderr.write(f"dnarod: {notice}\n")
            sys.stderr.flush()
    stage = SetupStages(n, progress)
    stage("building the model")
    return stage


def _setup_model(spec, model, stage, progress):
    """Once the model is built: the memory check of a source whose size was not known before (a file)."""
    from dnarod.run.resources import SetupStages, check_memory  # loads scipy.spatial

    if not stage.on:
        check_memory(model.n_nodes, spec.engine)
        stage = SetupStages(model.n_nodes, progress)
    return stage


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
    stage = _setup_start(spec, progress)
    model = source_model(spec)
    stage = _setup_model(spec, model, stage, progress)
    spec_dt = dt if spec.dt is None else float(spec.dt)
    spec_seed = seed if spec.seed is None else int(spec.seed)
    compare_fingerprints(old_fp, fingerprint(spec, model, spec_dt, spec_seed), paths["run_json"])
    if not paths["checkpoint"].exists() and not meta.get("segments"):
        # stopped before its first checkpoint (no segment ever finished): nothing to lose, start it again
        return _restart(spec, outdir, paths, model, meta, run_json_text, seed, dt, progress)
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
        stale = export_status(outdir, meta, spec.xtc)[1] if spec.export else []
        if stale:  # the run ended (or was killed) before its exports were made, or they were made from less
            with folder_lock(outdir):
                _export(paths, meta, spec.xtc, _sequence_of(paths))
        files = run_files(outdir)
        if stale:
            msg = (f"the run in {outdir} is already at step {step} ({step * dt / 1000:.6g} ns) >= the requested "
                   f"{spec.time_ns:g} ns; remade its exports ({', '.join(stale)})")
        else:
            msg = (f"the run in {outdir} is already at step {step} ({step * dt / 1000:.6g} ns) >= the requested "
                   f"{spec.time_ns:g} ns; nothing to do (nothing changed)")
        return RunResult(outdir, files, dict(steps=step, steps_this_run=0, simulated_ps=step * dt, dt_ps=dt,
                                             omega_max=meta.get("omega_max"), already_done=True, message=msg,
                                             seed=seed, engine=spec.engine), resumed_from=step)
    have = sum(p.stat().st_size for p in run_files(outdir).values())
    check_free_space(outdir, estimate_run_bytes(spec, model.n_nodes, dt) - have, "the rest of this run")
    start = start_model(spec, model, seed)
    stage(f"the {spec.engine} engine")
    engine = make_engine(spec, start if start is not None else model, dt, seed, meta.get("omega_max"))
    with folder_lock(outdir):  # not while another process still runs (or resumes) in outdir
        if paths["run_json"].read_text() != run_json_text:
            raise ParameterError(f"cannot resume: {paths['run_json']} changed while this resume was set up (another "
                                 f"process wrote the run); run the command again")
        engine.load_checkpoint(paths["checkpoint"])
        meta["spec"] = spec.to_json()
        write_text_atomic(paths["run_json"], json.dumps(jsonable(meta), indent=1) + "\n")
        return _execute(spec, outdir, paths, engine, model, meta, resume_step=engine.step, progress=progress)


def _restart(spec, outdir, paths, model, meta, run_json_text, seed, dt, progress):
    """Resume a run stopped before its first checkpoint (a crash, a full disk, Ctrl-C early on): it starts again
    from its start pose with its own seed, so it is the run that was begun (its partial frames are replaced)."""
    start = start_model(spec, model, seed)
    engine = make_engine(spec, start if start is not None else model, dt, seed, meta.get("omega_max"))
    if start is None:  # OpenMM energy minimisation of the context (no static solver available)
        engine.minimize()
    with folder_lock(outdir):
        if paths["run_json"].read_text() != run_json_text:
            raise ParameterError(f"cannot resume: {paths['run_json']} changed while this resume was set up (another "
                                 f"process wrote the run); run the command again")
        for key in ("trajectory", "energies", "final_model"):
            paths[key].unlink(missing_ok=True)
        meta["spec"] = spec.to_json()
        meta["segments"] = []
        write_text_atomic(paths["run_json"], json.dumps(jsonable(meta), indent=1) + "\n")
        return _execute(spec, outdir, paths, engine, model, meta, resume_step=None, progress=progress)


def _execute(spec, outdir, paths, engine, model, meta, resume_step, progress):
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
    try:
        out = simulate_engine(engine, n_steps, outdir, fi, fi, None if spec.checkpoint_interval_ps is None else ci,
                              resume=resume_step is not None, overwrite=True, velocities=spec.velocities,
                              metadata=traj_meta, observables=_observables(spec, engine.model), progress=progress,
                              duration_ps=spec.time_ns * 1000.0, checkpoint_extra=dict(run=meta["run_id"]),
                              restored=True, checkpoint_wall_s=spec.checkpoint_wall_s)
    except WriteError as exc:  # a full disk mid-run: say what the rest of the run needs and how to go on
        raise _run_write_error(exc, spec, model.n_nodes, dt, outdir, staged=resume_step is None and
                               outdir.name.startswith(STAGE_PREFIX)) from None
    meta["segments"].append(dict(from_step=resume_step or 0, to_step=out["steps"], wall_s=out["wall_s"],
                                 cpu_s=out["cpu_s"]))
    meta.pop("export", None)  # the trajectory changed: the exports are stale until remade
    _write_meta(paths, meta)
    # after run.json: a failed export leaves a finished run whose --resume (or `dnarod export`) remakes it
    if spec.export:
        try:
            _export(paths, meta, spec.xtc, model.sequence)
        except WriteError as exc:
            if not outdir.name.startswith(STAGE_PREFIX):
                exc.args = (f"{exc}; the run itself is complete: make its exports with `dnarod export {outdir}` "
                            f"(or --resume)",)
            raise
    done = out["steps_this_run"]
    wall = out["wall_s"]
    temps = out["temperatures"]
    summary = dict(engine=spec.engine, n_nodes=model.n_nodes, steps=out["steps"], steps_this_run=done,
                   simulated_ps=out["steps"] * dt, dt_ps=dt, omega_max=getattr(engine, "omega_max", None),
                   frame_interval_steps=fi, wall_s=wall, cpu_s=out["cpu_s"], ns_per_day=_ns_per_day(out, dt),
                   mean_temperature_K=float(np.mean(temps)) if temps else float("nan"), seed=meta["seed"],
                   already_done=False, message=None, selection=(model.metadata or {}).get("selection"))
    if spec.engine == "mc":
        summary.update(acceptance=engine.acceptance(), amplitudes=engine.amplitudes())
    if spec.engine == "openmm":
        summary.update(elastic_path=engine.rs.elastic, platform=engine.platform_name,
                       platform_reason=getattr(engine, "platform_reason", None),
                       nonbonded=engine.rs.nonbonded or None, context_s=engine.context_time)
    return RunResult(outdir, run_files(outdir), summary, resumed_from=resume_step)


# ----------------------------------------------------------------------------------------------
# exports (trajectory.pdb, .dcd, .xtc): made from the .dtraj, recorded in run.json, remade when stale
# ----------------------------------------------------------------------------------------------
def _run_write_error(exc, spec, n_nodes, dt, outdir, staged):
    """The one line of a run stopped by a failed write: for a full disk the space the rest of the run needs;
    the run continues from its last checkpoint with ``--resume``."""
    needed = exc.needed
    if exc.errno in FULL_DISK_ERRNOS:
        have = sum(p.stat().st_size for p in run_files(outdir).values())
        needed = max(estimate_run_bytes(spec, n_nodes, dt) - have, exc.needed or 0)
    err = write_failure(exc.path, OSError(exc.errno, ""), needed) if exc.errno is not None else exc
    if not staged:
        err.args = (str(err) + "; the run continues from its last checkpoint with --resume",)
    return err


def _ns_per_day(out, dt):
    """Speed of the run loop, ns/day, over the steps after its first advance (:func:`dnarod.run.loop.run_engine`:
    the kernels' first-call compile and the first report are not in it); over the whole loop if it had one advance."""
    steps, wall = out.get("timed_steps"), out.get("timed_wall_s")
    if not steps or not wall or wall <= 0:
        steps, wall = out["steps_this_run"], out["wall_s"]
    return steps * dt * 1e-3 / wall * 86400 if wall > 0 and steps else float("nan")


def _write_meta(paths, meta):
    write_text_atomic(paths["run_json"], json.dumps(jsonable(meta), indent=1) + "\n")


def _dtraj_stamp(path):
    """What identifies the trajectory an export was made from: its size and modification time (ns)."""
    st = Path(path).stat()
    return dict(dtraj_bytes=int(st.st_size), dtraj_mtime_ns=int(st.st_mtime_ns))


def export_status(outdir: str | Path, meta: dict[str, Any] | None = None,
                  xtc: bool = True) -> tuple[list[str], list[str]]:
    """Which exports of the run in ``outdir`` are up to date.

    An export is up to date when it exists and ``run.json`` records that it was made from the trajectory
    as it is now (size and modification time of ``trajectory.dtraj``); a run stopped between its end and its
    exports (a full disk, a path the XTC writer refused, a kill) has none recorded.

    Parameters
    ----------
    outdir : str or Path
    meta : dict, optional
        ``run.json`` (read if not given).
    xtc : bool
        Whether ``trajectory.xtc`` is expected.

    Returns
    -------
    (list of str, list of str)
        File names up to date, file names missing or stale.
    """
    outdir = Path(outdir)
    if meta is None:
        meta = json.loads((outdir / RUN_FILES["run_json"]).read_text())
    names = [RUN_FILES[k] for k in ("pdb", "dcd", "xtc") if k != "xtc" or xtc]
    traj = outdir / RUN_FILES["trajectory"]
    rec = meta.get("export") or {}
    fresh = traj.exists() and {k: rec.get(k) for k in ("dtraj_bytes", "dtraj_mtime_ns")} == _dtraj_stamp(traj)
    ok = [n for n in names if fresh and n in rec.get("files", ()) and (outdir / n).exists()]
    return ok, [n for n in names if n not in ok]


def _sequence_of(paths):
    """Strand I of the run's model (``final_model.npz``, else the trajectory's metadata), or None."""
    if paths["final_model"].exists():
        try:
            return RodModel.load(paths["final_model"]).sequence
        except Exception:  # noqa: BLE001 - a damaged model file: fall back to the trajectory's metadata
            pass
    return None


def _export(paths, meta, xtc, sequence):
    """Export ``trajectory.dtraj`` to PDB + DCD (+ XTC) and record it in ``run.json`` (the folder is locked)."""
    from dnarod.structure.export import export_trajectory  # loads scipy.spatial: not at the CLI's start-up

    if not paths["trajectory"].exists():
        raise ParameterError(f"{paths['trajectory']} does not exist: nothing to export")
    xtc_fresh = paths["xtc"].name in export_status(paths["run_json"].parent, meta, True)[0]
    stamp = _dtraj_stamp(paths["trajectory"])
    export_trajectory(paths["trajectory"], paths["pdb"], paths["dcd"], sequence=sequence,
                      xtc_path=paths["xtc"] if xtc else None)
    if not xtc and not xtc_fresh:
        paths["xtc"].unlink(missing_ok=True)  # an XTC of an earlier trajectory would be stale
    files = [paths[k].name for k in ("pdb", "dcd", "xtc") if k != "xtc" or xtc or xtc_fresh]
    meta["export"] = dict(stamp, files=files)
    _write_meta(paths, meta)
    return {n: paths["run_json"].parent / n for n in files}


def export_run(outdir: str | Path, xtc: bool | None = None) -> dict[str, Path]:
    """Make (or remake) the exports of the run in ``outdir``: ``trajectory.pdb`` (topology, first frame),
    ``trajectory.dcd`` (all frames) and ``trajectory.xtc`` (all frames, with times), from ``trajectory.dtraj``.

    The files are written atomically (the old ones stay until the new ones are complete) and recorded in
    ``run.json``, so :func:`export_status` (and ``--resume`` of a finished run) knows they are up to date.
    The folder is locked while they are written (a run still writing it is refused).

    Parameters
    ----------
    outdir : str or Path
        A run folder (``run.json`` and ``trajectory.dtraj``).
    xtc : bool, optional
        Also write ``trajectory.xtc`` (default: as the run's settings say).

    Returns
    -------
    dict
        File name -> Path of the exports written.

    Raises
    ------
    ParameterError
        ``outdir`` holds no run or no trajectory.
    WriteError
        A file could not be written (one line naming it; a full disk gives the free space).
    """
    if not isinstance(outdir, (str, Path)) or not str(outdir).strip():
        raise ParameterError(f"run folder {outdir!r}: give a folder path")
    outdir = Path(outdir)
    paths = {k: outdir / v for k, v in RUN_FILES.items()}
    if not paths["run_json"].exists():
        what = "does not exist" if not outdir.exists() else "holds no run (no run.json)"
        raise ParameterError(f"{outdir} {what}: give the folder of a `dnarod simulate` run")
    try:
        meta = json.loads(paths["run_json"].read_text())
        spec_xtc = bool((meta.get("spec") or {}).get("xtc", True))
    except (OSError, ValueError, AttributeError) as exc:
        raise ParameterError(f"{paths['run_json']}: not a readable dnarod run file ({type(exc).__name__})") from None
    with folder_lock(outdir):
        return _export(paths, meta, spec_xtc if xtc is None else bool(xtc), _sequence_of(paths))
