"""Input checks shared by dnarod.physics.lax: every failure names the argument and says what to do."""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError

READINGS = ("R1", "midpoint")

#: Docstring fragments (:func:`dnarod.core.docs.fill_doc`) of the parameters checked here.
LAM_DOC = """\
lam : float
    Real spectral parameter."""
LAM_DS_DOC = LAM_DOC + """
ds : float
    Step length (nm), > 0."""


def as_field(name, value, n=None, allow_complex=False):
    """Return ``value`` as a float (or complex) array of shape (n, 3); raise DnarodError naming it."""
    try:
        arr = np.asarray(value, dtype=complex if allow_complex and np.iscomplexobj(value) else float)
    except (TypeError, ValueError) as exc:
        raise DnarodError(f"{name}: cannot convert to a numeric array ({exc}); pass an (n, 3) array") from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise DnarodError(f"{name}: expected shape (n_nodes, 3), got {arr.shape}; pass one 3-vector per node")
    if arr.shape[0] == 0:
        raise DnarodError(f"{name}: has no nodes; pass at least one node")
    if n is not None and arr.shape[0] != n:
        raise DnarodError(
            f"{name}: has {arr.shape[0]} nodes but the first field has {n}; all fields need the same node count")
    bad = ~np.isfinite(arr)
    if bad.any():
        node = int(np.argwhere(bad)[0][0])
        raise DnarodError(f"{name}: non-finite value at node {node}; fix the input (NaN or inf)")
    return arr


def as_fields(names, values, allow_complex=False):
    """Check several (n, 3) fields with a common node count; return a list of arrays."""
    out = []
    n = None
    for name, value in zip(names, values):
        arr = as_field(name, value, n, allow_complex=allow_complex)
        n = arr.shape[0]
        out.append(arr)
    return out


def as_ds(ds):
    """Return ds as a positive finite float or raise DnarodError."""
    try:
        ds = float(ds)
    except (TypeError, ValueError):
        raise DnarodError(f"ds: expected a positive number (nm), got {ds!r}") from None
    if not np.isfinite(ds) or ds <= 0.0:
        raise DnarodError(f"ds: must be positive and finite (the step length, nm), got {ds!r}")
    return ds


def as_lambda(lam, name="lam", allow_complex=False):
    """Return the spectral parameter as a finite real (or complex) number."""
    if allow_complex and np.iscomplexobj(lam):
        val = complex(lam)
        ok = np.isfinite(val.real) and np.isfinite(val.imag)
    else:
        try:
            val = float(lam)
        except (TypeError, ValueError):
            raise DnarodError(f"{name}: expected a real number, got {lam!r}") from None
        ok = np.isfinite(val)
    if not ok:
        raise DnarodError(f"{name}: must be finite, got {lam!r}")
    return val


def as_reading(reading):
    if reading not in READINGS:
        raise DnarodError(f"reading: expected one of {READINGS}, got {reading!r}")
    return reading


def shift_next(x, periodic):
    """Field at node k+1 for every node k: wraps when periodic, else the last row is zero."""
    nxt = np.roll(x, -1, axis=0)
    if not periodic:
        nxt[-1] = 0.0
    return nxt
