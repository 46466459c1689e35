"""``dnarod simulate`` (both engines) and its alias ``dnarod lax-run``: a thin shell over :func:`dnarod.run.run`.

Results go to stdout, diagnostics (progress bar, warnings) to stderr.
"""
from __future__ import annotations

import warnings


import click
import numpy as np
from click.core import ParameterSource

from dnarod.core.errors import ParameterError
from dnarod.physics.nonbonded import nonbonded_options
from dnarod.run.api import source_model, run
from dnarod.physics.loads import tweezers
from dnarod.run.spec import RunSpec

#: ``--charge`` and ``--cutoff-debye``, shared by ``dnarod simulate`` and ``dnarod protocol`` (checked by
#: :func:`dnarod.physics.nonbonded.nonbonded_options`).
CHARGE_OPTIONS = [
    click.option("--charge", default=None,
                 help="Non-bonded charge model: calibrated (Poisson-Boltzmann far-field charge, effective diameter "
                      "5.0 nm at 0.15 M; the default) or manning (0.48 e/bp)."),
    click.option("--cutoff-debye", "cutoff_debye", type=float, default=None,
                 help="Debye-Hueckel cutoff, Debye lengths (default 12)."),
]

_OPTIONS = [
    click.argument("source"),
    click.option("-f", "--forcefield", default="dna-default", show_default=True,
                 help="Force field: a bundled name or a .toml file."),
    click.option("--circular", is_flag=True, help="Periodic chain (screw-closed straight helix) from a sequence."),
    click.option("--ring", is_flag=True, help="Closed planar ring (a minicircle) from a sequence."),
    click.option("--delta-lk", type=int, default=0, show_default=True,
                 help="With --ring: linking number relative to the relaxed ring (supercoiling)."),
    click.option("--duplex", type=int, default=None,
                 help="Duplex of a structure file, numbered from 1 as `dnarod pairs` lists them [default: longest]."),
    click.option("--intrinsic", type=click.Choice(["sequence", "structure"]), default="sequence", show_default=True,
                 help="Intrinsic shape of a structure's model: the force field's for its sequence, or the "
                      "structure's own step parameters (a protein-bent DNA keeps its bend)."),
    click.option("--time", "time_ns", type=float, default=1.0, show_default=True,
                 help="Total simulated time, ns (with --resume: the new total)."),
    click.option("--dt", type=float, default=None, help="Time step, ps [default: 0.4/omega_max of the model]."),
    click.option("-T", "--temperature", type=float, default=300.0, show_default=True, help="K."),
    click.option("--friction", type=float, default=None,
                 help="Langevin collision rate, 1/ps; 0 runs NVE (constant energy) from Maxwell velocities "
                      "[default: 1.0]."),
    click.option("--integrator", type=click.Choice(["langevin", "verlet"]), default="langevin", show_default=True,
                 help="verlet: NVE (the same as --friction 0)."),
    click.option("--platform", default=None,
                 help="OpenMM platform (CPU, Reference, CUDA, HIP, OpenCL) [default: chosen automatically: a GPU "
                      "platform if a GPU is present, else the CPU fast path; the choice and its reason are printed]."),
    click.option("--threads", type=int, default=None,
                 help="OpenMM CPU platform threads (without --platform: more than 1 selects the CPU platform, 1 the "
                      "single-threaded Reference platform)."),
    click.option("--elastic", type=click.Choice(["auto", "plugin", "fast", "portable"]), default="auto",
                 show_default=True,
                 help="OpenMM elastic path."),
    click.option("--excluded-volume/--no-excluded-volume", default=None,
                 help="WCA excluded volume [default: on with --engine openmm; the lax engine has none]."),
    click.option("--electrostatics/--no-electrostatics", default=None,
                 help="Debye-Hueckel electrostatics [default: on with --engine openmm; the lax engine has none]."),
    click.option("--salt", type=float, default=0.15, show_default=True, help="Monovalent salt, mol/L (Debye length)."),
    *CHARGE_OPTIONS,
    click.option("--pull", type=float, default=None,
                 help="Pull the last node along the axis (and node 0 the other way unless --clamp-first), pN."),
    click.option("--torque", type=float, default=None, help="Torque on the last node about the axis, pN nm."),
    click.option("--rotation-clamp", type=float, default=None,
                 help="Clamp the last node's orientation, stiffness kJ/mol."),
    click.option("--turns", type=float, default=0.0,
                 help="Turn the rotation clamp by this many turns, at a constant rate over the run, counted from "
                      "the torque-free state at --temperature (as magnet turns are): the clamp's target starts "
                      "turned by the 0 K offset, turns_offset_0K in run.json (about -0.42 turns for 1 kbp at "
                      "300 K)."),
    click.option("--clamp-first", is_flag=True,
                 help="Fix the first base pair in space (position and orientation): the surface of a magnetic-tweezers "
                      "cell."),
    click.option("--axis", type=click.Choice(["end-to-end", "z"]), default="end-to-end", show_default=True,
                 help="Axis of --pull, --torque and --rotation-clamp: the source's end-to-end direction or lab z."),
    click.option("--trap", multiple=True,
                 help="Harmonic trap NODE:K (NODE a base pair numbered from 1 as `dnarod steps` does, -1 the last; "
                      "K in pN/nm) at its start position; repeatable."),
    click.option("--minimize", is_flag=True, help="Start from the static minimum under the loads."),
    click.option("--equilibrium", is_flag=True,
                 help="Start from an exact thermal-equilibrium sample of the free chain (open chains)."),
    click.option("-o", "--out", "outdir", default="dnarod_run", show_default=True,
                 help="Output folder (run.json, trajectory, energies, checkpoint, final model): new, empty or a "
                      "run's (any other non-empty folder is refused); locked (OUT/.dnarod.lock) while the run "
                      "writes."),
    click.option("--frame-interval", type=float, default=1.0, show_default=True,
                 help="Time between trajectory frames and energy rows, ps."),
    click.option("--checkpoint-interval", type=float, default=None,
                 help="Simulated time between checkpoints, ps [default: by wall time, --checkpoint-wall]; one is "
                      "always written at the end and on Ctrl-C."),
    click.option("--checkpoint-wall", type=float, default=None,
                 help="Wall-clock seconds between checkpoints when --checkpoint-interval is not given "
                      "[default: 120]."),
    click.option("--resume", is_flag=True, help="Continue the run in --out from its checkpoint up to --time."),
    click.option("--overwrite", is_flag=True, help="Replace an earlier run in --out (its run files are removed)."),
    click.option("--seed", type=int, default=None,
                 help="Seed of the initial velocities and the Langevin noise [default: drawn and recorded in "
                      "run.json; --resume keeps it]."),
    click.option("--velocities", is_flag=True, help="Also store velocities in the trajectory (1.5x its size)."),
    click.option("--export/--no-export", default=True, show_default=True,
                 help="Also write trajectory.pdb + trajectory.dcd for VMD, mdtraj and MDAnalysis."),
    click.option("--xtc/--no-xtc", default=True, show_default=True,
                 help="With --export, also write trajectory.xtc (frame times that mdtraj reads; its DCD reader has "
                      "none)."),
    click.option("--progress/--no-progress", default=True, show_default=True, help="Progress bar on stderr."),
]


