"""The persistent, pausable simpleFoam process of one episode (+ watchdog, process-group kill).

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

simpleFoam pauses itself: whenever it (re-)reads ``system/fvSolution`` it opens the FIFO that
fvSolution #includes, ``system/foamBridge/relaxation.<K>`` (one per pause boundary K, see
foam_bridge._episode_case), and blocks until the bridge writes the relaxation factors into it and closes it.
The bridge notices the pause at K without any race: opening FIFO K for writing with O_NONBLOCK
succeeds only while a reader has it open, and only the solver's read after iteration K opens it. A
solver that runs past K without opening it (a missed pause) is stopped at once and reported
(``MISSED``): a step is exactly ``interval`` iterations or it fails with a cause.

OpenFOAM also watches the files fvSolution #includes: writing into a FIFO changes its mtime, and now
and then (depending on when it took the FIFO's timestamp) the solver re-reads fvSolution for that
alone, opening the FIFO it has just been served again. So the bridge puts the FIFO's mtime back
before it closes its end, and should such a re-read happen anyway (it prints "Re-reading object
fvSolution" first), serves it the same factors again: a re-read never changes the factors of a step.

While the solver runs, its stdout+stderr is read as it arrives, fed to a LogParser and appended to
``log.simpleFoam`` in the case. Every wait has a wall-clock deadline (the watchdog): a solver that
neither pauses nor exits before it is reported as hung, and so is one that closed its output but
does not exit.

No solver outlives its owner: it runs in its own session (process group); ``kill()`` SIGKILLs the
whole group while the group leader is still unreaped (a reaped leader's group id may be reused by an
unrelated process group, so the bridge never waits for the leader before the kill: exits are
observed with ``waitid(WNOWAIT)``), then reaps it. As a second line of defence the solver is started
with ``PR_SET_PDEATHSIG = SIGKILL``: the kernel kills it when the thread that started it dies (a
SIGKILLed worker, a crashed driver), even before anything else notices.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import select
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

from foam_bridge._logparse import LogParser
from foam_bridge._openfoam import OpenFOAM
from foam_bridge._parallel import kill_session, solver_command

__all__ = ["EOF_TIMEOUT_S", "QUIET_POLL_S", "READ_BATCH_S", "FoamSolver", "run_to_end"]

#: How long the output must be quiet before the bridge checks whether the solver waits on the FIFO.
QUIET_POLL_S = 0.002
#: After reading output, let more accumulate for this long: simpleFoam flushes every line, and waking
#: up once per line would cost the bridge (and a loaded machine) far more CPU than parsing does.
READ_BATCH_S = 0.005
#: Upper bound on reading a killed solver's output to EOF and on reaping it (only a stray inheritor
#: of the pipe could hold it open; the whole process group is dead).
EOF_TIMEOUT_S = 5.0
PAUSED, EXITED, HUNG, DIVERGED, MISSED = "paused", "exited", "hung", "diverged", "missed"
_PR_SET_PDEATHSIG = 1
_LIBC = ctypes.CDLL(None, use_errno=True)


def _die_with_parent() -> Callable[[], None]:
    """A ``preexec_fn`` that makes the child get SIGKILL when its parent (thread) dies.

    Everything is looked up before the fork: the child only calls prctl and getppid. If the parent
    died before prctl took effect, the child exits at once.
    """
    prctl, parent, getppid, exit_now = _LIBC.prctl, os.getpid(), os.getppid, os._exit
    kill = int(signal.SIGKILL)

    def preexec() -> None:
        prctl(_PR_SET_PDEATHSIG, kill, 0, 0, 0)
        if getppid() != parent:
            exit_now(1)

    return preexec


class FoamSolver:
    """One simpleFoam run in ``case``; ``start()``, then alternate ``wait()`` and ``release()``.

    ``fifo(K)`` is the path of the FIFO the solver reads its factors from at the pause after
    iteration K (K = 0: the start-up read).
    """

    def __init__(
        self, case: Path, openfoam: OpenFOAM, parser: LogParser, fifo: Callable[[int], Path], ranks: int = 1
    ) -> None:
        self.case = case
        self.ranks = ranks
        self.openfoam = openfoam
        self.parser = parser
        self.fifo = fifo
        self.process: subprocess.Popen[bytes] | None = None
        self.pgid: int | None = None
        self._writer: int | None = None
        self._writer_fifo: Path | None = None
        #: (FIFO, factors, fvSolution re-reads seen) of the last release: what a re-read is served.
        self._served: tuple[Path, bytes, int] | None = None
        self._log = None
        #: Seconds the solver sat waiting on the bridge: from its last output before a pause (an upper
        #: bound of the detection latency) to the release. The benchmark's bridge-overhead measure.
        self.idle_s = 0.0
        self._last_output = self._paused_at = time.monotonic()

    @property
    def exited(self) -> bool:
        """Whether the solver has exited (observed without reaping it; see the module docstring)."""
        return self.process is not None and _exit_status(self.process.pid) is not None

    def start(self) -> None:
        """Launch simpleFoam (``ranks`` > 1: under mpirun, the case decomposed) in a new session; it soon
        waits on FIFO 0 for the first factors."""
        command = solver_command(self.openfoam, self.case, self.ranks)
        self._log = open(self.case / "log.simpleFoam", "ab")  # noqa: SIM115 (closed in kill)
        self.process = subprocess.Popen(
            command, cwd=self.case,
            env=self.openfoam.environment(self.case), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_die_with_parent(),  # noqa: PLW1509
        )
        self.pgid = self.process.pid
        assert self.process.stdout is not None
        os.set_blocking(self.process.stdout.fileno(), False)

    def wait(self, timeout_s: float, boundary: int) -> str:
        """Run until the solver pauses after iteration ``boundary`` (PAUSED), exits (EXITED), diverges,
        runs past ``boundary`` without pausing (MISSED) or passes the deadline (HUNG)."""
        assert self.process is not None and self.process.stdout is not None
        out = self.process.stdout.fileno()
        deadline = time.monotonic() + timeout_s
        while True:
            if self.parser.diverged:
                return DIVERGED
            if self.parser.completed > boundary:
                return MISSED
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return HUNG
            readable, _, _ = select.select([out], [], [], min(QUIET_POLL_S, remaining))
            if readable:
                if not self._pump(out):
                    self.parser.finish()
                    return EXITED if self._await_exit(deadline) else HUNG
                time.sleep(READ_BATCH_S)
                continue
            writer = self._open_fifo_writer(self.fifo(boundary))
            if writer is None:
                self._serve_reread()
                continue
            self._drain(out)
            self._writer, self._writer_fifo = writer, self.fifo(boundary)
            self._paused_at = time.monotonic()
            self.idle_s += self._paused_at - self._last_output
            if self.parser.diverged:
                return DIVERGED
            return MISSED if self.parser.completed != boundary else PAUSED

    def release(self, text: bytes) -> None:
        """Hand the waiting solver its relaxation factors; it resumes once the FIFO is closed."""
        if self._writer is None or self._writer_fifo is None:
            raise RuntimeError("the solver is not paused")
        _feed(self._writer, self._writer_fifo, text)
        self._served = (self._writer_fifo, text, self.parser.fvsolution_rereads)
        self._writer = self._writer_fifo = None
        self.idle_s += time.monotonic() - self._paused_at

    def _serve_reread(self) -> None:
        """Serve the last factors again to a re-read of the FIFO they were served from (see the module
        docstring). Only after a new "Re-reading" line: a reader there before it is the stale one of
        the read already served, which gets nothing."""
        if self._served is None or self.parser.fvsolution_rereads <= self._served[2]:
            return
        fifo, text, _ = self._served
        writer = self._open_fifo_writer(fifo)
        if writer is not None:
            _feed(writer, fifo, text)
            self._served = (fifo, text, self.parser.fvsolution_rereads)

    def kill(self) -> int | None:
        """SIGKILL the solver's whole process group, reap it, read its output to EOF, close everything.

        The group is killed before the leader is reaped (its id cannot have been reused while the
        leader is a zombie). Reading to EOF after the kill makes what the parser saw independent of how
        far the bridge had read when it decided to stop the solver. Returns the exit status (None if it
        never started; -9 if it could not be reaped within EOF_TIMEOUT_S, which only a process stuck in
        the kernel does).
        """
        code = None
        if self.process is not None and self.pgid is not None:
            if self.process.returncode is None:  # never reaped: the group (session) id is still ours
                _kill_all(self.pgid, self.ranks)
            try:
                code = self.process.wait(EOF_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                code = -signal.SIGKILL
            if self.process.stdout is not None and not self.process.stdout.closed:
                self._drain_to_eof(self.process.stdout.fileno())
                self.process.stdout.close()
        if self._writer is not None:
            os.close(self._writer)
            self._writer = None
        if self._log is not None:
            self._log.close()
            self._log = None
        return code

    def _await_exit(self, deadline: float) -> bool:
        """After EOF: whether the solver exits before the deadline (observed, not reaped)."""
        while not self.exited:
            if time.monotonic() >= deadline:
                return False
            time.sleep(QUIET_POLL_S)
        return True

    def _pump(self, out: int) -> bool:
        """Read what is available (maybe nothing); False at end of stream."""
        try:
            data = os.read(out, 1 << 16)
        except BlockingIOError:
            return True
        if not data:
            return False
        self._last_output = time.monotonic()
        self.parser.feed(data)
        assert self._log is not None
        self._log.write(data)
        return True

    def _drain_to_eof(self, out: int) -> None:
        """Read the dead group's remaining output; every writer is gone, so EOF comes at once."""
        deadline = time.monotonic() + EOF_TIMEOUT_S
        while time.monotonic() < deadline:
            readable, _, _ = select.select([out], [], [], max(deadline - time.monotonic(), 0.0))
            if readable and not self._pump(out):
                break
        self.parser.finish()

    def _drain(self, out: int) -> None:
        """Everything the paused solver printed is already in the pipe: read all of it."""
        while True:
            readable, _, _ = select.select([out], [], [], 0)
            if not readable or not self._pump(out):
                return

    @staticmethod
    def _open_fifo_writer(fifo: Path) -> int | None:
        try:
            return os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as error:
            if error.errno in (errno.ENXIO, errno.ENOENT):
                return None
            raise


