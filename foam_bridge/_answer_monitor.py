"""The answer monitor: a running simpleFoam's fields and function-object values, sampled as it goes, judged
after every sample, and a prompt stop that leaves the fields written.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

What it installs in the case it watches (a copy: the user's case is never touched), by appending one
``#include`` to ``system/controlDict`` (the user's dictionaries are never re-serialised, as in
foam_bridge._episode_case): ``system/jaxsimrlSettle/controlDict`` with

- a ``writeObjects`` function object that writes the solved fields every ``interval`` iterations (odd, so
  that a two-iteration cycle shows as a difference between samples), in binary: read straight from the
  bytes (foam_bridge._fields.read_internal_field), writing and reading them costs a fraction of an
  iteration where ascii costs about one (pitzDaily, 12,225 cells: 17-23 ms to read four ascii fields);
- ``runTimeModifiable`` with immediate time-stamp checks, so that the stop is read at the next iteration.

The monitor reads a sample once the log shows the iteration after it (its function objects have then
written), removes a time directory that holds nothing but the sampled fields, and follows the case's own
function objects' time series under ``postProcessing/`` (foam_bridge._function_objects) row by row. To
stop, it writes ``stopAt writeNow`` (and the case's own ``writeFormat``) into its include: simpleFoam writes
every field at the iteration it is in and ends, so the case is a normal one at that iteration
(foamEndJob stops a run the same way). :func:`restore_case` takes the include out again and writes the
last fields in the case's own format when the run ended by itself in binary.
"""

from __future__ import annotations

import math
import re
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from time import process_time
from typing import Any

import numpy as np

from foam_bridge._export import POST_PROCESSING
from foam_bridge._fields import read_internal_field, time_directories, time_names
from foam_bridge._function_objects import TableReader, quantity_name, row_scale, time_series
from foam_bridge._iterative_error import MIN_HISTORY, WRITTEN_RESOLUTION, QuantityTrack
from foam_bridge._openfoam import find_openfoam
from foam_bridge._settle_verdict import SettleRule, Verdict, _Since, judge, judge_due
from foam_bridge._template import run_application

__all__ = ["MONITOR_DIR", "SAMPLE_INTERVAL", "AnswerMonitor", "install_monitor", "new_track", "request_stop",
           "restore_case"]

MONITOR_DIR = "jaxsimrlSettle"
_INCLUDE = f'#include "{MONITOR_DIR}/controlDict"'
#: Iterations between two samples of the fields (odd: see the module docstring).
SAMPLE_INTERVAL = 25
SAMPLE_FUNCTION = "jaxsimrlSettleSample"
#: Snapshots kept of a field (foam_bridge._iterative_error.QuantityTrack thins them to cover the run):
#: enough for the window's blocks and range, few enough that a judgement costs little.
FIELD_SNAPSHOTS = 64
#: Snapshots kept of a function-object value (a few numbers each): enough to see a period in every sample.
VALUE_SNAPSHOTS = 1 << 16
#: Function-object rows are followed every this many iterations (odd, as the fields' samples: a
#: two-iteration cycle still shows between two rows); the rows between are not parsed.
VALUE_STRIDE = 5
#: A function-object value sampled less often than every this many field samples is not judged.
RARE_SAMPLES = 10
#: Checks kept in a report's history (for the plot).
HISTORY_POINTS = 400
_WRITE_FORMAT = re.compile(r"^\s*writeFormat\s+(\w+)\s*;", re.MULTILINE)
_WRITE_PRECISION = re.compile(r"^\s*writePrecision\s+(\d+)\s*;", re.MULTILINE)


def new_track(name: str, is_field: bool) -> QuantityTrack:
    """The track the monitor keeps of a quantity: a field (read in binary, at full precision) or a
    function object's value (written with 6 significant digits)."""
    if is_field:
        return QuantityTrack(name, max_snapshots=FIELD_SNAPSHOTS)
    return QuantityTrack(name, VALUE_SNAPSHOTS, resolution=WRITTEN_RESOLUTION)


def install_monitor(case: Path, fields: Sequence[str], interval: int = SAMPLE_INTERVAL,
                    ranks: int = 1) -> None:
    """Write the monitor's include into ``case`` (see the module docstring) and #include it once."""
    _write_include(case, fields, interval, ranks, stop=False)
    control = case / "system" / "controlDict"
    if _INCLUDE not in control.read_text():
        with open(control, "a") as out:
            out.write(f"\n// ----- jaxsimrl solve: the answer monitor -----\n{_INCLUDE}\n")


