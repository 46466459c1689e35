"""Per-frame step parameters (3DNA) and Cayley strains of every step of a trajectory.

Strains come from :func:`dnarod.core.strains.strains` (the one strain computation of dnarod) and
step parameters from :func:`dnarod.core.stepparams.step_parameters`, vectorised over frames and
steps at once.

Units: strains Omega in 1/nm, Gamma dimensionless; step parameters nm and rad inside, the
CSV table in Angstrom and degrees (the field's units).
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError, GeometryError
from dnarod.core.forcefield import sequence_steps
from dnarod.core.io import atomic_path
from dnarod.core.stepparams import STEP_PARAMETER_NAMES, step_parameters, to_angstrom_degrees
from dnarod.core.strains import step_ends, strains
from dnarod.analysis.base import AnalysisBase, check_closed, closure_of

STRAIN_COLUMNS = ("Omega1_per_nm", "Omega2_per_nm", "Omega3_per_nm", "Gamma1", "Gamma2", "Gamma3")
STEP_COLUMNS = ("shift_A", "slide_A", "rise_A", "tilt_deg", "roll_deg", "twist_deg")


def frame_strains(positions, frames, ds, closure=None):
    """Strains of every step in every frame.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_nodes, 3)
        nm.
    frames : ndarray, shape (n_frames, n_nodes, 3, 3)
    ds : float
        nm.
    closure : Closure or None

    Returns
    -------
    Omega : ndarray, shape (n_frames, n_steps, 3)
        1/nm.
    Gamma : ndarray, shape (n_frames, n_steps, 3)
    """
    try:
        return strains(positions, frames, ds, closure)
    except GeometryError:
        for f in range(positions.shape[0]):  # name the frame of the bad step
            try:
                strains(positions[f], frames[f], ds, closure)
            except GeometryError as exc:
                raise GeometryError(f"trajectory frame {f}: {exc}") from None
        raise


def frame_step_parameters(positions, frames, closure=None):
    """3DNA step parameters of every step in every frame; shape (n_frames, n_steps, 6), nm and rad."""
    r0, L0, r1, L1 = step_ends(positions, frames, closure)
    return step_parameters(L0, r0, L1, r1)


def step_names(n_steps, sequence=None, circular=False):
    """Step-type labels: dinucleotides of ``sequence`` (strand I, 5'->3') or ``"*"`` for every step."""
    if sequence is None:
        return ["*"] * n_steps
    names = sequence_steps(sequence, circular)
    if len(names) != n_steps:
        raise DnarodError(f"sequence {sequence!r} gives {len(names)} steps but the trajectory has {n_steps} "
                          f"({'circular' if circular else 'open'} chain): sequence and trajectory do not match")
    return names


class StepAnalysis(AnalysisBase):
    """Step parameters and strains of every step of every selected frame.

    Parameters
    ----------
    trajectory : Trajectory
    ds : float
        Reference arc length per step (nm) of the strain map.
    sequence : str, optional
        Strand I, 5'->3', one letter per node (labels steps by dinucleotide).
    circular : bool
        Treat the chain as closed (the last step joins the last node to node 0, through
        ``closure``, identity by default).
    closure : Closure, optional
    check_spacing : bool

    Results
    -------
    step_parameters : ndarray (n_frames, n_steps, 6)
        shift, slide, rise (nm); tilt, roll, twist (rad).
    Omega, Gamma : ndarray (n_frames, n_steps, 3)
        Strains (1/nm; dimensionless).
    names : list of str
        Step type of each step.
    mean_step_parameters, std_step_parameters : ndarray (n_steps, 6)
        Over frames.
    """

    def __init__(self, trajectory, ds, sequence=None, circular=False, closure=None, check_spacing=True):
        super().__init__(trajectory, check_spacing=check_spacing)
        if not (np.isfinite(ds) and ds > 0):
            raise DnarodError(f"ds must be a positive length (nm), got {ds}")
        self.ds = float(ds)
        self.closure = closure_of(circular, closure)
        n_steps = trajectory.n_nodes if self.closure is not None else trajectory.n_nodes - 1
        self.names = step_names(n_steps, sequence, self.closure is not None)

    def _compute(self, positions, frames, time):
        if self.closure is not None:
            check_closed(positions, self.closure)
        r = self.results
        r.step_parameters = frame_step_parameters(positions, frames, self.closure)
        r.Omega, r.Gamma = frame_strains(positions, frames, self.ds, self.closure)
        r.names = list(self.names)
        r.time = np.asarray(time)
        r.mean_step_parameters = r.step_parameters.mean(axis=0)
        r.std_step_parameters = r.step_parameters.std(axis=0)

    def write_csv(self, path):
        """Write the per-frame, per-step table (long format; Angstrom, degrees, 1/nm) atomically.

        Columns: ``frame, time_ps, step, step_type``, the six step parameters
        (``shift_A ... twist_deg``) and the six strains (``Omega1_per_nm ... Gamma3``).
        """
        r = self.results
        if "Omega" not in r:
            raise DnarodError("run() the analysis before writing its table")
        nf, m = r.Omega.shape[:2]
        p = to_angstrom_degrees(r.step_parameters).reshape(nf * m, 6)
        xi = np.concatenate([r.Omega, r.Gamma], axis=-1).reshape(nf * m, 6)
        frame = np.repeat(self.frame_indices, m)
        time = np.repeat(r.time, m)
        step = np.tile(np.arange(1, m + 1), nf)  # numbered from 1, as `dnarod steps` numbers them
        names = np.tile(np.array(self.names, dtype=object), nf)
        cols = ["frame", "time_ps", "step", "step_type", *STEP_COLUMNS, *STRAIN_COLUMNS]
        nums = np.concatenate([p, xi], axis=1)
        with atomic_path(path) as tmp, open(tmp, "w") as fh:
            fh.write(",".join(cols) + "\n")
            for i in range(nf * m):
                fh.write(f"{frame[i]},{time[i]:.6g},{step[i]},{names[i]},"
                         + ",".join(f"{v:.8g}" for v in nums[i]) + "\n")

    def summary_rows(self):
        """Per-step mean and standard deviation over frames, Angstrom and degrees: list of dicts."""
        r = self.results
        mean = to_angstrom_degrees(r.mean_step_parameters)
        std = to_angstrom_degrees(r.std_step_parameters)
        rows = []
        for k, name in enumerate(self.names):
            row = {"step": k + 1, "step_type": name}
            for j, col in enumerate(STEP_COLUMNS):
                row[col] = float(mean[k, j])
                row[col + "_std"] = float(std[k, j])
            rows.append(row)
        return rows


__all__ = ["StepAnalysis", "frame_strains", "frame_step_parameters", "step_names",
           "STEP_PARAMETER_NAMES"]
