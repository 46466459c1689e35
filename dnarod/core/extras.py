"""Optional dependencies: what an extra provides, and one line naming the extra when it is missing.

The core (models, engines, ``simulate``, ``analyze``, structures) needs only the packages of ``pyproject.toml``'s
``dependencies``; ensembles and protocols on several workers need the ``ensemble`` extra (dask.distributed, pyarrow),
SLURM clusters the ``cluster`` extra (dask-jobqueue). ``pip install 'dnarod[all]'`` installs them all.
"""
from __future__ import annotations

import importlib
from types import ModuleType

from dnarod.core.errors import DnarodError

#: Extra -> what it is for (named in the message).
EXTRAS = {"ensemble": "ensembles and protocols on dask workers (dask.distributed, pyarrow)",
          "cluster": "ensembles on SLURM clusters (dask-jobqueue)"}


class MissingExtraError(DnarodError):
    """An optional dependency is not installed; the message names the extra that provides it."""


def require(module: str, extra: str) -> ModuleType:
    """Import ``module`` or raise :class:`MissingExtraError` naming ``extra``: ``pip install 'dnarod[EXTRA]'``.

    Parameters
    ----------
    module : str
        Importable name (``"distributed"``, ``"pyarrow.parquet"``).
    extra : str
        A key of :data:`EXTRAS`.
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        top = module.split(".")[0]
        raise MissingExtraError(f"{EXTRAS[extra]} need {top}, which is not installed: pip install 'dnarod[{extra}]' "
                                f"(or 'dnarod[all]')") from None
