"""Locate the bundled reference data (standard bases, residue names, fibre templates)."""
from __future__ import annotations

from dnarod.core.errors import StructureError
from dnarod.core.forcefield import data_dir


def data_file(*parts):
    """Path of a file under dnarod's bundled ``data/`` directory.

    Raises
    ------
    StructureError
        If the file is missing (a broken installation).
    """
    p = data_dir().joinpath(*parts)
    if not p.is_file():
        raise StructureError(f"bundled data file {'/'.join(parts)} is missing from {data_dir()}; reinstall dnarod")
    return p