def _simulate_options(f):
    for opt in reversed(_OPTIONS):
        f = opt(f)
    return f


def parse_trap(text, n_nodes):
    """``"NODE:K"`` (K in pN/nm) -> (node index from 0, K). NODE is a base pair numbered from 1, as `dnarod steps`
    and every message number them; a negative NODE counts from the end (-1: the last)."""
    try:
        node, k = text.split(":")
        node, k = int(node), float(k)
    except ValueError:
        raise ParameterError(f"--trap {text!r}: expected NODE:STIFFNESS (a base pair numbered from 1, stiffness in "
                             f"pN/nm), e.g. 1:50") from None
    if node == 0:
        raise ParameterError(f"--trap {text!r}: base pairs are numbered from 1 (1 to {n_nodes}, or -1 for the last)")
    if not -n_nodes <= node <= n_nodes:
        raise ParameterError(f"--trap {text!r}: base pair {node} does not exist (the chain has {n_nodes} nodes, "
                             f"numbered from 1)")
    node = node - 1 if node > 0 else node
    if not (np.isfinite(k) and k > 0):
        raise ParameterError(f"--trap {text!r}: the stiffness must be positive (pN/nm)")
    return node, k


def spec_from_options(engine, source, forcefield, circular, ring, delta_lk, duplex, intrinsic, time_ns, dt, temperature,
                      friction, integrator, platform, threads, elastic, excluded_volume, electrostatics, salt, pull,
                      torque, rotation_clamp, turns, clamp_first, trap, minimize, equilibrium, frame_interval,
                      checkpoint_interval, seed, velocities, export, xtc, charge=None, cutoff_debye=None,
                      axis="end-to-end", checkpoint_wall=None):
    """The :class:`~dnarod.run.RunSpec` of the ``simulate`` options (loads built from the source model)."""
    if minimize and equilibrium:
        raise ParameterError("choose --minimize or --equilibrium, not both")
    if integrator == "verlet":
        if friction not in (None, 0.0):
            raise ParameterError(f"--integrator verlet runs NVE (no friction) but --friction {friction:g} was given; "
                                 f"drop one of them")
        friction = 0.0
    elif friction is None:
        friction = 1.0
    nb_default = engine in ("openmm", "mc")
    charge_options = nonbonded_options(charge, cutoff_debye, salt, temperature)
    spec = RunSpec(**charge_options, source=source, forcefield=forcefield, engine=engine, time_ns=time_ns,
                   temperature=temperature,
                   friction=friction, dt=dt, seed=seed, salt=salt,
                   excluded_volume=nb_default if excluded_volume is None else excluded_volume,
                   electrostatics=nb_default if electrostatics is None else electrostatics, platform=platform,
                   circular=circular, ring=ring, delta_lk=delta_lk, duplex=duplex, intrinsic=intrinsic,
                   start="minimized" if minimize else "equilibrium" if equilibrium else "intrinsic",
                   frame_interval_ps=frame_interval, checkpoint_interval_ps=checkpoint_interval, velocities=velocities,
                   export=export, xtc=xtc, elastic=elastic, threads=threads,
                   **({} if checkpoint_wall is None else dict(checkpoint_wall_s=checkpoint_wall)))
    spec.check()
    _refuse_ignored_options(spec, xtc, export)
    if pull is not None or torque is not None or rotation_clamp is not None or clamp_first or trap or turns:
        model = source_model(spec)
        traps = tuple(parse_trap(t, model.n_nodes) for t in trap)
        if len({node % model.n_nodes for node, _ in traps}) < len(traps):  # two traps on one base pair add up silently
            seen = {}
            for t, (node, _) in zip(trap, traps):
                if node % model.n_nodes in seen:
                    raise ParameterError(f"--trap {t!r}: base pair {node % model.n_nodes + 1} already has a trap "
                                         f"({seen[node % model.n_nodes]!r}); give one --trap per base pair with the "
                                         f"stiffness you want")
                seen[node % model.n_nodes] = t
        # turns count from the torque-free state at the run's temperature: the clamp's target starts turned by the
        # 0 K offset (dnarod.physics.loads.torque_free_offset), recorded in run.json (spec extra)
        from dnarod.physics.loads import torque_free_offset

        offset = torque_free_offset(model, spec.temperature) if rotation_clamp is not None else 0.0
        spec = spec.replace(loads=tweezers(model, pull, torque, rotation_clamp, turns,
                                           anchor="surface" if clamp_first else "ends", axis=axis, traps=traps,
                                           turns_offset=offset),
                            extra={**dict(spec.extra), **({"turns_offset_0K": offset} if rotation_clamp is not None
                                                          else {})})
    return spec


