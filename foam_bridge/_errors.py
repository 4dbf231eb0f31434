"""Exceptions of foam_bridge. Bad input is a ``ValueError`` (one line naming the problem)."""

from __future__ import annotations

__all__ = ["CaseError", "ClusterError", "NoResidualControl", "OpenFOAMNotFoundError", "PoolLostError",
           "SolverFailure"]


class OpenFOAMNotFoundError(RuntimeError):
    """OpenFOAM's binaries (simpleFoam, blockMesh) are not on the configured PATH."""


class CaseError(ValueError):
    """A case directory is unusable (missing file, unknown patch or field, unreadable dictionary)."""


class NoResidualControl(CaseError):
    """A case whose SIMPLE has no residualControl, when its criterion is wanted (``where``: its fvSolution).
    Its own class so that each command can name its own way to give a criterion."""

    def __init__(self, message: str, where: object) -> None:
        super().__init__(message)
        self.where = where


class SolverFailure(RuntimeError):
    """The solver failed during an episode. Caught inside the env and turned into an outcome.

    ``outcome`` is one of "crashed", "diverged", "hung"; the message is the recorded cause.
    """

    def __init__(self, outcome: str, cause: str) -> None:
        super().__init__(cause)
        self.outcome = outcome
        self.cause = cause


class ClusterError(ValueError):
    """A Ray cluster that cannot be reached, or that cannot host the pool's workers."""


class PoolLostError(RuntimeError):
    """Every worker of a pool is lost (e.g. every node of a Ray cluster died) and none can be started."""