def _feed(writer: int, fifo: Path, text: bytes) -> None:
    """Write ``text`` into the FIFO and close it, its mtime put back first (no watch-triggered re-read)."""
    try:
        before = os.stat(fifo)
        os.set_blocking(writer, True)
        os.write(writer, text)
        os.utime(fifo, ns=(before.st_atime_ns, before.st_mtime_ns))
    except (BrokenPipeError, FileNotFoundError):
        pass  # the solver died (or the case was broken) meanwhile; the next wait() reports it
    finally:
        os.close(writer)


def _exit_status(pid: int) -> int | None:
    """The exit status of our child ``pid`` if it has exited, without reaping it (None if running)."""
    try:
        result = os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
    except ChildProcessError:
        return -1  # already reaped
    return None if result is None else result.si_status


def _kill_all(leader: int, ranks: int) -> None:
    """SIGKILL the solver's process group; under mpirun also every rank (each has a group of its own
    in mpirun's session: foam_bridge._parallel). ``leader`` must be unreaped."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(leader, signal.SIGKILL)
    if ranks > 1:
        kill_session(leader)


def run_to_end(case: Path, openfoam: OpenFOAM, parser: LogParser, timeout_s: float,
               ranks: int = 1, watch: Callable[[LogParser], None] | None = None) -> tuple[int, float]:
    """Run simpleFoam on ``case`` once, start to end, without pauses (the reference for chunked runs);
    ``ranks`` > 1: under mpirun, ``case`` decomposed already.

    The case must not pause (see foam_bridge._episode_case.make_uninterrupted). The output goes to
    ``log.simpleFoam``; it is parsed once the run has ended, or, with ``watch``, as it grows:
    ``watch(parser)`` every WATCH_POLL_S while the solver runs and once after it ended (the answer
    monitor, foam_bridge._answer_monitor, reads and stops the run from there). Returns (exit code, wall
    seconds); past ``timeout_s``, or on any exception here (Ctrl-C, one raised by ``watch``), every
    process of the run is killed first.
    """
    log = case / "log.simpleFoam"
    start = time.monotonic()
    with open(log, "wb") as out:
        process = subprocess.Popen(solver_command(openfoam, case, ranks), cwd=case,
                                   env=openfoam.environment(case), stdin=subprocess.DEVNULL, stdout=out,
                                   stderr=subprocess.STDOUT, start_new_session=True,
                                   preexec_fn=_die_with_parent())  # noqa: PLW1509
        try:
            code = process.wait(timeout_s) if watch is None else _watched(process, log, parser, watch,
                                                                          start + timeout_s)
        except BaseException:  # the timeout, Ctrl-C: the leader is unreaped, its session still ours
            if process.returncode is None:
                _kill_all(process.pid, ranks)
            process.wait()
            raise
    wall = time.monotonic() - start
    if watch is None:
        parser.feed(log.read_bytes())
        parser.finish()
    return code, wall


#: How often a watched run's log is read.
WATCH_POLL_S = 0.1


def _watched(process: subprocess.Popen, log: Path, parser: LogParser, watch: Callable[[LogParser], None],
             deadline: float) -> int:
    """Wait for ``process``, feeding ``parser`` the log as it grows and calling ``watch`` after each read
    (and once after the exit, the log read to its end and finished)."""
    with open(log, "rb") as reader:
        while True:
            code = process.poll()
            parser.feed(reader.read())
            if code is not None:
                parser.finish()
                watch(parser)
                return code
            watch(parser)
            if time.monotonic() > deadline:
                raise subprocess.TimeoutExpired(process.args, 0)
            time.sleep(WATCH_POLL_S)