def _given(name):
    """True if option ``name`` (the parameter name) was given on the command line (not its default)."""
    ctx = click.get_current_context(silent=True)
    return ctx is not None and ctx.get_parameter_source(name) in (ParameterSource.COMMANDLINE,
                                                                  ParameterSource.ENVIRONMENT)


def _refuse_ignored_options(spec, xtc, export):
    """An option given explicitly that these settings would ignore is refused (it was silently dropped)."""
    if _given("salt") and not spec.nonbonded:
        why = "the lax engine has none" if spec.engine == "lax" else "--no-electrostatics --no-excluded-volume"
        raise ParameterError(f"--salt {spec.salt:g}: sets the Debye screening of the non-bonded terms, which are "
                             f"off here ({why}); drop --salt or turn them on")
    if _given("xtc") and xtc and not export:
        raise ParameterError("--xtc writes trajectory.xtc beside the exported PDB/DCD, but --no-export was given; "
                             "drop one of them")


def _report(result, spec):
    s = result.summary
    echo = click.echo
    if s.get("already_done"):
        echo(s["message"])
        return
    if result.resumed_from is not None:
        echo(f"resumed from step {result.resumed_from} ({result.resumed_from * s['dt_ps'] / 1000:.6g} ns)")
    if s.get("selection"):
        echo(f"input: {s['selection']}")
    head = f"engine: {s['engine']}  nodes: {s['n_nodes']}  ensemble: {spec.ensemble}"
    if s["engine"] == "openmm":
        head += f"  elastic path: {s['elastic_path']}  platform: {s['platform']}"
    echo(head)
    if s.get("platform_reason"):
        echo(f"platform choice: {s['platform_reason']}")
    if s["engine"] == "mc":
        echo(f"Monte Carlo sweeps: {s['steps']} (1 ps = 1 sweep)  seed: {s['seed']}")
    else:
        echo(f"dt: {s['dt_ps'] * 1000:.2f} fs (omega_max {s['omega_max']:.4g} rad/ps)  steps: {s['steps']}  "
             f"simulated: {s['simulated_ps'] / 1000:.6g} ns  seed: {s['seed']}")
    nb = s.get("nonbonded")
    if nb:
        echo(f"nonbonded: Debye length {nb['debye_length']:.3g} nm, charge {nb['charge']:.3g} e/bp"
             f"{' (' + nb['charge_model'] + ')' if nb.get('charge_model') else ''}, "
             f"cutoff {nb['cutoff']:.3g} nm"
             + (f" ({nb['rc_dh'] * nb['kappa']:.3g} Debye lengths)" if nb.get("rc_dh") else "")
             + f", chain exclusion {nb['n_exclude']} bp")
    if spec.extra.get("turns_offset_0K") is not None:
        echo(f"turns counted from the torque-free state at {spec.temperature:g} K: the clamp started "
             f"{spec.extra['turns_offset_0K']:+.4f} turns (turns_offset_0K) from the chain's 0 K intrinsic twist")
    if s["engine"] == "mc":
        echo(f"wall: {s['wall_s']:.1f} s (CPU {s['cpu_s']:.1f} s)  acceptance: "
             + ", ".join(f"{k} {v:.2f}" for k, v in (s.get("acceptance") or {}).items() if v == v))
    else:
        echo(f"wall: {s['wall_s']:.1f} s (CPU {s['cpu_s']:.1f} s)  speed: {s['ns_per_day']:.4g} ns/day  "
             f"mean kinetic temperature: {s['mean_temperature_K']:.1f} K")
    echo("wrote: " + ", ".join(str(p) for p in result.files.values()))


