"""What every backend shares: envs pinned to workers, batches in parallel, dead workers replaced.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

A backend runs ``Request`` s (see ``worker``) on ``pool`` workers; env ``i`` always lives on worker
``i % pool`` (until a worker is lost, see below). ``run`` sends each worker its share of a batch at
once, so workers compute in parallel, then gathers the replies in request order. A worker that dies
(or does not answer within the batch deadline, in which case it is killed) answers every request of
the batch with ``Reply(ok=False, worker_died=True, error=cause)`` (cause "worker died", or for a Ray
actor whose node died "node lost: ...") and is replaced by a fresh one; its envs are rebuilt on their
next request. The other workers are not touched. An env of the dead worker that had no request in
the answered batches (its result was waiting with the caller) lost its running episode all the same:
it is kept in ``stranded`` (env -> cause), so that the batch ends that episode with the worker's
cause at its next step instead of stepping a fresh env that has none. A replacement that cannot be
started for lack of room (``NoRoomError``: a cluster that lost a node) loses the worker for good: its
envs move to the surviving workers (the fewest envs first), the pool goes on smaller, and the loss is
logged (one warning line) and kept in ``lost``. ``run`` does not raise for a worker fault, except
``PoolLostError`` when no worker is left at all; a replacement that fails otherwise counts as a dead
worker again on the next batch.

Every batch carries a sequence number and its replies carry it back: a batch whose call was
interrupted (Ctrl-C, an exception in the caller between send and receive) leaves its replies in the
worker's channel, and the next batch drops them instead of taking them for its own.

Asynchronous use (foam_bridge._async_batch): ``submit(requests)`` sends each request to its worker as a
batch of its own, without waiting, queued behind the batches the worker has not answered yet;
``collect(timeout_s)`` returns the replies of whichever batches are done (at once, or after waiting up
to ``timeout_s`` for the first). A worker's queued batches are answered in order; its deadline runs
from when its oldest batch reached the head of its queue. A dead or hung worker answers all its queued
batches as in ``run`` and is replaced (or lost) the same way. ``run`` must not be called while
submitted batches are unanswered.
"""

from __future__ import annotations

import logging
import os
import socket
import time
from abc import ABC, abstractmethod
from collections import deque
from typing import Any

from foam_bridge._backends.worker import Reply, Request
from foam_bridge._errors import PoolLostError

__all__ = ["CLOSE_GRACE_S", "RESET_ALLOWANCE_S", "WORKER_DIED", "Backend", "NoRoomError",
           "start_deadline_s", "validate_pool"]

WORKER_DIED = "worker died"
log = logging.getLogger("foam_bridge")
# Seconds allowed, on top of the env's own step watchdog, for case generation (blockMesh) and start-up.
RESET_ALLOWANCE_S = 300.0
#: How long ``close`` lets an idle worker close its envs before killing it. Closing kills each env's
#: solver first (milliseconds), so this bounds only the removal of case directories; a busy worker
#: (``Backend.busy``) is never waited for: its step could take many minutes on a big mesh.
CLOSE_GRACE_S = 30.0


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


def _batch_deadline_s(cfg: Any, requests: list[Request]) -> float:
    """Last-resort deadline for one worker's batch: the env's watchdog normally fires long before. A
    ``cfg`` whose requests are whole jobs of many steps (jaxsimrl solve's campaigns: a request solves a
    case) gives its own ``request_timeout_s`` per request; ``step_timeout_s`` still bounds a worker's
    start."""
    per_request = getattr(cfg, "request_timeout_s", None)
    if per_request is not None:
        return float(per_request) * len(requests)
    step_s = float(getattr(cfg, "step_timeout_s", 120.0))
    return sum(2 * step_s + (RESET_ALLOWANCE_S if r.method == "reset" else 30.0) for r in requests)


def start_deadline_s(cfg: Any) -> float:
    """How long starting a worker may take (a Ray actor waits for a free CPU): the step watchdog, so
    losing capacity is noticed within the watchdog's time; at least 30 s for a slow process start."""
    return max(float(getattr(cfg, "step_timeout_s", 120.0)), 30.0)


class NoRoomError(RuntimeError):
    """A worker cannot be started because the pool has nowhere to run it (see the module docstring)."""


