"""Statistics of correlated samples in one home: blocks, the block jackknife."""
from __future__ import annotations

import numpy as np


def jackknife(estimator, blocks):
    """Block-jackknife estimate and standard error.

    Parameters
    ----------
    estimator : callable
        Maps a list of per-block summaries (each whatever ``blocks`` holds) to an estimate (array).
    blocks : list
        One summary per block of consecutive frames (time blocks longer than the correlation time).

    Returns
    -------
    estimate, standard_error : ndarray
        Estimate from all blocks, and the jackknife standard error over the blocks.
    """
    nb = len(blocks)
    full = np.asarray(estimator(blocks), float)
    loo = np.array([np.asarray(estimator(blocks[:i] + blocks[i + 1:]), float) for i in range(nb)])
    se = np.sqrt((nb - 1) / nb * np.sum((loo - loo.mean(axis=0)) ** 2, axis=0))
    return full, se


def split_blocks(arrays, n_blocks):
    """Split arrays (same leading length, the frames) into ``n_blocks`` consecutive blocks.

    Returns a list of tuples, one per block, of the arrays' slices.
    """
    n = len(arrays[0])
    edges = np.linspace(0, n, n_blocks + 1).astype(int)
    return [tuple(a[edges[i]:edges[i + 1]] for a in arrays) for i in range(n_blocks)]
