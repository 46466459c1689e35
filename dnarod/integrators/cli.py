"""``dnarod lax-run``: run the direct Lax-form engine from the command line."""
from __future__ import annotations

from pathlib import Path

import click

from ..inputs import load_model


@click.command("lax-run")
@click.argument("model_or_sequence")
@click.option("--forcefield", "-f", default="dna-default", show_default=True,
              help="Force field for a sequence (or a node count, for uniform sets).")
@click.option("--circular", is_flag=True, help="Periodic chain (screw-closed straight helix) from the sequence.")
@click.option("--ring", is_flag=True, help="Closed planar ring (a minicircle) from the sequence.")
@click.option("--delta-lk", type=int, default=0, show_default=True,
              help="With --ring: linking number relative to the relaxed ring (supercoiling).")
@click.option("--dt", type=float, default=0.05, show_default=True, help="Time step, ps.")
@click.option("--steps", type=int, default=1000, show_default=True, help="Total number of steps.")
@click.option("--temperature", "-T", type=float, default=300.0, show_default=True, help="K.")
@click.option("--friction", type=float, default=1.0, show_default=True,
              help="Langevin collision rate, 1/ps; 0 gives an NVE run from Maxwell velocities.")
@click.option("--seed", type=int, default=None, help="Random seed (velocities and noise).")
@click.option("--out", "-o", type=click.Path(dir_okay=False), required=True, help="Trajectory (.dtraj).")
@click.option("--energies", type=click.Path(dir_okay=False), default=None, help="Energies CSV.")
@click.option("--report-interval", type=int, default=100, show_default=True, help="Steps between frames.")
@click.option("--checkpoint", type=click.Path(dir_okay=False), default=None, help="Checkpoint file (.npz).")
@click.option("--checkpoint-interval", type=int, default=10000, show_default=True)
@click.option("--resume", is_flag=True, help="Continue from --checkpoint.")
@click.option("--exact", "exact_t", type=float, default=None,
              help="Instead of the splitting, integrate the exact strain-space system with DOP853 for this many ps.")
@click.option("--rtol", type=float, default=1e-10, show_default=True, help="DOP853 tolerance (with --exact).")
@click.option("--reference", is_flag=True, help="Use the numpy reference path instead of the numba kernel.")
@click.option("--progress/--no-progress", default=False)
def lax_run(model_or_sequence, forcefield, circular, ring, delta_lk, dt, steps, temperature, friction, seed, out, energies,
            report_interval, checkpoint, checkpoint_interval, resume, exact_t, rtol, reference, progress):
    """Simulate MODEL_OR_SEQUENCE with the Lax-form engine.

    MODEL_OR_SEQUENCE is a PDB/mmCIF structure, a model .npz, a DNA sequence or a node count.

    Default: BAOAB Langevin dynamics with the symplectic splitting; --friction 0 runs NVE.
    """
    from .run import simulate_exact, simulate_langevin, simulate_nve

    model = load_model(model_or_sequence, forcefield, circular, ring, delta_lk)
    if exact_t is not None:
        res = simulate_exact(model, exact_t, temperature=temperature, seed=seed, rtol=rtol, atol=rtol,
                             n_frames=max(2, int(exact_t / (dt * report_interval)) + 1), out=out, energy_csv=energies)
        drift = abs(res.energy[-1] - res.energy[0]) / abs(res.energy[0])
        click.echo(f"exact DOP853 run: {model.n_nodes} nodes, {exact_t:g} ps, {res.nfev} RHS evaluations, "
                   f"relative energy change {drift:.2e}; wrote {out}")
        return
    kw = dict(seed=seed, out=out, report_interval=report_interval, energy_csv=energies, checkpoint=checkpoint,
              checkpoint_interval=checkpoint_interval, resume=resume, fast=not reference, progress=progress)
    if friction > 0:
        res = simulate_langevin(model, dt, steps, temperature, friction, **kw)
    else:
        res = simulate_nve(model, dt, steps, temperature=temperature, **kw)
    e = res.energies
    click.echo(f"{'Langevin' if friction > 0 else 'NVE'} run: {model.n_nodes} nodes, {res.step} steps of {dt:g} ps "
               f"(omega_max {res.omega_max:.4g} rad/ps, dt_crit {2 / res.omega_max:.4g} ps); "
               f"final E = {e[-1, 4]:.6g} kJ/mol, T_kin = {e[-1, 5]:.1f} K; wrote {out}")
