"""Validation suite: the two engines against each other and against exact results (``dnarod validate``).

Checks (by name; each module states its system, reference and tolerances):

* ``engines`` -- OpenMM and the Lax-form integrator agree in NVE, converging as dt^2 (:mod:`.engines`);
* ``thermal`` -- Langevin runs of both engines reproduce the exact equilibrium of docs/formulation.md §8
  (:mod:`.thermal_equilibrium`);
* ``dispersion`` -- OpenMM normal modes equal the exact dispersion relation (:mod:`.dispersion`);
* ``helix`` -- the intrinsic helix is a zero-force state in both engines (:mod:`.helix`);
* ``paper_scheme`` -- the printed (3.13) is O(ds) from the exact system and unstable (:mod:`.paper_scheme`);
* ``force_extension`` -- a 1 kbp chain against the extensible WLC (slow; not in ``quick``)
  (:mod:`.force_extension`);
* ``torsion`` -- C_eff(F) of a stretched chain from the torque-turns slope and from twist fluctuations,
  against each other and Moroz & Nelson (:mod:`.torsion`);
* ``plectonemes`` -- the writhe fraction of supercoiled rings at sigma ~ -0.05 against the two-phase relation
  ``1 - P/C`` (:mod:`.plectonemes`);
* ``nicked_ring`` -- ``<ΔLk²>`` of nicked rings (exact twist part, model writhe vs a worm-like-ring Monte Carlo
  with the model's A and effective diameter) and the free-energy coefficient K (:mod:`.nicked_ring`);
* ``experiment`` -- the model's persistence length and effective torsional stiffness against measured DNA
  values (``data/experimental/``; exact, no simulation), its effective diameter against the computed
  Poisson-Boltzmann reference its Debye-Hückel charge is calibrated to (gating), and -- when ``plectonemes``
  ran before it -- the ring's writhe fraction against the value read (:mod:`.experiment`).

:func:`run_validation` runs a selection and writes ``report.md``, PNG plots and ``results.json``
(``{"checks": {NAME: {"passed": bool, ...}}}``) to a folder.
"""
from __future__ import annotations

import importlib
import time
import traceback
from pathlib import Path

from dnarod.core.errors import DnarodError

#: name -> (module, function)
CHECKS = {
    "engines": ("engines", "check_engines"),
    "thermal": ("thermal_equilibrium", "check_thermal"),
    "dispersion": ("dispersion", "check_dispersion"),
    "helix": ("helix", "check_helix"),
    "paper_scheme": ("paper_scheme", "check_paper_scheme"),
    "force_extension": ("force_extension", "check_force_extension"),
    "torsion": ("torsion", "check_torsion"),
    "plectonemes": ("plectonemes", "check_plectonemes"),
    "nicked_ring": ("nicked_ring", "check_nicked_ring"),
    "experiment": ("experiment", "check_experiment"),
}
#: Checks of ``--quick`` (everything but the slow force-extension runs).
QUICK_CHECKS = ("engines", "thermal", "dispersion", "helix", "paper_scheme", "torsion", "experiment")


def check_function(name):
    """The function that runs check ``name`` (signature ``f(out_dir, quick=False, **options) -> dict``)."""
    if name not in CHECKS:
        raise DnarodError(f"unknown validation check {name!r}; available: {', '.join(CHECKS)}")
    mod, fn = CHECKS[name]
    return getattr(importlib.import_module(f"{__name__}.{mod}"), fn)


