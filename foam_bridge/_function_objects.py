"""A case's function-object results: the time series under ``postProcessing/``, read whole or as they grow.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

A time series is a file ``postProcessing/<object>/<startTime>/<file>`` whose rows start with a time and
whose header has a ``# Time`` line (forces, coefficients, probes, fieldMinMax, surfaceFieldValue...). Each
value is named ``<object>/<file> [row] column`` (``[row]`` only where a file has several rows per time,
keyed by their text cells: a patch or field name); a vector is one value, its components. Left out: files
that hold no result of the run (NOT_RESULTS: residuals, timing), discrete columns (DISCRETE_COLUMNS: where a
minimum sits), files that are not time series (VTK, sampled sets). A value is compared with another as
``|a - b| / max(|b|, SCALE_FLOOR x the row's largest |value|)``: the floor keeps noise next to its row (a
side force of 1e-24 in a 2-D case) from turning round-off into a huge relative difference.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from foam_bridge._export import POST_PROCESSING

__all__ = ["DISCRETE_COLUMNS", "NOT_RESULTS", "SCALE_FLOOR", "FunctionObjectTable", "Table", "TableReader",
           "final_rows", "quantity_name", "relative_difference", "row_scale", "time_series"]

#: A function-object value is measured against at least this fraction of its row's largest |value|.
SCALE_FLOOR = 1e-3
#: Function-object files that hold no result of the run: residuals and timing differ by construction.
NOT_RESULTS = ("solverInfo.dat", "residuals.dat", "timeInfo.dat", "time.dat")
#: Columns that are not continuous in the solution: where a minimum or maximum sits (a cell centre, which
#: jumps to a neighbouring cell on a near tie) and which processor holds it.
DISCRETE_COLUMNS = ("location(", "processor")
#: A cell of a function object's table: a word with an optional parenthesised tail, or a parenthesised
#: group (a vector); "location(min)" and "(1 2 3)" are one cell each.
_CELL = re.compile(r"[^\s()]*\([^()]*\)|[^\s()]+")

#: One file's rows at one time: {row key (its text cells: a patch or field name, "" if none): {column:
#: value}}; a value is a tuple: one number, or a vector's components.
Table = dict[str, dict[str, tuple[float, ...]]]
FunctionObjectTable = Table  # the package's name for it


def quantity_name(key: str, row: str, column: str) -> str:
    """``<object>/<file> [row] column``, as solve's agreement and the answer monitor name a value."""
    return f"{key} [{row}] {column}" if row else f"{key} {column}"


def row_scale(columns: Sequence[Sequence[float]]) -> float:
    """The scale floor of a row: SCALE_FLOOR x its largest finite |value|."""
    magnitudes = [math.hypot(*v) for v in columns]
    return SCALE_FLOOR * max((m for m in magnitudes if math.isfinite(m)), default=0.0)


def relative_difference(value: Sequence[float] | float, reference: Sequence[float] | float,
                        scale: float = 0.0) -> float:
    """``|value - reference| / max(|reference|, scale)`` (vectors: their norms); 0 for equal values (also
    two zeros, two NaNs), inf when only one is finite or the denominator is 0."""
    a, b = np.asarray(value, dtype=np.float64), np.asarray(reference, dtype=np.float64)
    if np.array_equal(a, b, equal_nan=True):
        return 0.0
    denominator = max(float(np.linalg.norm(b)), scale)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))) or denominator == 0:
        return math.inf
    return float(np.linalg.norm(a - b)) / denominator


def time_series(case: Path) -> dict[str, Path]:
    """{``<object>/<file>``: file} of the case's function-object output (``postProcessing/<object>/
    <startTime>/<file>``), results only (not NOT_RESULTS). A restart starts a new start-time directory,
    so the latest holding a file is the one with its final values."""
    root = case / POST_PROCESSING
    latest: dict[str, tuple[float, tuple[str, ...]]] = {}
    for parts in sorted(_files(str(root), ())):  # in path order, as sorted(root.rglob("*")) gives them
        if parts[-1] in NOT_RESULTS:
            continue
        at = max((i for i, part in enumerate(parts[:-1]) if _number(part) is not None), default=None)
        start = -math.inf if at is None else float(parts[at])
        key = "/".join(part for i, part in enumerate(parts) if i != at)
        if key not in latest or start >= latest[key][0]:
            latest[key] = (start, parts)
    return {key: root.joinpath(*parts) for key, (_, parts) in latest.items()}


def _files(directory: str, parts: tuple[str, ...]) -> list[tuple[str, ...]]:
    """The files under ``directory`` (their path parts below it), as ``Path.rglob("*")`` finds them:
    symlinks to files count, symlinked directories are not entered; a directory that cannot be read
    holds nothing. One scandir per directory and no stat per regular file: the answer monitor walks
    postProcessing/ once a sample (foam_bridge._answer_monitor)."""
    found = []
    try:
        with os.scandir(directory) as entries:
            listed = list(entries)
    except OSError:
        return found
    for entry in listed:
        try:
            if entry.is_dir() and not entry.is_symlink():
                found += _files(entry.path, (*parts, entry.name))
            elif entry.is_file():
                found.append((*parts, entry.name))
        except OSError:
            continue
    return found


