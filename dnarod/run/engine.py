"""The engine protocol of the run layer: what :func:`dnarod.run.run_engine` drives.

An engine is any object with these members (duck-typed, like OpenMM's reporters; :class:`Engine` states them
as a :class:`typing.Protocol` for type checkers). Engines never import the run layer: the run layer builds
them (:func:`dnarod.run.api.make_engine`) and feeds their state to its reporters.

* :class:`dnarod.engines.openmm.simulation.RodSimulation`: the OpenMM engine.
* :class:`dnarod.engines.lax.engine.LaxEngine`: the direct Lax-form splitting integrator.

:class:`BatchReportingEngine` adds the optional batched reports the run loop uses where an engine offers them.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from dnarod.core.model import RodModel


@runtime_checkable
class Engine(Protocol):
    """An engine the run layer can drive.

    Attributes
    ----------
    name : str
        ``"openmm"`` or ``"lax"`` (recorded in run files).
    model : RodModel
        The model it was built from (parameters, masses, closure).
    dt : float
        Time step, ps.
    step : int
        Steps done since the start of the run (restored by :meth:`load_checkpoint`).
    omega_max : float or None
        Fastest normal mode of the start pose, rad/ps.
    """

    name: str
    model: RodModel
    dt: float

    @property
    def omega_max(self) -> float | None: ...

    @property
    def step(self) -> int: ...

    def advance(self, n_steps: int) -> None:
        """Integrate ``n_steps`` steps; raise :class:`~dnarod.core.errors.SimulationError` naming the step, node
        and term on a blow-up."""

    def node_state(self, *, copy: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """On-step ``(positions (n, 3) nm, frames (n, 3, 3), velocities (n, 3) nm/ps lab, angular velocities
        (n, 3) rad/ps body)``; ``copy=False`` may return the engine's own arrays or read-only views, valid until
        it advances (the run layer's reports read each state once, so they need no copies)."""

    def energies(self) -> dict[str, float]:
        """kJ/mol: ``potential``, ``kinetic``, ``elastic``, ``nonbonded``, ``external``; K: ``temperature``."""

    def save_checkpoint(self, path: str | Path, *, extra: dict[str, Any] | None = None) -> None:
        """Write, atomically, everything needed to continue bit for bit."""

    def load_checkpoint(self, path: str | Path) -> dict[str, Any]:
        """Restore a checkpoint; a foreign or corrupt file raises :class:`~dnarod.core.errors.ParameterError`."""

    def current_model(self) -> RodModel:
        """The model at the current pose."""


@runtime_checkable
class BatchReportingEngine(Engine, Protocol):
    """An engine that can also read several reports in one call (optional; the OpenMM engine on the compiled
    path). The run loop uses it when :meth:`supports_report_batches` is true and every reporter takes batches
    (``supports_batch``); the result is the same, bit for bit, as advancing and reporting one report at a time.
    """

    #: Most reports one :meth:`advance_reports` call returns.
    MAX_BATCH_REPORTS: int

    def supports_report_batches(self) -> bool:
        """True if :meth:`advance_reports` can be used now."""

    def advance_reports(self, n_reports: int, interval: int, duration_ps: float | None = None
                        ) -> tuple[np.ndarray, tuple[np.ndarray, ...], dict[str, np.ndarray], Exception | None]:
        """Advance up to ``n_reports`` times ``interval`` steps, reading a report after each: ``(steps (k,), state
        (arrays with a leading axis k, as :meth:`node_state`), energies (dict of (k,) arrays, as :meth:`energies`),
        error)``, where ``error`` is a blow-up after the last good report (raised by the caller once the good
        reports are written) or None."""

