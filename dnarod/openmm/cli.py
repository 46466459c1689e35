"""``dnarod simulate``: run the OpenMM engine on a structure (PDB/mmCIF), a sequence or a saved model."""
from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from ..errors import ParameterError
from ..inputs import load_model


def _parse_trap(text, n_nodes):
    try:
        node, k = text.split(":")
        return int(node), float(k)
    except ValueError:
        raise ParameterError(f"--trap {text!r}: expected NODE:STIFFNESS (stiffness in pN/nm), e.g. 0:50") from None


@click.command("simulate")
@click.argument("source")
@click.option("-f", "--forcefield", default="dna-default", show_default=True, help="Force field (bundled name or .toml).")
@click.option("--circular", is_flag=True, help="Periodic chain (screw-closed straight helix) when SOURCE is a sequence.")
@click.option("--ring", is_flag=True, help="Closed planar ring (a minicircle) when SOURCE is a sequence.")
@click.option("--delta-lk", type=int, default=0, show_default=True,
              help="With --ring: linking number relative to the relaxed ring (supercoiling).")
@click.option("--time", "time_ns", type=float, default=1.0, show_default=True, help="Simulated time, ns.")
@click.option("--dt", type=float, default=None, help="Time step, ps [default: 0.4/omega_max of the model].")
@click.option("-T", "--temperature", type=float, default=300.0, show_default=True, help="K.")
@click.option("--friction", type=float, default=1.0, show_default=True, help="Langevin friction, 1/ps.")
@click.option("--integrator", type=click.Choice(["langevin", "verlet"]), default="langevin", show_default=True)
@click.option("--platform", default=None,
              help="OpenMM platform (CUDA, OpenCL, HIP, CPU, Reference) [default: automatic, CUDA > OpenCL GPU > "
                   "CPU fast path; the choice is printed].")
@click.option("--threads", type=int, default=None, help="CPU platform threads.")
@click.option("--elastic", type=click.Choice(["auto", "fast", "portable"]), default="auto", show_default=True)
@click.option("--excluded-volume/--no-excluded-volume", default=True, show_default=True)
@click.option("--electrostatics/--no-electrostatics", default=True, show_default=True)
@click.option("--salt", type=float, default=0.15, show_default=True, help="Monovalent salt, mol/L (Debye length).")
@click.option("--pull", type=float, default=None, help="Pull the ends apart along their initial axis, pN.")
@click.option("--torque", type=float, default=None, help="Torque on the last node about the end-to-end axis, pN nm.")
@click.option("--rotation-clamp", type=float, default=None, help="Clamp the last node's orientation, stiffness kJ/mol.")
@click.option("--turns", type=float, default=0.0,
              help="Turn the rotation clamp by this many turns, at a constant rate over the run.")