def final_rows(path: Path) -> Table | None:
    """The rows of the file's last time (several for per-patch or per-field output; of repeated ones the
    last); None if it is not a time series: no ``# Time`` header, or a row that does not start with a
    time (VTK, binary or sampled-set files)."""
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    reader = TableReader(path)
    rows = reader.parse(lines)
    if rows is None or not rows:
        return None
    last = rows[-1][0]
    return {key: values for time, key, values in rows if time == last}


class TableReader:
    """A time series read as it grows: :meth:`read` returns the rows completed since the last call (a
    line without its newline is left for the next); None once the file shows it is not a time series."""

    def __init__(self, path: Path) -> None:
        self.path, self._offset, self._headers = path, 0, []
        self._failed = False
        self._timed = False  # a "# Time" header came
        self._columns: dict[int, list[tuple[bool, str]]] = {}  # _column_names' of a row of so many cells

    def read(self, stride: int = 1) -> list[tuple[float, str, dict[str, tuple[float, ...]]]] | None:
        """The rows completed since the last call; ``stride``: only those whose time is a multiple of it
        (the others are not parsed)."""
        if self._failed:
            return None
        try:
            with open(self.path, "rb") as file:
                file.seek(self._offset)
                data = file.read()
        except OSError:
            return []
        complete = data[:data.rfind(b"\n") + 1]
        self._offset += len(complete)
        try:
            lines = complete.decode().splitlines()
        except UnicodeDecodeError:
            self._failed = True
            return None
        rows = self._rows(lines, stride)
        self._failed = rows is None
        return rows

    def parse(self, lines: Sequence[str]) -> list[tuple[float, str, dict[str, tuple[float, ...]]]] | None:
        """The rows of ``lines`` (the headers met so far name their columns), in order; None if a row does
        not start with a time or no ``# Time`` header came before it."""
        return self._rows(lines, 1)

    def _rows(self, lines: Sequence[str],
              stride: int) -> list[tuple[float, str, dict[str, tuple[float, ...]]]] | None:
        """:meth:`parse` of the rows whose time is a multiple of ``stride`` (a row that does not start with
        a number is parsed: it ends the table); the others are skipped unparsed."""
        rows = []
        for line in lines:
            if line.startswith("#"):
                header = _CELL.findall(line.lstrip("#"))
                self._headers.append(header)
                self._timed = self._timed or bool(header[:1] and header[0].lower() == "time")
                self._columns.clear()
                continue
            head = line.split(None, 1)  # empty: a blank line
            if not head or (stride > 1 and not _on_stride(head[0], stride)):
                continue
            cells = _CELL.findall(line)
            time = _number(cells[0])
            if time is None or not self._timed:
                return None
            rows.append((time, *_row_values(cells[1:], self._column_names(len(cells)))))
        return rows

    def _column_names(self, count: int) -> list[tuple[bool, str]]:
        """(discrete?, value name) of a row's ``count`` - 1 value columns. Their names: the last header
        line with one name per cell (probes name them on a "# Probe 0 1" line above "# Time"), else the
        cells' positions."""
        if count not in self._columns:
            names = next((h[1:] for h in reversed(self._headers) if len(h) == count),
                         [f"column {i}" for i in range(1, count)])
            self._columns[count] = [(name.startswith(DISCRETE_COLUMNS), _vector_name(name)) for name in names]
        return self._columns[count]


def _on_stride(head: str, stride: int) -> bool:
    """Whether a row whose first cell is ``head`` has a time that is a multiple of ``stride``; a row that
    does not start with a number is kept (parse decides what it is)."""
    time = _number(head)
    return time is None or round(time) % stride == 0


def _row_values(cells: Sequence[str],
                columns: Sequence[tuple[bool, str]]) -> tuple[str, dict[str, tuple[float, ...]]]:
    """(the row's key: its text cells, {column: value}) of its cells and columns (discrete?, value name);
    a vector cell is one value, its components."""
    text: list[str] = []
    values: dict[str, tuple[float, ...]] = {}
    for cell, (discrete, name) in zip(cells, columns, strict=True):
        numbers = _numbers(cell)
        if numbers is None:
            text.append(cell)
        elif not discrete:
            values[name] = numbers
    return " ".join(text), values


def _vector_name(name: str) -> str:
    """A column's name; a vector's named by its components, "(total_x total_y total_z)", is "total"."""
    inner = name[1:-1].split() if name.startswith("(") and name.endswith(")") else []
    return inner[0].rsplit("_", 1)[0] if inner else name


def _numbers(cell: str) -> tuple[float, ...] | None:
    inner = cell[1:-1] if cell.startswith("(") and cell.endswith(")") else cell
    try:
        return tuple(map(float, inner.split()))
    except ValueError:
        return None


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None
