"""Solve campaigns: many cases, each through :func:`jaxsimrl.apps.foam.solve.solve_case`, on foam_bridge's
worker pool: local processes or Ray actors (``jaxsimrl solve CASE [CASE ...] --pool N``).

Layout of OUT: ``NAME.solved`` per case (a single solve's output, unchanged; NAME the case directory's
name, made unique: a second ``step`` is ``step-2.solved``), ``campaign.json`` (the plan: which case goes to
which directory, so that ``--resume`` finds them again), ``campaign.csv`` and ``campaign.png``
(jaxsimrl.apps.foam.solve.campaign_table), ``logs/NAME.log`` (each solve's per-step lines).

The pool is foam_bridge._backends' own, the one training runs on, used asynchronously (``submit`` /
``collect``): each of ``pool`` slots is an "env" whose worker-side object is a :class:`CaseSolver`, and a
request to it solves one case, so a worker runs one solve at a time and takes the next case when it is
free. What the pool does for training it does here: a worker that dies, or a Ray actor whose node is
lost, answers its request with ``worker_died`` and is replaced (without room for a replacement, the pool
goes on smaller); its case goes back to the head of the queue and is solved again, from scratch, by the
next free worker. Nothing else is touched. A case counts as finished once its solve.json says
"complete" (solve writes it last), so a campaign killed at any point, kill -9 included, and run again
with ``--resume`` skips exactly the finished cases and solves the others once.

No solver outlives the campaign: each solve's processes die with the worker running it (the local
worker watches its driver, solve's own worker watches that worker, and each simpleFoam has
PR_SET_PDEATHSIG), and ``close`` kills the busy workers at once on Ctrl-C or SIGTERM.

On a cluster, OUT and the cases must be on a file system every node sees: a worker writes its case's
output there.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import shutil
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foam_bridge import Reply, Request, kill_processes_under, make_backend
from jaxsimrl.apps.foam.solve.campaign_table import failed_row, row_of, write_plot, write_table
from jaxsimrl.apps.foam.solve.report import write_status
from jaxsimrl.apps.foam.solve.runner import solve_case
from jaxsimrl.runs.atomic import atomic_write_text

__all__ = ["CASE_TIMEOUT_S", "CaseJob", "CaseSolver", "find_cases", "plan_campaign", "run_campaign"]

PLAN_JSON = "campaign.json"
LOG_DIR = "logs"
SOLVE_JSON = "solve.json"
#: Last resort on one case's solve: its own watchdog (--step-timeout per step of 100 iterations) and the
#: case's iteration budget end a stuck or endless run long before; this only catches a worker that hangs
#: outside the solver (a dead file system), which then counts as a lost worker.
CASE_TIMEOUT_S = 48 * 3600.0
#: How many times a case is sent out again after losing its worker: a case that kills every worker it
#: lands on (out of memory) must not take the whole pool down with it.
MAX_LOSSES = 3
#: How often the driver wakes while it waits for a case to finish (only bounds Ctrl-C's latency).
POLL_S = 1.0


@dataclass(frozen=True)
class CaseJob:
    """One case of the campaign and the directory its solve writes."""

    case: Path
    out: Path

    @property
    def log(self) -> Path:
        return self.out.parent / LOG_DIR / f"{self.out.name.removesuffix('.solved')}.log"


@dataclass(frozen=True)
class CampaignSettings:
    """The pool's config (foam_bridge._backends reads these two): ``step_timeout_s`` bounds a worker's
    start (a Ray actor waiting for a CPU); ``request_timeout_s`` a whole solve (CASE_TIMEOUT_S)."""

    step_timeout_s: float
    request_timeout_s: float = CASE_TIMEOUT_S


def is_case(path: Path) -> bool:
    """Whether ``path`` looks like an OpenFOAM case (solve checks the rest)."""
    return (path / "system" / "controlDict").is_file()


def find_cases(paths: Sequence[str | Path]) -> list[Path]:
    """The cases ``paths`` name: each a case, or a directory whose subdirectories include cases (those,
    sorted by name). One-line ValueError for anything else, or a case named twice."""
    found: list[Path] = []
    for given in paths:
        path = Path(given).expanduser().resolve()
        inner = sorted(p for p in path.iterdir() if is_case(p)) if path.is_dir() else []
        if is_case(path):
            found.append(path)
        elif inner:
            found += inner
        else:
            raise ValueError(f"{given} is not a simpleFoam case (no system/controlDict) nor a directory "
                             f"holding cases")
    twice = sorted({str(p) for p in found if found.count(p) > 1})
    if twice:
        raise ValueError(f"case {twice[0]} is given twice")
    return found


def plan_campaign(cases: Sequence[Path], out: str | Path, resume: bool = False) -> list[CaseJob]:
    """Each case's output directory under ``out``, written down in OUT/campaign.json. ``out`` must be new
    or empty, or with ``resume`` hold a campaign: its cases keep their directories, new ones get new
    names. One-line ValueError otherwise."""
    out = Path(out).expanduser().resolve()
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} exists and is not a directory")
    known: dict[str, str] = {}
    if out.is_dir() and any(out.iterdir()):
        if not resume:
            raise ValueError(f"--out {out} exists and is not empty; choose a new directory, or --resume to "
                             f"go on with the campaign in it")
        try:
            entries = json.loads((out / PLAN_JSON).read_text())["cases"]
            known = {entry["case"]: entry["out"] for entry in entries}
        except (OSError, ValueError, KeyError, TypeError):
            raise ValueError(f"--out {out} holds no campaign to resume (no readable {PLAN_JSON})") from None
    taken = set(known.values())
    jobs = []
    for case in cases:
        if out == case or case in out.parents or out in case.parents:
            raise ValueError(f"--out {out} and the case {case} must not contain each other")
        name = known.get(str(case)) or _unique(case.name, taken)
        taken.add(name)
        known[str(case)] = name
        jobs.append(CaseJob(case, out / name))
    out.mkdir(parents=True, exist_ok=True)
    plan = {"cases": [{"case": case, "out": name} for case, name in known.items()]}
    atomic_write_text(out / PLAN_JSON, json.dumps(plan, indent=2) + "\n")
    return jobs


def _unique(name: str, taken: set[str]) -> str:
    """NAME.solved, or NAME-2.solved, NAME-3.solved ... when another case of that name has it."""
    candidate, number = f"{name}.solved", 1
    while candidate in taken:
        number += 1
        candidate = f"{name}-{number}.solved"
    return candidate


def finished(job: CaseJob) -> dict[str, Any] | None:
    """The case's row if its solve has finished (solve.json "complete"), else None."""
    try:
        data = json.loads((job.out / SOLVE_JSON).read_text())
    except (OSError, ValueError):
        return None
    return row_of(job.case, job.out, data) if data.get("status") == "complete" else None


