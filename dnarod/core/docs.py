"""Shared numpydoc fragments: one wording of the parameters that many functions take.

A docstring names a fragment as ``%(name)s`` on a line of its own; :func:`fill_doc` puts the fragment there at
import time, indented as that line is, so ``help()``, Sphinx and numpydoc read the full text (the same
substitution scheme as matplotlib's and scipy's docstring helpers).
"""
from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any, TypeVar, overload

T = TypeVar("T")

#: A pose of the chain, as the engines, loads and exports take it.
POSE = """\
positions : ndarray, shape (n_nodes, 3)
    Node centres, nm.
frames : ndarray, shape (n_nodes, 3, 3)
    Directors as columns."""

#: The shared fragments by placeholder name.
FRAGMENTS = {"pose": POSE}

_PLACEHOLDER = re.compile(r"^([ \t]*)%\((\w+)\)s[ \t]*$", re.MULTILINE)


@overload
def fill_doc(obj: T) -> T: ...


@overload
def fill_doc(obj: None = None, **fragments: str) -> Callable[[T], T]: ...


def fill_doc(obj: Any = None, **fragments: str) -> Any:
    """Put the shared fragments (:data:`dnarod.core.docs.FRAGMENTS`, and any given as keywords) into ``obj.__doc__``.

    Used as a decorator, bare (``@fill_doc``) or with module-local fragments (``@fill_doc(name=text)``).

    Raises
    ------
    KeyError
        For a placeholder that names no fragment (a typo shows at import).
    """
    table = {**FRAGMENTS, **fragments}

    def fill(target: Any) -> Any:
        if target.__doc__:
            target.__doc__ = _PLACEHOLDER.sub(
                lambda m: "\n".join(m.group(1) + line if line else line
                                    for line in table[m.group(2)].splitlines()), target.__doc__)
        return target

    return fill if obj is None else fill(obj)
