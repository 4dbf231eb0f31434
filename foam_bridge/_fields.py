"""The solution a run ended with, and how far it is from another one.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

Why it exists: simpleFoam's convergence test reads *normalised* initial residuals, and OpenFOAM
normalises with the relaxed matrix (its diagonal grows as 1/alpha). Lowering alpha_u therefore lowers
the reported residual at once, without the field getting any closer to the solution: on 2h at 50 m/s,
dropping alpha_u from 0.95 to 0.2 at iteration 300 cut the U residual 13x within one interval and met
the test criterion at iteration 630, with the U field 21 % (relative L2) from a 6000-iteration
reference, where the constant (0.95, 0.875) met it at 839 and 1.8 % from it
(experiments/foam/README.md). Iterations to the criterion are only comparable together with the error
of the field they stop at; :func:`relative_l2` measures that against a long reference run.
"""

from __future__ import annotations

import gzip
import os
import re
from pathlib import Path

import numpy as np

__all__ = ["final_field", "read_internal_field", "relative_l2", "time_directories", "time_directory",
           "time_names"]

#: The start of a non-uniform internal field: its element type and count.
_NONUNIFORM = re.compile(rb"internalField\s+nonuniform\s+List<(\w+)>\s*(\d+)\s*\(")
_WIDTH = {b"scalar": 1, b"vector": 3, b"symmTensor": 6, b"tensor": 9, b"sphericalTensor": 1}


def time_directories(case: Path) -> list[tuple[float, Path]]:
    """The case's time directories (numeric names), earliest first."""
    return [(value, Path(case, name)) for value, name in time_names(case)]


def time_names(case: Path) -> list[tuple[float, str]]:
    """(time, name) of the case's time directories, earliest first: one scandir, no stat or path per
    entry (the answer monitor lists the case every poll: foam_bridge._answer_monitor)."""
    found = []
    with os.scandir(case) as entries:
        for entry in entries:
            try:
                value = float(entry.name)
            except ValueError:
                continue
            if entry.is_dir():  # follows a symlink, as Path.is_dir
                found.append((value, entry.name))
    return sorted(found)


def time_directory(case: Path, value: float) -> Path | None:
    """The case's time directory of time ``value`` (``100`` or ``100.0`` alike), None if it has none."""
    return next((path for time, path in time_directories(case) if time == value), None)


def final_field(case: Path, name: str = "U") -> tuple[float, np.ndarray] | None:
    """``(time, internal field)`` of ``name`` at the case's latest time after its first, as a float
    array (one row per cell); ascii, binary or gzip-compressed (``name.gz``). None when no later time
    was written (a run that crashed before its write) or the field cannot be read or is uniform."""
    from foamlib import FoamFieldFile

    times = time_directories(case)
    if len(times) < 2:
        return None
    time, directory = times[-1]
    written = [directory / f for f in (name, f"{name}.gz") if (directory / f).is_file()]  # writeCompression
    if not written:
        return None
    try:
        values = np.asarray(FoamFieldFile(written[0]).internal_field, dtype=np.float64)
    except Exception:  # noqa: BLE001 - an unreadable field is "no field", not a crashed evaluation
        return None
    uniform = values.ndim == 0 or values.shape == (3,)  # foamlib gives a uniform field as its one value
    return None if uniform else (time, values)


def relative_l2(field: np.ndarray | None, reference: np.ndarray | None) -> float | None:
    """``|field - reference| / |reference|`` over all cells and components (cells unweighted); None if
    either is missing, their shapes differ or the reference is zero."""
    if field is None or reference is None or field.shape != reference.shape:
        return None
    norm = float(np.linalg.norm(reference))
    return float(np.linalg.norm(field - reference)) / norm if norm > 0 else None


def read_internal_field(path: Path) -> tuple[np.ndarray, bool] | None:
    """(internal field, uniform?) of one field file (``path`` or ``path.gz``), float64, one row per cell;
    None if it is missing or unreadable. A uniform field comes back as its one value. Binary fields of
    64-bit scalars are read straight from the bytes (the answer monitor reads one every few iterations:
    foam_bridge._answer_monitor); anything else through foamlib."""
    found = next((p for p in (path, path.with_name(path.name + ".gz")) if p.is_file()), None)
    if found is None:
        return None
    try:
        data = found.read_bytes()
        if found.suffix == ".gz":
            data = gzip.decompress(data)
    except OSError:
        return None
    fast = _binary_internal(data)
    return (fast, False) if fast is not None else _foamlib_internal(found)


def _binary_internal(data: bytes) -> np.ndarray | None:
    """A binary non-uniform internal field of 64-bit scalars, else None (ascii, uniform, other widths)."""
    head = data[:4096]
    if b"binary" not in head or b"scalar=64" not in head:
        return None
    match = _NONUNIFORM.search(data)
    if match is None or match.group(1) not in _WIDTH:
        return None
    width, count = _WIDTH[match.group(1)], int(match.group(2))
    end = match.end() + 8 * width * count
    if len(data) < end + 1 or data[end:end + 1] != b")":
        return None
    values = np.frombuffer(data, dtype="<f8", count=width * count, offset=match.end())
    return values.reshape(count, width) if width > 1 else values.copy()


def _foamlib_internal(path: Path) -> tuple[np.ndarray, bool] | None:
    from foamlib import FoamFieldFile

    try:
        file = FoamFieldFile(path)
        values, kind = np.asarray(file.internal_field, dtype=np.float64), str(file.class_)
    except Exception:  # noqa: BLE001 - an unreadable field is "not read", not a crash
        return None
    # foamlib gives a uniform field as its value: ndim 0 for scalars, 1 for vectors (a scalar field's
    # cells are ndim 1 too, hence the class)
    return values, values.ndim < (1 if "Scalar" in kind else 2)