def _run_command(engine, kw):

    resume, overwrite, progress, outdir = kw.pop("resume"), kw.pop("overwrite"), kw.pop("progress"), kw.pop("outdir")
    spec = spec_from_options(engine, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, *a, **k: click.echo(f"dnarod: warning: {message}", err=True)
        result = run(spec, outdir, resume=resume, overwrite=overwrite, progress=progress)
    _report(result, spec)


@click.command("simulate")
@click.option("--engine", type=click.Choice(["openmm", "lax", "mc"]), default="openmm", show_default=True,
              help="OpenMM engine, the direct Lax-form integrator, or the Monte Carlo sampler (equilibrium only; "
                   "its times count sweeps, 1 ps = 1 sweep). Same model, same outputs.")
@_simulate_options
def simulate_cmd(engine, **kw):
    """Simulate SOURCE with either engine.

    SOURCE is a PDB/mmCIF structure (a duplex of it: nodes at its base-pair frames), a saved model
    .npz, a DNA sequence (any length), a FASTA or plain-text sequence file (.fa, .fasta, .fna,
    .seq, .txt) or a node count.

    Writes OUT/run.json, OUT/trajectory.dtraj, OUT/energies.csv, OUT/checkpoint.npz,
    OUT/final_model.npz (and OUT/trajectory.pdb + .dcd + .xtc with --export) and prints a
    summary. --resume continues up to --time, refusing any change of the run's settings.
    """
    _run_command(engine, kw)


@click.command("lax-run")
@_simulate_options
def lax_run(**kw):
    """Alias of `dnarod simulate --engine lax` (same options)."""
    _run_command("lax", kw)
