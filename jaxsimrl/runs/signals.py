"""Stop signals: SIGTERM (a batch scheduler, ``docker stop``, ``kill``) handled the way Ctrl-C is.

Python's default for SIGTERM ends the process at once, skipping the ``finally`` blocks that stop the
solvers and write what a run directory holds; the workers would then notice only through their
driver watch. With :func:`terminate_as_interrupt`, SIGTERM raises :class:`Terminated`, a
KeyboardInterrupt, wherever Ctrl-C would, so every command's Ctrl-C path (stop the solvers, say what
was saved) serves both; only the exit code (143, 128 + SIGTERM) and the word differ.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["STOP_SIGNALS", "Terminated", "exit_code", "interrupt_for", "stop_word", "terminate_as_interrupt"]

#: The signals that stop a command through its Ctrl-C path.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C raises KeyboardInterrupt."""


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated


@contextlib.contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """Within the block SIGTERM raises :class:`Terminated` in the main thread (a no-op in another thread,
    where Python cannot set handlers); the previous handler is put back after it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupt_for(signals: list[int]) -> KeyboardInterrupt:
    """The exception a stop by ``signals`` (received in this order) raises: Terminated if any was SIGTERM."""
    return Terminated() if signal.SIGTERM in signals else KeyboardInterrupt()


def exit_code(stop: BaseException) -> int:
    """The exit code of a command stopped by ``stop``: 143 for SIGTERM, 130 for Ctrl-C (as a shell's)."""
    return 128 + (signal.SIGTERM if isinstance(stop, Terminated) else signal.SIGINT)


def stop_word(stop: BaseException) -> str:
    """How the stop is named in a command's last line."""
    return "terminated (SIGTERM)" if isinstance(stop, Terminated) else "interrupted"
