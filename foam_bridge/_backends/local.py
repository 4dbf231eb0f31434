"""The local backend: a pool of worker processes on this machine (multiprocessing, "spawn" context).

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

"spawn" (not fork) so a parent that has already initialised JAX or threads is safe. Each worker serves
batches of requests over a pipe until it gets ``None`` or the pipe closes; either way it closes its
envs, so their solvers die with it. A worker that dies is noticed through its process sentinel and
replaced (see ``base``); its solvers die with it (PR_SET_PDEATHSIG, see foam_bridge._solver), and
whatever is still running in its env directories is killed before the replacement takes them over.

A worker never outlives its driver by more than a poll: while it runs a step it reads nothing from the
pipe (a step is 100 SIMPLE iterations: minutes on a big mesh), so a thread of its own watches the
driver (its parent pid; ``DRIVER_POLL_S``) and, once the driver is gone (SIGKILL, a crash, a SIGTERM
with no handler), kills the solvers in its env directories and exits at once.

``close()`` kills at once every worker that may be mid-step (``Backend.busy``: a batch interrupted by
Ctrl-C or SIGTERM, steps submitted and not collected), with the processes in its env directories;
the idle ones are asked to close their envs and given ``CLOSE_GRACE_S`` before they are killed too.
So an interrupted driver leaves no solver running within seconds, whatever the step length.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import tempfile
import threading
import time
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from foam_bridge._backends.base import CLOSE_GRACE_S, Backend
from foam_bridge._backends.reaper import kill_processes_under
from foam_bridge._backends.worker import EnvFactory, EnvHost, Reply, Request, env_dir
from foam_bridge._base_case import check_case
from foam_bridge._openfoam import find_openfoam

__all__ = ["DRIVER_POLL_S", "KILL_JOIN_S", "LocalBackend", "_preflight"]

#: Reaping a SIGKILLed worker takes milliseconds; this only bounds a process stuck in the kernel.
KILL_JOIN_S = 10.0
#: How often a worker checks that its driver is alive (a getppid call: nothing to measure).
DRIVER_POLL_S = 0.1


def _preflight(cfg: Any) -> None:
    """Fail now, in one line, on what would fail every env later: no OpenFOAM, a broken user case.

    Only for the local backend: Ray nodes may have OpenFOAM and the case where the driver has not.
    """
    openfoam = find_openfoam(cfg.openfoam_path)
    if cfg.case_dir is not None:
        with tempfile.TemporaryDirectory(prefix="foam_bridge_check_") as scratch:
            check_case(Path(cfg.case_dir), cfg, openfoam, Path(scratch))


def _serve(conn: Connection, cfg: Any, work_dir: Path, make_env: EnvFactory | None = None,
           driver: int | None = None) -> None:
    """Worker main loop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle; it closes us
    host = EnvHost(cfg, work_dir, make_env)
    if driver is not None:
        threading.Thread(target=_watch_driver, args=(driver, host), name="driver-watch", daemon=True).start()
    try:
        while True:
            try:
                batch = conn.recv()
            except (EOFError, OSError):
                break
            if batch is None:
                break
            result = host.handle_batch(batch)
            try:
                conn.send(result)
            except OSError:  # the driver has gone (a second Ctrl-C): nobody is left to read the result
                break
    finally:
        host.close()


def _watch_driver(driver: int, host: EnvHost) -> None:
    """Once the driver is gone (this process re-parented), kill the solvers of this worker's envs and exit
    now: the main thread may be inside a step for minutes. The solvers would also die with this process
    (PR_SET_PDEATHSIG); killing them first does not rely on that alone."""
    while os.getppid() == driver:
        time.sleep(DRIVER_POLL_S)
    for env_id in list(host.envs):  # a snapshot: the main thread may add an env meanwhile
        kill_processes_under(env_dir(host.work_dir, env_id))
    os._exit(1)