class CaseSolver:
    """A worker's "env" (foam_bridge's ``make_env``): ``reset(case, out, log, options)`` solves one case
    and returns its row. Module-level so it pickles to a local worker or a Ray actor."""

    def __init__(self, cfg: Any, work_dir: Path, env_id: int) -> None:
        # The local pool starts its workers as daemonic processes, which multiprocessing forbids to start
        # children, and solve_case starts its own (the controlled run's worker, the --compare runs). The
        # rule exists so that no child is orphaned when a daemon is killed with its parent; here every one
        # dies with this worker all the same (each watches its parent or has PR_SET_PDEATHSIG).
        mp.current_process()._config.pop("daemon", None)  # type: ignore[attr-defined]

    def reset(self, case: str, out: str, log: str, options: Mapping[str, Any]) -> dict[str, Any]:
        target = Path(out)
        kill_processes_under(target)  # what a lost worker's solve left running here (on this node)
        shutil.rmtree(target, ignore_errors=True)  # its partial output: solve needs an empty directory
        Path(log).parent.mkdir(parents=True, exist_ok=True)
        with open(log, "w") as lines:
            def say(text: str) -> None:
                lines.write(text + "\n")
                lines.flush()

            solve_case(case, target, say=say, **options)
        return row_of(Path(case), target, json.loads((target / SOLVE_JSON).read_text()))

    def close(self) -> None:
        """Nothing to close: solve_case stops its processes before it returns."""


