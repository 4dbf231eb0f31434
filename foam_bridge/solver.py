"""The persistent, pausable simpleFoam process of one episode (+ watchdog, process-group kill).

simpleFoam pauses itself: whenever it (re-)reads ``system/fvSolution`` it opens the FIFO
``system/foamBridgeRelaxation`` (#included by fvSolution) and blocks until the bridge writes the
relaxation factors into it and closes it (see foam_bridge.case for what makes it re-read exactly after
every ``interval`` iterations). The bridge notices the pause without any race: opening a FIFO for
writing with O_NONBLOCK succeeds only while a reader has it open. The reader of a read already served
may linger (a SIGSTOPped solver never closes it), so a reader counts as a new pause only if it is the
first one or the solver printed a new "Re-reading object fvSolution" line (flushed before it opens the
FIFO again) since the last pause; otherwise the bridge closes its end again without writing.

While the solver runs, its stdout+stderr is read as it arrives, fed to a LogParser and appended to
``log.simpleFoam`` in the case. A step has a wall-clock deadline (the watchdog): a solver that neither
prints nor waits on the FIFO past it is reported as hung. The solver is started in its own session
(process group); ``kill()`` SIGKILLs the whole group and reaps it, so nothing outlives an episode.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import signal
import subprocess
import time
from pathlib import Path

from foam_bridge.logparse import LogParser
from foam_bridge.openfoam import OpenFOAM

#: How long the output must be quiet before the bridge checks whether the solver waits on the FIFO.
QUIET_POLL_S = 0.002
#: After reading output, let more accumulate for this long: simpleFoam flushes every line, and waking
#: up once per line would cost the bridge (and a loaded machine) far more CPU than parsing does.
READ_BATCH_S = 0.005
#: Upper bound on reading a killed solver's output to EOF (only a stray inheritor of the pipe could
#: hold it open; the whole process group is dead).
EOF_TIMEOUT_S = 5.0
PAUSED, EXITED, HUNG, DIVERGED = "paused", "exited", "hung", "diverged"


class FoamSolver:
    """One simpleFoam run in ``case``; ``start()``, then alternate ``wait()`` and ``release()``."""

    def __init__(self, case: Path, openfoam: OpenFOAM, parser: LogParser, fifo: Path) -> None:
        self.case = case
        self.openfoam = openfoam
        self.parser = parser
        self.fifo = fifo
        self.process: subprocess.Popen[bytes] | None = None
        self.pgid: int | None = None
        self._writer: int | None = None
        self._served_rereads = -1  # fvSolution re-reads seen at the last pause; -1: none yet
        self._log = None
        #: Seconds the solver sat waiting on the bridge: from its last output before a pause (an upper
        #: bound of the detection latency) to the release. The benchmark's bridge-overhead measure.
        self.idle_s = 0.0
        self._last_output = self._paused_at = time.monotonic()

    @property
    def returncode(self) -> int | None:
        """The solver's exit status (negative: killed by that signal); None while it runs."""
        return None if self.process is None else self.process.poll()

    def start(self) -> None:
        """Launch simpleFoam in a new session; it soon waits on the FIFO for the first factors."""
        self._log = open(self.case / "log.simpleFoam", "ab")  # noqa: SIM115 (closed in kill)
        self.process = subprocess.Popen(
            [self.openfoam.executable("simpleFoam"), "-case", str(self.case)], cwd=self.case,
            env=self.openfoam.environment(self.case), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, start_new_session=True,
        )
        self.pgid = self.process.pid
        assert self.process.stdout is not None
        os.set_blocking(self.process.stdout.fileno(), False)

    def wait(self, timeout_s: float) -> str:
        """Run until the solver pauses (PAUSED), exits (EXITED), diverges or passes the deadline."""
        assert self.process is not None and self.process.stdout is not None
        out = self.process.stdout.fileno()
        deadline = time.monotonic() + timeout_s
        while True:
            if self.parser.diverged:
                return DIVERGED
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return HUNG
            readable, _, _ = select.select([out], [], [], min(QUIET_POLL_S, remaining))
            if readable:
                if not self._pump(out):
                    self.process.wait()
                    self.parser.finish()
                    return EXITED
                time.sleep(READ_BATCH_S)
                continue
            writer = self._open_fifo_writer()
            if writer is None:
                continue
            self._drain(out)
            if self.parser.fvsolution_rereads > self._served_rereads:
                self._writer, self._served_rereads = writer, self.parser.fvsolution_rereads
                self._paused_at = time.monotonic()
                self.idle_s += self._paused_at - self._last_output
                return DIVERGED if self.parser.diverged else PAUSED
            os.close(writer)  # the reader of the read already served: not a new pause

    def release(self, text: bytes) -> None:
        """Hand the waiting solver its relaxation factors; it resumes once the FIFO is closed."""
        if self._writer is None:
            raise RuntimeError("the solver is not paused")
        try:
            os.set_blocking(self._writer, True)
            os.write(self._writer, text)
        except BrokenPipeError:
            pass  # the solver died meanwhile; the next wait() reports its exit
        finally:
            os.close(self._writer)
            self._writer = None
            self.idle_s += time.monotonic() - self._paused_at

    def kill(self) -> int | None:
        """SIGKILL the solver's whole process group, reap it, read its output to EOF, close everything.

        Reading to EOF after the kill makes what the parser saw independent of how far the bridge had
        read when it decided to stop the solver. Returns the exit status (None if it never started).
        """
        code = None
        if self.process is not None and self.pgid is not None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.pgid, signal.SIGKILL)
            code = self.process.wait()
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

    def _open_fifo_writer(self) -> int | None:
        try:
            return os.open(self.fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as error:
            if error.errno in (errno.ENXIO, errno.ENOENT):
                return None
            raise


def run_to_end(case: Path, openfoam: OpenFOAM, parser: LogParser, timeout_s: float) -> tuple[int, float]:
    """Run simpleFoam on ``case`` once, start to end, without pauses (the reference for chunked runs).

    The case must not pause (see foam_bridge.case.make_uninterrupted). The output goes to
    ``log.simpleFoam`` and is parsed once the run has ended. Returns (exit code, wall seconds).
    """
    log = case / "log.simpleFoam"
    start = time.monotonic()
    with open(log, "wb") as out:
        result = subprocess.run([openfoam.executable("simpleFoam"), "-case", str(case)], cwd=case,
                                env=openfoam.environment(case), stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True, timeout=timeout_s,
                                check=False)
    wall = time.monotonic() - start
    parser.feed(log.read_bytes())
    parser.finish()
    return result.returncode, wall