@click.option("--clamp-first", is_flag=True, help="Fix node 0 in space (position and orientation).")
@click.option("--trap", multiple=True, help="Harmonic trap NODE:K (pN/nm) at the node's start position; repeatable.")
@click.option("--minimize", is_flag=True, help="Minimise the energy before the run.")
@click.option("-o", "--out", "outdir", default="dnarod_run", show_default=True, type=click.Path(file_okay=False))
@click.option("--frame-interval", type=int, default=None, help="Steps between frames [default: 1 ps worth].")
@click.option("--checkpoint-interval", type=int, default=None, help="Steps between checkpoints [default: 10 frames].")
@click.option("--resume", is_flag=True, help="Continue the run in --out from its checkpoint.")
@click.option("--overwrite", is_flag=True, help="Replace an earlier run in --out.")
@click.option("--seed", type=int, default=None)
@click.option("--export/--no-export", default=True, show_default=True, help="Also write trajectory.pdb + .dcd.")
@click.option("--progress/--no-progress", default=True, show_default=True)
def simulate_cmd(source, forcefield, circular, ring, delta_lk, time_ns, dt, temperature, friction, integrator, platform, threads,
                 elastic, excluded_volume, electrostatics, salt, pull, torque, rotation_clamp, turns, clamp_first,
                 trap, minimize, outdir, frame_interval, checkpoint_interval, resume, overwrite, seed, export, progress):
    """Simulate SOURCE (a PDB/mmCIF structure, a DNA sequence or a saved model .npz) with the OpenMM engine.

    A structure's longest duplex becomes the model: nodes at its base-pair frames, parameters from
    --forcefield for its sequence.

    Writes OUT/trajectory.dtraj, OUT/energies.csv, OUT/checkpoint.npz, OUT/final_model.npz
    (and OUT/trajectory.pdb + .dcd with --export) and prints a summary.
    """
    from ..units import PN
    from .loads import Clamp, PullingForce, RotationClamp, Torque, Trap
    from .nonbonded import NonbondedSettings
    from .simulation import RodSimulation

    model = load_model(source, forcefield, circular, ring, delta_lk)
    n = model.n_nodes
    axis = model.positions[-1] - model.positions[0]
    if np.linalg.norm(axis) == 0:
        axis = model.frames[0][:, 2]
    axis = axis / np.linalg.norm(axis)
    loads = []
    if clamp_first:
        loads.append(Clamp(0))
    if pull is not None:
        loads.append(PullingForce(n - 1, pull * PN * axis))
        if not clamp_first:
            loads.append(PullingForce(0, -pull * PN * axis))
    if torque is not None:
        loads.append(Torque(n - 1, torque * PN * axis))
    if rotation_clamp is not None:
        loads.append(RotationClamp(n - 1, rotation_clamp, axis=axis))
    for t in trap:
        node, k = _parse_trap(t, n)
        loads.append(Trap(node, k * PN))
    nb = NonbondedSettings(excluded_volume=excluded_volume, electrostatics=electrostatics, salt=salt) \
        if (excluded_volume or electrostatics) else False
    outdir = Path(outdir)
    if resume and dt is None and (outdir / "checkpoint.npz").exists():
        with np.load(outdir / "checkpoint.npz", allow_pickle=False) as z:
            dt = json.loads(str(z["meta"]))["dt"]
    sim = RodSimulation(model, integrator=integrator, temperature=temperature, dt=dt, friction=friction,
                        platform=platform, elastic=elastic, nonbonded=nb, loads=loads, seed=seed, threads=threads)
    click.echo(f"platform: {sim.platform_reason}", err=True)
    if minimize and not resume:
        sim.minimize()
    n_steps = max(1, int(round(time_ns * 1000.0 / sim.dt)))
    turn = None
    if rotation_clamp is not None and turns:
        def turn(s):
            s.set_clamp_rotation(2 * np.pi * turns * s.step / n_steps)
    fi = frame_interval or max(1, int(round(1.0 / sim.dt)))
    summary = sim.run(n_steps, outdir, frame_interval=fi, checkpoint_interval=checkpoint_interval, resume=resume,
                      progress=progress, overwrite=overwrite, on_advance=turn)
    if export:
        from .export import export_trajectory

        export_trajectory(outdir / "trajectory.dtraj", outdir / "trajectory.pdb", outdir / "trajectory.dcd",
                          sequence=model.sequence)
    click.echo(f"nodes: {n}  elastic path: {sim.rs.elastic}  platform: {sim.platform_name}  integrator: {integrator}")
    click.echo(f"dt: {sim.dt * 1000:.2f} fs (omega_max {sim.omega_max:.4g} rad/ps)  steps: {summary['steps']}  "
               f"simulated: {summary['simulated_ps'] / 1000:.4g} ns")
    if sim.rs.nonbonded:
        nb = sim.rs.nonbonded
        click.echo(f"nonbonded: Debye length {nb['debye_length']:.3g} nm, charge {nb['charge']:.3g} e/bp, "
                   f"cutoff {nb['cutoff']:.3g} nm, chain exclusion {nb['n_exclude']} bp")
    click.echo(f"wall: {summary['wall_s']:.1f} s  speed: {summary['ns_per_day']:.4g} ns/day  "
               f"mean kinetic temperature: {summary['mean_temperature']:.1f} K")
    click.echo(f"wrote: {summary['trajectory']}, {summary['energies']}, {summary['final_model']}")