def run_campaign(jobs: Sequence[CaseJob], out: str | Path, pool: int, options: Mapping[str, Any],
                 backend: str = "local", ray_address: str | None = None,
                 on_row: Callable[[dict[str, Any], int, int], None] | None = None,
                 say: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Solve every job not finished yet (see the module docstring) on ``pool`` workers with
    ``solve_case(**options)``; OUT/campaign.csv and campaign.png are rewritten after every case.
    ``on_row(row, done, total)`` sees each case as it ends, ``say`` each re-run. Returns the rows of the
    finished cases, in job order. PoolLostError when no worker is left (the cases finished stay)."""
    out = Path(out).expanduser().resolve()
    say = say or (lambda text: None)
    compare = bool(options.get("compare"))
    rows = {index: row for index, row in enumerate(map(finished, jobs)) if row is not None}
    pending = deque(index for index in range(len(jobs)) if index not in rows)
    if rows:  # a resumed campaign: its table holds the kept cases from the start
        _write(out, jobs, rows, compare)
        say(f"{len(rows)} of {len(jobs)} cases finished before: kept; solving the other {len(pending)}")
    if not pending:
        return [rows[index] for index in sorted(rows)]
    slots = min(pool, len(pending))
    settings = CampaignSettings(step_timeout_s=float(options.get("step_timeout_s", 300.0)))
    workers = make_backend(backend, settings, slots, slots, out / ".campaign-work", ray_address,
                           make_env=CaseSolver)
    running: dict[int, int] = {}  # slot -> job index
    losses: dict[int, int] = {}
    try:
        while pending or running:
            for slot in range(slots):
                if slot not in running and pending:
                    running[slot] = index = pending.popleft()
                    job = jobs[index]
                    workers.submit([Request(slot, "reset", {"case": str(job.case), "out": str(job.out),
                                                            "log": str(job.log), "options": dict(options)})])
            for reply in workers.collect(POLL_S):
                index = running.pop(reply.env_id)
                row = _row(reply, jobs[index], losses, index)
                if row is None:  # its worker was lost: the case goes first to the next free worker
                    pending.appendleft(index)
                    say(f"{jobs[index].out.name}: {reply.error}; solving it again")
                    continue
                rows[index] = row
                _write(out, jobs, rows, compare)
                if on_row is not None:
                    on_row(row, len(rows), len(jobs))
    finally:
        workers.close()
        _mark_stopped(jobs, running.values())
    return [rows[index] for index in sorted(rows)]


def _row(reply: Reply, job: CaseJob, losses: dict[int, int], index: int) -> dict[str, Any] | None:
    """The case's row from its reply, or None when it is to be solved again (a lost worker)."""
    if reply.ok:
        return dict(reply.value)
    if reply.worker_died:
        losses[index] = losses.get(index, 0) + 1
        if losses[index] <= MAX_LOSSES:
            return None
        cause = f"lost its worker {losses[index]} times, the last: {reply.error}"
        return failed_row(job.case, job.out, cause)
    return failed_row(job.case, job.out, reply.error)


def _write(out: Path, jobs: Sequence[CaseJob], rows: Mapping[int, dict[str, Any]], compare: bool) -> None:
    ordered = [rows[index] for index in sorted(rows)]
    write_table(out, ordered, compare)
    write_plot(out, ordered, compare)


def _mark_stopped(jobs: Sequence[CaseJob], stopped: Any) -> None:
    """The cases the campaign stopped mid-solve say so in their solve.json (their worker was killed
    before it could), unless the solve finished just before; --resume solves them again either way."""
    for index in stopped:
        job = jobs[index]
        if job.out.is_dir() and finished(job) is None:
            write_status(job.out, "interrupted", job.case, "stopped with the campaign")
