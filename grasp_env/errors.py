"""Project exceptions: bad input raises ValueError subclasses; solver failures carry a status."""

from __future__ import annotations


class SceneError(ValueError):
    """A scene description is invalid; the message names the field and the value."""


class ComputationError(RuntimeError):
    """A computation could not be completed: a solve failed (:class:`SolverError`) or a move
    could not be followed (:class:`SimulationError`)."""


class SolverError(ComputationError):
    """An LP or Newton solve failed; ``status`` says how (e.g. ``"infeasible"``)."""

    def __init__(self, message: str, status: str) -> None:
        super().__init__(f"{message} (status: {status})")
        self.status = status


class SimulationError(ComputationError):
    """The simulator could not continue (a solve failed even on the fallbacks)."""


class WorkLimitError(SimulationError):
    """A move needed more work than its budget (``max_solves`` pose solves, ``max_iterations``
    increments, or a stall without progress): it cannot be followed in bounded time.
    Deterministic, so it is not retried."""