def request_stop(case: Path, fields: Sequence[str], interval: int = SAMPLE_INTERVAL,
                 ranks: int = 1) -> None:
    """Make the running simpleFoam write every field at its current iteration and end."""
    _write_include(case, fields, interval, ranks, stop=True)


def _write_include(case: Path, fields: Sequence[str], interval: int, ranks: int, stop: bool) -> None:
    checking = "timeStamp" if ranks <= 1 else "timeStampMaster"
    body = [f"writeFormat {own_write_format(case) if stop else 'binary'};", "runTimeModifiable true;",
            f"OptimisationSwitches {{ fileModificationSkew 0; fileModificationChecking {checking}; }}",
            "functions", "{", f"    {SAMPLE_FUNCTION}", "    {",
            "        type writeObjects; libs (utilityFunctionObjects); writeOption anyWrite;",
            f"        objects ({' '.join(fields)});",
            f"        writeControl timeStep; writeInterval {interval};",
            "    }", "}"]
    if stop:
        body.insert(0, "stopAt writeNow;")
    target = case / "system" / MONITOR_DIR / "controlDict"
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = target.with_suffix(".tmp")
    staging.write_text("\n".join(body) + "\n")
    staging.replace(target)  # simpleFoam never reads half a file


def own_write_format(case: Path) -> str:
    """The case's own writeFormat (ascii unless its controlDict says otherwise)."""
    found = _WRITE_FORMAT.findall((case / "system" / "controlDict").read_text())
    return found[-1] if found else "ascii"


def written_resolution(case: Path) -> float:
    """How far rounding alone puts the fields ``case`` writes from the ones computed, relative: none in
    binary; in ascii, half a unit in the last of its writePrecision significant digits (6 unless it says).
    A field the solver no longer changes is still that far from its answer as written (slotJetFar's k,
    written with 8 digits, 2.9e-8 from its reference)."""
    if own_write_format(case) == "binary":
        return 0.0
    found = _WRITE_PRECISION.findall((case / "system" / "controlDict").read_text())
    return 0.5 * 10.0 ** (1 - int(found[-1] if found else 6))


def restore_case(case: Path, ranks: int = 1) -> None:
    """Take the monitor out of ``case`` (its include and the sample-only time directories) and, where the
    run ended in binary but the case writes ascii, rewrite its latest fields in the case's own format."""
    control = case / "system" / "controlDict"
    text = control.read_text()
    text = text.replace(f"\n// ----- jaxsimrl solve: the answer monitor -----\n{_INCLUDE}\n", "\n")
    control.write_text(text.replace(_INCLUDE, ""))
    shutil.rmtree(case / "system" / MONITOR_DIR, ignore_errors=True)
    for root in _roots(case, ranks):
        for _, directory in time_directories(root)[1:]:
            if not _full_write(directory):
                shutil.rmtree(directory, ignore_errors=True)
    latest = time_directories(case)
    if ranks > 1 or own_write_format(case) == "binary" or len(latest) < 2:
        return  # reconstructPar writes a decomposed run's fields in the case's own format
    written = latest[-1][1] / "phi"
    if written.is_file() and re.search(rb"format\s+binary", written.read_bytes()[:2048]):
        run_application(find_openfoam(), "foamFormatConvert", case, "-time", latest[-1][1].name)


def _roots(case: Path, ranks: int) -> list[Path]:
    """Where the time directories are: the case, or its processor directories."""
    if ranks <= 1:
        return [case]
    return [case / f"processor{rank}" for rank in range(ranks)]


def _full_write(directory: Path) -> bool:
    """A time directory simpleFoam wrote (it always writes the face flux phi), not a sample alone."""
    return (directory / "phi").exists() or (directory / "phi.gz").exists()


@dataclass
class _Sources:
    """Which function-object files are followed, and the notes on what could not be."""

    readers: dict[str, TableReader]
    notes: list[str]
    rejected: set[str]