class LocalBackend(Backend):
    """``pool`` spawned processes on this machine; worker ``w`` hosts the envs with ``i % pool == w``."""

    name = "local"

    def __init__(self, cfg: Any, num_envs: int, pool: int, work_dir: Path, checked: bool = False,
                 make_env: EnvFactory | None = None) -> None:
        super().__init__(cfg, num_envs, pool)
        # ``checked``: the caller has just run the same checks (jaxsimrl solve); a ``make_env`` of the
        # caller's own (a stand-in solver) needs neither OpenFOAM nor a case
        if not checked and make_env is None:
            _preflight(cfg)
        self.work_dir = Path(work_dir)
        self._make_env = make_env
        self._ctx = mp.get_context("spawn")
        self._procs: list[Any] = [None] * pool
        self._conns: list[Connection | None] = [None] * pool
        for worker in range(pool):
            self._start(worker)

    def _start(self, worker: int) -> None:
        parent_end, child_end = self._ctx.Pipe()
        proc = self._ctx.Process(
            target=_serve, args=(child_end, self.cfg, self.work_dir, self._make_env, os.getpid()),
            name=f"foam-worker-{worker}", daemon=True,
        )
        proc.start()
        child_end.close()
        self._procs[worker], self._conns[worker] = proc, parent_end

    def _send(self, worker: int, batch: list[Request]) -> bool:
        conn = self._conns[worker]
        if conn is None:  # its replacement could not be started
            return False
        try:
            conn.send(batch)
            return True
        except (BrokenPipeError, OSError):
            return False

    def _receive(
        self, worker: int, batch: list[Request], handle: Any, deadline_s: float
    ) -> list[Reply] | None:
        conn, proc = self._conns[worker], self._procs[worker]
        if not handle:
            return None
        deadline = time.monotonic() + deadline_s
        while True:
            ready = wait([conn, proc.sentinel], timeout=max(deadline - time.monotonic(), 0.0))
            if conn not in ready:
                if not ready:  # missed the deadline: a hung worker counts as a dead one
                    proc.kill()
                return None
            try:
                answers = conn.recv()
            except (EOFError, OSError):
                return None
            if answers and answers[0].seq == batch[0].seq:
                return answers
            # the replies of an interrupted earlier batch: drop them, ours come next

    def _wait_ready(self, workers: list[int], timeout_s: float) -> list[int]:
        """The workers whose pipe has a reply or whose process ended (one without a pipe: at once)."""
        if any(self._conns[worker] is None for worker in workers):
            return workers
        owners = {}
        for worker in workers:
            owners[self._conns[worker]] = owners[self._procs[worker].sentinel] = worker
        return sorted({owners[ready] for ready in wait(list(owners), timeout=timeout_s)})

    def _replace(self, worker: int) -> None:
        self._stop(worker)
        self._start(worker)

    def _stop(self, worker: int) -> None:
        """Kill a worker, reap it, and kill whatever still runs in its env directories."""
        proc, conn = self._procs[worker], self._conns[worker]
        proc.kill()
        proc.join(KILL_JOIN_S)
        if conn is not None:
            conn.close()
        self._conns[worker] = None
        for env_id in self.envs_of(worker):
            kill_processes_under(env_dir(self.work_dir, env_id))

    def worker_pid(self, env_id: int) -> int:
        return self._procs[self.worker_of(env_id)].pid

    def close(self) -> None:
        busy = self._forget_busy()
        for worker in busy:  # mid-step: its step may take minutes; kill it and its solvers now
            if self._conns[worker] is not None:
                self._stop(worker)
        live = [(w, conn) for w, conn in enumerate(self._conns) if conn is not None]
        for _, conn in live:  # ask the idle ones first, so they close their envs in parallel
            with contextlib.suppress(BrokenPipeError, OSError):
                conn.send(None)
        deadline = time.monotonic() + CLOSE_GRACE_S
        for worker, conn in live:
            proc = self._procs[worker]
            proc.join(max(deadline - time.monotonic(), 0.0))
            if proc.is_alive():
                self._stop(worker)
            else:
                conn.close()
                self._conns[worker] = None
