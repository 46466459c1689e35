"""``dnarod protocol``: force-extension, magnetic-tweezers hat curves, torque-turns and supercoiled rings.

Each subcommand is a thin shell over :func:`dnarod.workflows.protocols.run_protocol`: it runs one member per value
of its axes (dask local workers) and writes ``OUT/curve.csv`` and ``OUT/curve.png``. Bad input exits with
status 2 and one line, before anything runs.
"""
from __future__ import annotations

import math
import re

import click

from dnarod.core.errors import DnarodError
from dnarod.cli.simulate import CHARGE_OPTIONS
from dnarod.workflows.protocols.curves import STARTS, run_protocol
from dnarod.workflows.ensemble.cluster import check_workers
from dnarod.core.io import check_dir_path
from dnarod.physics.nonbonded import nonbonded_options


def _floats(text, what):
    parts = str(text).replace(" ", "").split(",")
    if len(parts) > 1 and "" in parts:
        raise DnarodError(f"{what}: empty entry in {text!r}; give comma-separated numbers such as 0.5,1,2")
    try:
        vals = [float(v) for v in parts if v != ""]
    except ValueError:
        raise DnarodError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if not vals:
        raise DnarodError(f"{what}: give at least one value")
    bad = [v for v in vals if not math.isfinite(v)]
    if bad:
        raise DnarodError(f"{what} {text}: {bad[0]} is not a finite number")
    return vals


#: The settings keys the protocol commands fill from their options (for messages in the options' names).
_OPTION_OF_KEY = {"time_ns": "--time", "equilibration_ns": "--equilibration", "temperature_K": "--temperature",
                  "salt_M": "--salt", "seed": "--seed", "force_pN": "--force", "turns": "--turns",
                  "delta_lk": "--delta-lk", "rotation_clamp_kJ_mol": "--clamp-k", "source": "--source",
                  "forcefield": "--forcefield"}


def _run_protocol(kind, axes, base, out, overwrite=False, **kw):
    """:func:`dnarod.workflows.protocols.curves.run_protocol` (which refuses a folder of other settings unless
    ``overwrite``, any other non-empty folder, and a folder in use), its settings errors named by the command's
    options."""

    try:
        return run_protocol(kind, axes, base, out, overwrite=overwrite, **kw)
    except DnarodError as exc:
        m = re.match(r"\[(base|axes)\] (\w+)(.*)", str(exc), re.S)
        if m and m.group(2) in _OPTION_OF_KEY:
            raise DnarodError(f"{_OPTION_OF_KEY[m.group(2)]} ({m.group(2)}){m.group(3)}") from None
        raise


def _check_run_options(workers, out):
    """Refuse a negative worker count and an output path under a regular file, before anything runs (the
    folder's content is checked by :func:`~dnarod.workflows.protocols.curves.run_protocol`)."""
    check_workers(workers)
    check_dir_path(out, what="output folder")