class AnswerMonitor:
    """Samples a running case (see the module docstring) and judges its answer after every field sample
    (foam_bridge._settle_verdict). ``poll(iteration)`` with the log's latest ``Time =`` (iterations from
    ``start``) reads what is ready; ``stop_due`` once the verdict says stop."""

    def __init__(self, case: Path, fields: Sequence[str], start: int = 0, rule: SettleRule | None = None,
                 interval: int = SAMPLE_INTERVAL, ranks: int = 1) -> None:
        self.case, self.fields, self.start = case, list(fields), start
        self.interval, self.ranks = interval, ranks
        self.rule = rule or SettleRule()
        self.tracks: dict[str, QuantityTrack] = {}
        self.verdict: Verdict | None = None
        self.stop_due: Verdict | None = None
        self.errors: list[tuple[int, dict[str, float | None]]] = []  # every check's errors, for the plot
        self._since: _Since | None = None
        self.cpu_s = 0.0  # this process's CPU seconds in poll: the monitor's own cost beside the solver's
        self._sources = _Sources({}, [], set())
        self._sampled_to = 0  # the iteration of the last field sample read
        self._listed: int | None = None  # the log's iteration at the last listing of the time directories
        self._retry = False  # the last sample found could not be read: list again at the next poll
        self._spacing: dict[str, tuple[int, float, float]] = {}  # _rare's (iterations, least, most spacing)
        self._values: dict[tuple[str, str, str], QuantityTrack] = {}  # a function-object value's track

    def install(self) -> None:
        install_monitor(self.case, self.fields, self.interval, self.ranks)

    def poll(self, iteration: int, ended: bool = False) -> Verdict | None:
        """Read every sample the log shows complete (all of them once the run ``ended``), judge the field
        samples (at most every JUDGE_FRACTION of the run, and the last one once it ended); returns the
        verdict that first said stop, once (None otherwise).

        The run's own last write (a criterion met, a stop, its endTime) is not a sample where it comes
        sooner after the last one than the sample interval: a converging quantity's shorter step there
        reads as a slowdown, and the estimate drops (measured at criterion stops of heldout-v1 and -v3:
        channelRib's p 4.7e-3 at its last sample, 7.5e-4 with the write 9 iterations on, true 2.1e-3).
        The estimate at the last sample holds for the answer written a few iterations later."""
        started = process_time()
        due_before = self.stop_due
        ready = self._ready_samples(iteration, ended)
        if ready or ended:
            self._follow_files()  # once a poll: it walks postProcessing/
        for index, (time, directory_set) in enumerate(ready):
            self._read_values()
            if ended and index == len(ready) - 1 and self._too_soon(time):
                break  # the run's own last write (see above)
            values = self._read_fields(directory_set)
            if values is None:
                continue
            for name, value in values.items():
                self._track(name).add(time, value)
            self._sampled_to = time
            self._judge(time)
        self._retry = bool(ready) and ready[-1][0] > self._sampled_to
        if ended:
            self._read_values()
            if self._sampled_to > 0 and (self.verdict is None or self.verdict.iteration < self._sampled_to):
                self._judge(self._sampled_to, final=True)
        self.cpu_s += process_time() - started
        return self.stop_due if self.stop_due is not None and due_before is None else None

    def _too_soon(self, time: int) -> bool:
        """Whether a write at ``time`` comes sooner after the last sample than the sample interval."""
        return 0 < self._sampled_to < time < self._sampled_to + self.interval

    def _ready_samples(self, iteration: int, ended: bool) -> list[tuple[int, list[Path]]]:
        """The time directories after the last sample read whose iteration the log shows complete. Not
        listed again while the log shows the same iteration (a slow case's polls): simpleFoam writes an
        iteration's directories before it prints the next ``Time =``, so none can have become ready since
        the last listing, unless its last sample could not be read then (it is tried again)."""
        if not ended and iteration == self._listed and not self._retry:
            return []
        self._listed = iteration
        roots = _roots(self.case, self.ranks)
        ready = []
        for time, name in time_names(roots[0]):
            at = int(round(time)) - self.start
            if at <= max(0, self._sampled_to) or (not ended and at >= iteration) or time != round(time):
                continue  # not after the start, read already (a full write kept), or not complete yet
            ready.append((at, [root / name for root in roots]))
        return ready

    def _read_fields(self, directories: list[Path]) -> dict[str, np.ndarray] | None:
        """The sampled fields of one time (processor pieces in rank order); the sample-only directories
        removed. None if a field is missing or unreadable there (a write the stop overtook)."""
        values = {}
        for name in self.fields:
            pieces = [read_internal_field(directory / name) for directory in directories]
            if any(piece is None or piece[1] for piece in pieces):
                return None
            values[name] = np.concatenate([piece[0] for piece in pieces])  # type: ignore[index]
        for directory in directories:
            if not _full_write(directory):
                shutil.rmtree(directory, ignore_errors=True)
        return values

    def _track(self, name: str) -> QuantityTrack:
        if name not in self.tracks:
            self.tracks[name] = new_track(name, is_field=name in self.fields)
        return self.tracks[name]

    def _read_values(self) -> None:
        """Every function-object row written since the last read (of the files _follow_files found)."""
        for key, reader in list(self._sources.readers.items()):
            rows = reader.read(VALUE_STRIDE)
            if rows is None:
                self._sources.notes.append(f"{key}: not a time series, not monitored")
                self._sources.rejected.add(key)
                del self._sources.readers[key]
                continue
            for time, row, columns in rows:
                at = int(round(time)) - self.start
                floor = row_scale(list(columns.values()))
                for column, value in columns.items():
                    track = self._values.get((key, row, column))
                    if track is None:
                        track = self._values[key, row, column] = self._track(quantity_name(key, row, column))
                    track.add(at, np.asarray(value), floor)

    def _follow_files(self) -> None:
        for key, path in time_series(self.case).items():
            known = key in self._sources.readers or key in self._sources.rejected
            if not known and not key.startswith(f"{SAMPLE_FUNCTION}/"):
                self._sources.readers[key] = TableReader(path)

    def _judge(self, iteration: int, final: bool = False) -> None:
        if not (final or judge_due(iteration, None if self.verdict is None else self.verdict.iteration)):
            return
        judged = {name: track for name, track in self.tracks.items() if not self._rare(track)}
        self.verdict, self._since = judge(judged, iteration, self.rule, self._since)
        self.errors.append((iteration, self.verdict.errors()))
        if self.verdict.outcome is not None and self.stop_due is None:
            self.stop_due = self.verdict

    def _rare(self, track: QuantityTrack) -> bool:
        """A function-object value written less often than every RARE_SAMPLES field samples (one written
        at write times only): too rarely to follow, so not judged (noted once)."""
        if track.name in self.fields or len(track.iterations) < 2:
            return False
        spacing = self._median_spacing(track)
        rare = spacing > RARE_SAMPLES * self.interval
        if rare:
            note = f"{track.name}: written every {spacing:g} iterations, too rarely to follow: not judged"
            if note not in self._sources.notes:
                self._sources.notes.append(note)
        return rare

    def _median_spacing(self, track: QuantityTrack) -> float:
        """The median of the iterations between the track's samples. Its least and most spacing are kept
        up to date sample by sample: where they are equal (a value written at every row followed) that is
        the median, without a median over the whole history at every judgement."""
        its = track.iterations
        seen, least, most = self._spacing.get(track.name, (1, math.inf, -math.inf))
        if seen > len(its):  # not the history it was kept for
            seen, least, most = 1, math.inf, -math.inf
        for before, after in zip(its[seen - 1:-1], its[seen:], strict=True):
            least, most = min(least, after - before), max(most, after - before)
        self._spacing[track.name] = (len(its), least, most)
        return float(least) if least == most else float(np.median(np.diff(its)))

    def request_stop(self) -> None:
        request_stop(self.case, self.fields, self.interval, self.ranks)

    def report(self) -> dict[str, Any]:
        """What solve.json says of the answer: the tolerance, the outcome of a stop on the answer
        ("settled", "oscillating"; None where the run ended otherwise) and where it was decided, each
        quantity's estimated error and model at the last sample, the notes, and the errors' history
        (at most HISTORY_POINTS checks, evenly thinned) for solve.png."""
        verdict = self.verdict
        written = written_resolution(self.case)
        quantities = {} if verdict is None else {name: _as_written(e.as_dict(), written if name in self.fields
                                                                   else 0.0)
                                                 for name, e in verdict.estimates.items()}
        history = self.errors[::max(1, math.ceil(len(self.errors) / HISTORY_POINTS))]
        if self.errors and (not history or history[-1] is not self.errors[-1]):
            history.append(self.errors[-1])
        return {"tolerance": self.rule.tolerance, "sample_interval": self.interval,
                "min_history": MIN_HISTORY, "monitor_cpu_s": self.cpu_s,
                "outcome": None if self.stop_due is None else self.stop_due.outcome,
                "decided_at": None if self.stop_due is None else self.stop_due.iteration,
                "at_iteration": None if verdict is None else verdict.iteration,
                "written_resolution": written,
                "iterative_error": {name: entry["error"] for name, entry in quantities.items()},
                "quantities": quantities,
                "notes": self.notes,
                "history": [{"iteration": it, "errors": errors} for it, errors in history]}

    @property
    def notes(self) -> list[str]:
        """What the monitor could not follow; says so when it watches the fields alone."""
        notes = list(self._sources.notes)
        if not any(name not in self.fields for name in self.tracks):
            root = self.case / POST_PROCESSING
            what = ("'s function objects write nothing readable" if root.is_dir()
                    else " has no function objects")
            notes.append(f"the case{what}: monitored by its fields alone")
        return notes


def _as_written(entry: dict[str, Any], written: float) -> dict[str, Any]:
    """A field's estimate (Estimate.as_dict) for its answer as written: its error at least the rounding of
    the written digits (``written``, foam_bridge._answer_monitor.written_resolution)."""
    if entry["error"] is None or entry["error"] >= written:
        return entry
    return {**entry, "error": written, "computed_error": entry["error"]}