def run_validation(out_dir, quick=False, checks=None, options=None, echo=None, overwrite=False):
    """Run validation checks and write the report folder.

    A folder that already holds a report is refused unless ``overwrite``, before any check runs; with it the
    report (``report.md``, ``results.json``) is replaced when the new one is written and the plots the old
    report listed but the new one does not are removed. Any other non-empty folder is refused
    (:func:`dnarod.core.io.check_output_folder`), and while the checks run the folder is locked against a second
    writer (:func:`dnarod.core.io.folder_lock`).

    Parameters
    ----------
    out_dir : str or Path
        Report folder (created): ``report.md``, ``results.json``, PNG plots.
    quick : bool
        Short runs; without ``checks`` only :data:`QUICK_CHECKS`.
    checks : sequence of str, optional
        Names to run (default: all, or the quick subset).
    options : dict, optional
        ``{name: {keyword: value}}`` passed to the check functions (used by the tests to shrink runs
        or to feed deliberately wrong references).
    echo : callable, optional
        Called with a one-line progress message before and after each check.
    overwrite : bool
        Replace a report already in ``out_dir``.

    Returns
    -------
    dict
        ``{"checks": {name: {"passed": bool, ...}}}`` -- exactly what ``results.json`` holds. A check
        that raises is recorded as failed with its error message and traceback.

    Raises
    ------
    DnarodError
        An unknown check, a folder holding a report (without ``overwrite``) or anything else, a folder in use.
    """
    from dnarod.core.io import check_output_folder, folder_lock, staged_folder
    from dnarod.validate.report import REPORT_FILES, old_report

    out_dir = Path(out_dir)
    names = list(checks) if checks else list(QUICK_CHECKS if quick else CHECKS)
    for n in names:
        check_function(n)  # validate names before running anything
    check_output_folder(out_dir, REPORT_FILES, "validation report", what="report folder")
    _refuse_old_report(out_dir, overwrite)
    with folder_lock(out_dir, what="report folder"):
        _refuse_old_report(out_dir, overwrite)  # again: another process may have finished a report here since
        # the earlier report's own plots, by name only (removed when the new report has no plot of that name)
        old_plots = [p for p in old_report(out_dir)[1] if Path(p).name == p and p.endswith(".png")]
        # the report is made beside the old one (a hidden folder in out_dir) and put in place when complete: an
        # interrupted or failed validation leaves the earlier report as it was
        options = {k: dict(v) for k, v in (options or {}).items()}
        with staged_folder(out_dir, (*REPORT_FILES, *old_plots), what="validation report") as stage:
            results = _run_checks(stage, names, quick, options, echo)
        return results


def _refuse_old_report(out_dir, overwrite):
    from dnarod.validate.report import old_report

    present = old_report(out_dir)[0]
    if present and not overwrite:
        raise DnarodError(f"{out_dir} already holds a validation report ({present}); pass --overwrite to replace it, "
                          f"or choose another folder with -o")


def _run_checks(out_dir, names, quick, options, echo):
    """Run the checks ``names`` into ``out_dir`` and write the report (see :func:`run_validation`)."""
    from dnarod.validate.report import write_report

    options = options or {}
    results = {"checks": {}}
    t0 = time.perf_counter()
    for n in names:
        if echo:
            echo(f"running {n} ...")
        tc = time.perf_counter()
        kw = dict(options.get(n, {}))
        prev = results["checks"].get("plectonemes", {})
        if n == "experiment" and "writhe_fraction_model" not in kw and "model_writhe_fraction" in prev:
            # the model's measured writhe fraction, compared with the measured one by check experiment
            kw["writhe_fraction_model"] = (prev["model_writhe_fraction"], prev["model_writhe_fraction_err"],
                                           f"check plectonemes: {prev.get('model', '')}")
        try:
            r = check_function(n)(out_dir, quick=quick, **kw)
        except Exception as exc:  # noqa: BLE001 - a crashing check is a failed check, reported
            r = {"passed": False, "error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()}
        r["runtime_s"] = time.perf_counter() - tc
        results["checks"][n] = r
        if echo:
            echo(f"  {n}: {'passed' if r['passed'] else 'FAILED'} ({r['runtime_s']:.1f} s)")
    total = time.perf_counter() - t0
    return write_report(out_dir, results, quick=quick, runtime_s=total)