def _common(f):
    opts = [
        click.option("--source", "-s", default="600", show_default=True,
                     help="Node count (uniform force field) or DNA sequence."),
        click.option("--forcefield", default="dna-default", show_default=True),
        click.option("--time", "time_ns", type=float, default=2.0, show_default=True,
                     help="Production time per member, ns."),
        click.option("--equilibration", "equilibration_ns", type=float, default=None,
                     help="Equilibration per member, ns (default: 5 slowest bending relaxation times)."),
        click.option("--temperature", "temperature_K", type=float, default=300.0, show_default=True, help="K."),
        click.option("--salt", "salt_M", type=float, default=0.15, show_default=True, help="Monovalent salt, mol/L."),
        click.option("--seed", type=int, default=1, show_default=True),
        click.option("--excluded-volume/--no-excluded-volume", default=True, show_default=True,
                     help="WCA excluded volume between nodes far apart along the chain."),
        click.option("--electrostatics/--no-electrostatics", default=True, show_default=True,
                     help="Debye-Hueckel electrostatics (both off: a bare worm-like chain)."),
        *CHARGE_OPTIONS,
        click.option("--workers", type=int, default=2, show_default=True,
                     help="Dask local workers (0: run members one after another in this process)."),
        click.option("--out", "-o", type=click.Path(file_okay=False), required=True,
                     help="Output folder: new, empty or a protocol's (any other non-empty folder is refused); "
                          "locked (OUT/.dnarod.lock) while the protocol runs."),
        click.option("--overwrite", is_flag=True,
                     help="Run into --out although it holds a protocol run with other settings (or another "
                          "protocol); without it that is refused. The same settings reuse the finished members "
                          "(more values extend the curve). A non-empty folder that is not a protocol's is "
                          "always refused."),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def _base(source, forcefield, time_ns, equilibration_ns, temperature_K, salt_M, seed, charge=None, cutoff_debye=None,
          excluded_volume=True, electrostatics=True, **extra):
    b = dict(source=str(source), forcefield=forcefield, time_ns=time_ns, temperature_K=temperature_K, salt_M=salt_M,
             seed=seed, **extra)
    if not excluded_volume:  # only when switched off: a curve recorded with the defaults keeps its settings
        b["excluded_volume"] = False
    if not electrostatics:
        b["electrostatics"] = False
    if equilibration_ns is not None:
        b["equilibration_ns"] = equilibration_ns

    b.update(nonbonded_options(charge, cutoff_debye, salt_M, temperature_K))
    return b


def _report(curve, x, ys):
    for r in curve.rows:
        parts = [f"{x} {r.get(x)}"] + [f"{y} {r.get(y):.4g} +- {r.get(y + '_err') or 0:.2g}" for y in ys
                                      if r.get(y) is not None]
        click.echo("  " + ", ".join(parts))
    click.echo(f"wrote {curve.files.get('csv')} and {curve.files.get('png')}")


@click.group("protocol")
def protocol():
    """Single-molecule protocols: force-extension, hat curves, torque-turns, supercoiled rings."""


@protocol.command("force-extension")
@click.option("--force", "forces", required=True, help="Forces, pN, comma-separated (e.g. 0.1,0.3,1,3,10).")
@click.option("--turns", default=None, help="Refused: the force-extension bead end is torsionally free.")
@_common
def force_extension_cmd(forces, turns, workers, out, overwrite, **kw):
    """Extension vs force with a torsionally free bead end."""
    _check_run_options(workers, out)
    run_protocol = _run_protocol

    if turns not in (None, "", "0"):
        raise DnarodError(f"--turns {turns}: turns need a rotation clamp; the force-extension bead end is "
                          f"torsionally free: use `dnarod protocol hat` or `dnarod protocol torque-turns`")
    c = run_protocol("force_extension", {"force_pN": _floats(forces, "--force")}, _base(**kw), out, workers=workers,
                     overwrite=overwrite)
    _report(c, "force_pN", ["relative_extension"])


def _clamp_options(default_force):
    """The options of the rotation-clamp protocols (force list, turns list, clamp stiffness)."""
    options = [click.option("--force", "forces", default=default_force, show_default=True,
                            help="Force(s), pN, comma-separated."),
               click.option("--turns", required=True, help="Turns, comma-separated (e.g. -6,-4,-2,0,2,4,6)."),
               click.option("--clamp-k", type=float, default=250.0, show_default=True,
                            help="Rotation clamp stiffness, kJ/mol."),
               click.option("--start", "start", type=click.Choice(STARTS),
                            default="static", show_default=True,
                            help="static: every member from the static pose under its loads; exchange: the turn "
                                 "values of each force are the rungs of one replica-exchange ladder (swaps between "
                                 "neighbouring rungs, the turn difference carried as twist), for hat curves past "
                                 "buckling, where a member keeps the state it starts in."),
               click.option("--exchange-ps", "exchange_ps", type=float, default=None,
                            help="With --start exchange: time between exchange attempts, ps (default 20).")]

    def decorate(f):
        for option in reversed(options):
            f = option(f)
        return f

    return decorate


def _run_clamped(kind, forces, turns, clamp_k, workers, out, kw, columns, start="static", overwrite=False,
                 exchange_ps=None):
    """Run a rotation-clamp protocol over forces x turns and print its curve."""
    _check_run_options(workers, out)
    c = _run_protocol(kind, {"force_pN": _floats(forces, "--force"), "turns": _floats(turns, "--turns")},
                      _base(**kw, rotation_clamp_kJ_mol=clamp_k), out, workers=workers, start=start,
                      overwrite=overwrite, exchange_ps=exchange_ps)
    _report(c, "turns", columns)


def _clamped_command(name, kind, clamp_k_default, columns, doc):
    """The ``protocol`` subcommand ``name`` of the rotation-clamp protocol ``kind``: forces x turns, its curve
    printed with ``columns``; ``doc`` is its help."""
    def command(forces, turns, clamp_k, start, exchange_ps, workers, out, overwrite, **kw):
        _run_clamped(kind, forces, turns, clamp_k, workers, out, kw, columns, start, overwrite, exchange_ps)

    command.__doc__ = doc
    return protocol.command(name)(_clamp_options(clamp_k_default)(_common(command)))


hat_cmd = _clamped_command("hat", "magnetic_tweezers", "0.5", ["relative_extension", "Wr", "plectoneme_fraction"],
                           "Magnetic tweezers at constant force: extension vs turns (the hat curve).")
torque_turns_cmd = _clamped_command("torque-turns", "torque_turns", "1.0",
                                    ["twist_torque_pN_nm", "clamp_torque_pN_nm", "relative_extension"],
                                    "Torque on the rotation clamp vs turns at constant force.")


@protocol.command("rings")
@click.option("--delta-lk", required=True, help="Linking differences, comma-separated integers.")
@_common
def rings_cmd(delta_lk, workers, out, overwrite, **kw):
    """Closed rings: Tw, Wr and plectonemes vs linking difference."""
    _check_run_options(workers, out)
    run_protocol = _run_protocol

    vals = _floats(delta_lk, "--delta-lk")
    if any(v != int(v) for v in vals):
        raise DnarodError(f"--delta-lk {delta_lk}: the linking number of a closed ring is an integer")
    c = run_protocol("rings", {"delta_lk": [int(v) for v in vals]}, _base(**kw), out, workers=workers,
                     overwrite=overwrite)
    _report(c, "delta_lk", ["Wr", "Tw", "writhe_fraction", "plectoneme_fraction"])
