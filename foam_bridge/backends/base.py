"""What every backend shares: envs pinned to workers, batches in parallel, dead workers replaced.

A backend runs ``Request`` s (see ``worker``) on ``pool`` workers; env ``i`` always lives on worker
``i % pool``. ``run`` sends each worker its share of a batch at once, so workers compute in parallel,
then gathers the replies in request order. A worker that dies (or does not answer within the batch
deadline, in which case it is killed) answers every request of the batch with
``Reply(ok=False, worker_died=True, error="worker died")`` and is replaced by a fresh one; its envs
are rebuilt on their next request. The other workers are not touched. ``run`` does not raise for a
worker fault, not even when a replacement cannot be started (the worker then counts as dead again on
the next batch).

Every batch carries a sequence number and its replies carry it back: a batch whose call was
interrupted (Ctrl-C, an exception in the caller between send and receive) leaves its replies in the
worker's channel, and the next batch drops them instead of taking them for its own.
"""

from __future__ import annotations

import contextlib
import os
from abc import ABC, abstractmethod
from typing import Any

from foam_bridge.backends.worker import Reply, Request

WORKER_DIED = "worker died"
# Seconds allowed, on top of the env's own step watchdog, for case generation (blockMesh) and start-up.
RESET_ALLOWANCE_S = 300.0


def validate_pool(num_envs: int, pool: int | None = None) -> int:
    """The pool size: ``pool``, or for None one worker per env up to the CPU count.

    One-line ValueError unless num_envs is a positive integer and 1 <= pool <= num_envs.
    """
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
    if pool is None:
        return min(num_envs, os.cpu_count() or 1)
    if isinstance(pool, bool) or not isinstance(pool, int) or not 1 <= pool <= num_envs:
        raise ValueError(f"pool must be an integer in [1, num_envs={num_envs}], got {pool!r}")
    return pool


def batch_deadline_s(cfg: Any, requests: list[Request]) -> float:
    """Last-resort deadline for one worker's batch: the env's watchdog normally fires long before."""
    step_s = float(getattr(cfg, "step_timeout_s", 120.0))
    return sum(2 * step_s + (RESET_ALLOWANCE_S if r.method == "reset" else 30.0) for r in requests)


def close_deadline_s(cfg: Any, envs: int) -> float:
    """How long ``close`` waits for a worker with ``envs`` envs: long enough for a step it may still be
    running (an interrupted batch) to end by its own watchdog, and for its envs to close."""
    return batch_deadline_s(cfg, [Request(0, "step", {})] * envs) + 30.0


class Backend(ABC):
    """``pool`` workers hosting ``num_envs`` envs; see the module docstring."""

    name = "abstract"

    def __init__(self, cfg: Any, num_envs: int, pool: int) -> None:
        validate_pool(num_envs, pool)
        self.cfg = cfg
        self.num_envs = num_envs
        self.pool = pool
        self._seq = 0

    def worker_of(self, env_id: int) -> int:
        """Index of the worker that hosts env ``env_id``."""
        return env_id % self.pool

    def run(self, requests: list[Request]) -> list[Reply]:
        """Run a batch (at most one request per env is sensible); replies come back in request order."""
        self._seq += 1
        requests = [request._replace(seq=self._seq) for request in requests]
        groups: dict[int, list[int]] = {}
        for position, request in enumerate(requests):
            groups.setdefault(self.worker_of(request.env_id), []).append(position)
        sent = {w: self._send(w, [requests[p] for p in positions]) for w, positions in groups.items()}
        replies: list[Reply | None] = [None] * len(requests)
        for worker, positions in groups.items():
            batch = [requests[p] for p in positions]
            answers = self._receive(worker, batch, sent[worker], batch_deadline_s(self.cfg, batch))
            if answers is None:
                with contextlib.suppress(Exception):  # a failed start shows as a dead worker next time
                    self._replace(worker)
                answers = [Reply(r.env_id, False, error=WORKER_DIED, worker_died=True, seq=r.seq)
                           for r in batch]
            for position, answer in zip(positions, answers, strict=True):
                replies[position] = answer
        return replies  # type: ignore[return-value]

    @abstractmethod
    def _send(self, worker: int, batch: list[Request]) -> Any:
        """Start the batch on the worker; returns a handle for _receive (None if the worker is gone)."""

    @abstractmethod
    def _receive(
        self, worker: int, batch: list[Request], handle: Any, deadline_s: float
    ) -> list[Reply] | None:
        """The worker's replies to ``batch`` (replies of earlier batches, which carry an older ``seq``,
        are dropped), or None if it died or missed the deadline (then it must be dead)."""

    @abstractmethod
    def _replace(self, worker: int) -> None:
        """Start a fresh worker in place of a dead one."""

    @abstractmethod
    def worker_pid(self, env_id: int) -> int:
        """Process id of the worker hosting env ``env_id``."""

    @abstractmethod
    def close(self) -> None:
        """Close every env (their solvers die) and stop the workers. Idempotent."""
