"""Atomic file writes: a reader sees either the old file or the complete new one, never a partial one.

The data goes to a temporary file in the destination's directory (same file system, so the final
``os.replace`` is an atomic rename), is flushed and fsynced, then renamed over the destination, and the
directory is fsynced so that the rename itself survives a power cut. If anything fails on the way, the
temporary file is removed and the destination is left untouched.

The one implementation both halves of the project use: foam_bridge stands on its own (it never imports
jaxsimrl) and jaxsimrl's core never imports foam_bridge, so it is a package of its own
(``jaxsimrl.runs.atomic`` adds JSON).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write_bytes", "atomic_write_text", "file_mode"]


def file_mode() -> int:
    """The permissions a plain ``open()`` would give a new file now (mkstemp gives 0o600)."""
    return 0o666 & ~_umask()


def _umask() -> int:
    """The process's umask. Linux reports it in /proc; setting and restoring it instead would leave it 0
    for a moment, and a file another thread (a checkpointer's) creates then would be world-writable."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    umask = os.umask(0)
    os.umask(umask)
    return umask


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (the parent directory must exist)."""
    target = Path(path)
    fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            os.fchmod(handle.fileno(), file_mode())
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp_name, target)
    except BaseException:  # a Ctrl-C between write and rename must not leave the temp file behind
        with contextlib.suppress(OSError):
            os.unlink(tmp_name)
        raise
    _fsync_directory(target.parent)


def atomic_write_text(path: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically."""
    atomic_write_bytes(path, text.encode(encoding))


def _fsync_directory(directory: Path) -> None:
    """Persist the rename itself; not every file system lets a directory be opened, so best effort."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