class Backend(ABC):
    """``pool`` workers hosting ``num_envs`` envs; see the module docstring."""

    name = "abstract"

    def __init__(self, cfg: Any, num_envs: int, pool: int) -> None:
        validate_pool(num_envs, pool)
        self.cfg = cfg
        self.num_envs = num_envs
        self.pool = pool
        self._seq = 0
        self._home = [env_id % pool for env_id in range(num_envs)]  # env -> worker
        # submitted batches per worker, oldest first: (batch, handle); and when the oldest became the head
        self._queues: dict[int, deque[tuple[list[Request], Any]]] = {}
        self._head_since: dict[int, float] = {}
        #: One line per worker lost for good (its envs moved to the others).
        self.lost: list[str] = []
        #: env -> why its episode went with a dead worker that had no request of it (module docstring).
        self.stranded: dict[int, str] = {}
        # workers sent a batch by ``run`` whose replies were not read (``run`` was interrupted there)
        self._running: set[int] = set()

    def worker_of(self, env_id: int) -> int:
        """Index of the worker that hosts env ``env_id``."""
        return self._home[env_id]

    def envs_of(self, worker: int) -> list[int]:
        """The envs worker ``worker`` hosts (none once it is lost)."""
        return [env_id for env_id, home in enumerate(self._home) if home == worker]

    def workers(self) -> int:
        """How many workers the pool has now (``pool`` less the lost ones)."""
        return len(set(self._home))

    def node_of(self, env_id: int) -> str:
        """Where env ``env_id`` runs now, as episodes.csv records it (this machine's host name)."""
        return socket.gethostname()

    def run(self, requests: list[Request]) -> list[Reply]:
        """Run a batch (at most one request per env is sensible); replies come back in request order."""
        self._seq += 1
        requests = [request._replace(seq=self._seq) for request in requests]
        groups: dict[int, list[int]] = {}
        for position, request in enumerate(requests):
            groups.setdefault(self.worker_of(request.env_id), []).append(position)
        sent = {w: self._send(w, [requests[p] for p in positions]) for w, positions in groups.items()}
        self._running.update(groups)
        replies: list[Reply | None] = [None] * len(requests)
        for worker, positions in groups.items():
            batch = [requests[p] for p in positions]
            answers = self._receive(worker, batch, sent[worker], _batch_deadline_s(self.cfg, batch))
            self._running.discard(worker)
            if answers is None:
                answers = self._died(worker, batch)
            for position, answer in zip(positions, answers, strict=True):
                replies[position] = answer
        return replies  # type: ignore[return-value]

    # ----- asynchronous use (see the module docstring) ------------------------------------------
    def submit(self, requests: list[Request]) -> None:
        """Send each request to its worker as a batch of its own, without waiting for the replies: each
        comes back as soon as it is done, not when the worker's other requests are."""
        for request in requests:
            self._seq += 1
            worker, batch = self.worker_of(request.env_id), [request._replace(seq=self._seq)]
            queue = self._queues.setdefault(worker, deque())
            if not queue:
                self._head_since[worker] = time.monotonic()
            queue.append((batch, self._send(worker, batch)))

    def busy(self) -> set[int]:
        """The workers that may be running a request now: sent a batch whose replies were not read
        (``run`` interrupted, or submitted and not collected). ``close`` kills these at once."""
        return self._running | {worker for worker, queue in self._queues.items() if queue}

    def _forget_busy(self) -> set[int]:
        """For ``close``: the busy workers (:meth:`busy`), whose batches are then forgotten (their replies
        will never be read)."""
        busy = self.busy()
        self._queues.clear()
        self._running.clear()
        return busy

    def pending(self) -> int:
        """Submitted batches not collected yet."""
        return sum(len(queue) for queue in self._queues.values())

    def collect(self, timeout_s: float) -> list[Reply]:
        """The replies of the submitted batches that are done, waiting up to ``timeout_s`` for one."""
        busy = [worker for worker, queue in self._queues.items() if queue]
        if not busy:
            return []
        due = min(self._head_deadline(worker) for worker in busy)
        ready = set(self._wait_ready(busy, max(min(timeout_s, due - time.monotonic()), 0.0)))
        replies: list[Reply] = []
        for worker in busy:
            if worker in ready or self._head_deadline(worker) <= time.monotonic():
                replies += self._collect_head(worker)
        return replies

    def _head_deadline(self, worker: int) -> float:
        return self._head_since[worker] + _batch_deadline_s(self.cfg, self._queues[worker][0][0])

    def _collect_head(self, worker: int) -> list[Reply]:
        """The replies to ``worker``'s oldest batch; if it died, to all its batches (then it is replaced)."""
        queue = self._queues[worker]
        batch, handle = queue[0]
        left = max(self._head_deadline(worker) - time.monotonic(), 0.0)
        answers = self._receive(worker, batch, handle, left)
        if answers is not None:
            queue.popleft()
            self._head_since[worker] = time.monotonic()
            return answers
        lost = [request for batch, _ in queue for request in batch]
        queue.clear()
        return self._died(worker, lost)

    def _wait_ready(self, workers: list[int], timeout_s: float) -> list[int]:
        """Which of ``workers`` have an answer (or died) for their oldest submitted batch, waiting up
        to ``timeout_s`` for one. The default waits on none: each is then read with its deadline."""
        return workers

    def _died(self, worker: int, unanswered: list[Request]) -> list[Reply]:
        """``worker`` died (or hung) with ``unanswered`` in its hands: mark its other envs stranded (their
        episodes died with it too), replace or lose it, and answer each request with the cause."""
        cause = self._death_cause(worker)
        answered = {request.env_id for request in unanswered}
        for env_id in self.envs_of(worker):
            if env_id not in answered:
                self.stranded[env_id] = cause
        self._recover(worker, cause)
        return [Reply(r.env_id, False, error=cause, worker_died=True, seq=r.seq) for r in unanswered]

    def _recover(self, worker: int, cause: str) -> None:
        """Replace a dead worker; without room for one, lose it and move its envs to the others."""
        try:
            self._replace(worker)
        except NoRoomError as err:
            self._drop(worker, f"{cause}; {err}")
        except Exception:  # noqa: BLE001 - a failed start shows as a dead worker next time
            pass

    def _drop(self, worker: int, why: str) -> None:
        """Lose ``worker`` for good: its envs go to the surviving workers with the fewest envs."""
        moved = self.envs_of(worker)
        survivors = sorted(set(self._home) - {worker})
        if not survivors:
            raise PoolLostError(f"every worker of the pool is lost, the last one: {why}")
        for env_id in moved:
            self._home[env_id] = min(survivors, key=lambda w: (len(self.envs_of(w)), w))
        message = (f"worker {worker} lost ({why}); the pool goes on with {len(survivors)} of {self.pool} "
                   f"workers, env(s) {', '.join(map(str, moved))} moved to the others")
        self.lost.append(message)
        log.warning("%s", message)  # logger "foam_bridge"

    def _death_cause(self, worker: int) -> str:
        """Why ``worker`` died, as its envs' episodes record it."""
        return WORKER_DIED

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
        """Close every env (their solvers die) and stop the workers, at once: a busy worker is killed
        with its solvers, an idle one closes its envs within CLOSE_GRACE_S or is killed. Idempotent."""
