"""A generator of cheap steady 2-D simpleFoam cases (issue 47): many cases of the geometry kinds users run.

A controller of the relaxation factors has to meet many geometries in training; hand-built cases are
few. :func:`generate_cases` draws N case specs (foam_bridge._generator_specs: channel flows with steps,
ribs, bumps, contractions, diffusers and bends, each with a user's own factors and criterion), writes
each as a plain OpenFOAM case ``dest/<kind>-<k>/`` meshed by blockMesh (geometry:
foam_bridge._generator_mesh; fields and dictionaries: foam_bridge._generator_physics), and runs each
once with its own settings. A case its own settings do not converge within its endTime (or that
crashes or diverges) is rejected, as a user would not ship it, and further specs are drawn until N are
accepted; with ``keep_unconverged`` a case that runs its whole endTime without meeting its criterion is
kept instead (``converged`` false in the manifest): the cases whose criterion is never met are the ones
``solve``'s stop on the answer and the env's ``settle`` option are for (issue 56). A crash or a divergence
is still rejected. ``dest/generated.json`` lists the accepted cases with their own run and the rejected specs
with the reason; it is rewritten (atomically) after each case, so an interrupted generation keeps what
it made and a second call with the same seed goes on from there.

Case directories appear complete or not at all: each is written and meshed under a hidden scratch
directory and renamed into place, and the own run works on a scratch copy (the case keeps only its
log), so ``dest`` holds accepted cases and nothing else that looks like one (``train-foam --family dest``
takes every directory in it with a system/controlDict).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from atomicfile import atomic_write_text
from foam_bridge._generator_mesh import blockmesh_dict, build_sketch
from foam_bridge._generator_physics import write_physics
from foam_bridge._generator_specs import (
    CHANNEL_HEIGHT,
    GEOMETRY_KINDS,
    NU,
    CaseSpec,
    check_kinds,
    draw_spec,
    sample_specs,
)
from foam_bridge._logparse import LogParser
from foam_bridge._openfoam import OpenFOAM, find_openfoam
from foam_bridge._template import cell_count, copy_case, run_application

__all__ = ["GEOMETRY_KINDS", "MANIFEST", "CaseSpec", "GeneratedCase", "OwnRun", "Rejected", "generate_cases",
           "make_case", "read_generated", "run_own", "sample_specs", "write_case"]

MANIFEST = "generated.json"
#: Hidden under dest: cases being written and own runs in progress (never taken for a case).
SCRATCH = ".generating"
#: Extrusion depth in H (one cell; any value gives the same 2-D flow).
DEPTH = 0.1
#: Draws per accepted case at most before the generator gives up on reaching n.
MAX_DRAWS_PER_CASE = 3
#: An own run still going after this long is stopped and rejected (a stuck solver, not a slow case).
OWN_RUN_LIMIT_S = 1800.0
_FORMAT = 1
_CLOCK = re.compile(r"^ExecutionTime = \S+ s\s+ClockTime = (\S+) s", re.MULTILINE)


def write_case(spec: CaseSpec, dest: Path, resolution: float = 1.0, openfoam: OpenFOAM | None = None) -> Path:
    """Write ``spec`` as an OpenFOAM case at ``dest`` (replaced) and mesh it with blockMesh.

    ``resolution`` multiplies the cells per block direction (1: about 8,000 cells); the geometry, factors
    and criterion do not depend on it. Written as ``<dest>.partial`` and renamed when meshed: a killed
    call leaves no half case at ``dest``.
    """
    dest = Path(dest).absolute()  # OpenFOAM runs in the case directory: a relative path would not hold
    partial = dest.with_name(dest.name + ".partial")
    return _write_via(spec, dest, partial, resolution, openfoam or find_openfoam())


def _write_via(spec: CaseSpec, dest: Path, partial: Path, resolution: float, openfoam: OpenFOAM) -> Path:
    if not resolution > 0:
        raise ValueError(f"resolution {resolution!r}: expected > 0")
    shutil.rmtree(partial, ignore_errors=True)
    try:
        sketch = build_sketch(spec.kind, spec.params, spec.reynolds, resolution)
        (partial / "system").mkdir(parents=True)
        (partial / "system" / "blockMeshDict").write_text(
            "FoamFile { version 2.0; format ascii; class dictionary; object blockMeshDict; }\n\n"
            + blockmesh_dict(sketch, CHANNEL_HEIGHT, DEPTH))
        # the bend starts from rest: the inlet's velocity everywhere would run into its outlet leg's walls
        write_physics(partial, model=spec.model, algorithm=spec.algorithm, factors=dict(spec.factors),
                      criterion=dict(spec.criterion), end_time=spec.end_time, nu=NU, speed=spec.speed,
                      intensity=spec.intensity, height=CHANNEL_HEIGHT,
                      start=0.0 if spec.kind == "bend" else 1.0)
        run_application(openfoam, "blockMesh", partial)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    if dest.exists():
        shutil.rmtree(dest)
    partial.rename(dest)
    return dest


#: Why a case whose own run reached its endTime without meeting its criterion was rejected.
NOT_CONVERGED = "not converged within endTime"


@dataclass(frozen=True)
class OwnRun:
    """A case's run with its own settings: converged (residualControl met), iterations (the last one
    run), simpleFoam's CPU and clock seconds at the end of its log, its exit code, and why it fails
    (None if it converged)."""

    converged: bool
    iterations: int
    cpu_s: float
    wall_s: float
    exit_code: int
    failure: str | None


def run_own(case: Path, openfoam: OpenFOAM, scratch: Path) -> OwnRun:
    """Run simpleFoam serially on a copy of ``case`` at ``scratch`` to its end (convergence or endTime),
    stopping it at the first diverged iteration; the case gets the log (log.simpleFoam), not the fields."""
    copy_case(case, scratch)
    parser = LogParser(cells_function="", inlet_function="")
    log = scratch / "log.simpleFoam"
    started = time.monotonic()
    with open(log, "wb") as out, subprocess.Popen(
            [openfoam.executable("simpleFoam"), "-case", str(scratch)], cwd=scratch,
            env=openfoam.environment(scratch), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL) as process:
        assert process.stdout is not None
        for chunk in iter(lambda: process.stdout.read1(65536), b""):  # type: ignore[union-attr]
            out.write(chunk)
            parser.feed(chunk)
            if parser.diverged or time.monotonic() - started > OWN_RUN_LIMIT_S:
                process.kill()  # a diverged run only burns CPU from here on
                break
        code = process.wait()
    parser.finish()
    clock = _CLOCK.findall(log.read_text(errors="replace"))
    shutil.copyfile(log, case / "log.simpleFoam")
    shutil.rmtree(scratch, ignore_errors=True)
    cpu = parser.execution_time  # the last ExecutionTime, as every run of the bridge counts it
    wall = float(clock[-1]) if clock else 0.0
    converged = parser.converged_at is not None and code == 0
    iterations = parser.converged_at if parser.converged_at is not None else parser.completed
    return OwnRun(converged, iterations, cpu, wall, code, None if converged else _failure(parser, code))


def _failure(parser: LogParser, code: int) -> str:
    if parser.diverged:
        return f"diverged: {parser.diverged}"
    if parser.error or code != 0:
        return f"crashed (exit {code}): {parser.error or 'no error message'} at iteration {parser.iteration}"
    return f"{NOT_CONVERGED} ({parser.completed} iterations)"


@dataclass(frozen=True)
class GeneratedCase:
    """An accepted case: where it is, what it was drawn from, its cells, and its own run (None for the
    run's fields when generated without one)."""

    name: str
    path: Path
    spec: CaseSpec
    resolution: float
    cells: int
    converged: bool | None
    iterations: int | None
    cpu_s: float | None
    wall_s: float | None
    exit_code: int | None

    def to_json(self) -> dict[str, Any]:
        own = {key: getattr(self, key) for key in ("converged", "iterations", "cpu_s", "wall_s", "exit_code")}
        return {"name": self.name, "index": _index(self.name), "resolution": self.resolution,
                "cells": self.cells, **own, "spec": self.spec.to_json()}

    @classmethod
    def from_json(cls, entry: dict[str, Any], dest: Path) -> GeneratedCase:
        own = {key: entry[key] for key in ("converged", "iterations", "cpu_s", "wall_s", "exit_code")}
        return cls(name=entry["name"], path=Path(dest) / entry["name"],
                   spec=CaseSpec.from_json(entry["spec"]), resolution=entry["resolution"],
                   cells=entry["cells"], **own)


@dataclass(frozen=True)
class Rejected:
    """A drawn spec that did not make a case, and why."""

    spec: CaseSpec
    reason: str

    def to_json(self) -> dict[str, Any]:
        return {"name": self.spec.name, "index": _index(self.spec.name), "reason": self.reason,
                "spec": self.spec.to_json()}


def _index(name: str) -> int:
    return int(name.rsplit("-", 1)[1])


def make_case(spec: CaseSpec, dest: Path, resolution: float, openfoam: OpenFOAM,
              own: bool, keep_unconverged: bool = False) -> GeneratedCase | Rejected:
    """One case in ``dest``: written, meshed and (``own``) run; a failure is a Rejected and leaves no
    directory (a run to its endTime without convergence is one unless ``keep_unconverged``). Runs in a
    worker process (everything here pickles)."""
    scratch = dest / SCRATCH
    final = dest / spec.name
    try:
        _write_via(spec, final, scratch / f"{spec.name}.partial", resolution, openfoam)
    except Exception as err:  # noqa: BLE001 - blockMesh refusing a drawn geometry rejects it, as a run would
        return Rejected(spec, f"meshing failed: {' '.join(str(err).split())[:300]}")
    cells = cell_count(final)
    if not own:
        return GeneratedCase(spec.name, final, spec, resolution, cells, None, None, None, None, None)
    result = run_own(final, openfoam, scratch / f"{spec.name}.own")
    ran_out = str(result.failure).startswith(NOT_CONVERGED)
    if not result.converged and not (keep_unconverged and ran_out):
        shutil.rmtree(final, ignore_errors=True)
        return Rejected(spec, str(result.failure))
    return GeneratedCase(spec.name, final, spec, resolution, cells, result.converged, result.iterations,
                         result.cpu_s, result.wall_s, result.exit_code)


def read_generated(dest: Path) -> dict[str, Any]:
    """The manifest of ``dest`` (``generated.json``), {} if there is none yet."""
    path = Path(dest) / MANIFEST
    return json.loads(path.read_text()) if path.is_file() else {}


def _resume(dest: Path, seed: int, kinds: tuple[str, ...], resolution: float, own: bool,
            keep_unconverged: bool) -> tuple[list[GeneratedCase], list[Rejected]]:
    """What an earlier call with the same settings made in ``dest`` (accepted cases whose directory is
    gone are made again); ValueError if it was made with other settings."""
    manifest = read_generated(dest)
    if not manifest:
        return [], []
    earlier = {"seed": manifest.get("seed"), "kinds": tuple(manifest.get("kinds", ())),
               "resolution": manifest.get("resolution"), "run_own": manifest.get("run_own"),
               "keep_unconverged": manifest.get("keep_unconverged", False)}
    now = {"seed": seed, "kinds": kinds, "resolution": resolution, "run_own": own,
           "keep_unconverged": keep_unconverged}
    if earlier != now:
        changed = ", ".join(f"{key} {earlier[key]} (now {now[key]})" for key in now
                            if earlier[key] != now[key])
        raise ValueError(f"{dest} holds cases generated with {changed}; use another directory")
    cases = [GeneratedCase.from_json(entry, dest) for entry in manifest.get("cases", [])]
    rejected = [Rejected(CaseSpec.from_json(entry["spec"]), entry["reason"])
                for entry in manifest.get("rejected", [])]
    return [case for case in cases if (case.path / "system" / "controlDict").is_file()], rejected


def _write_manifest(dest: Path, settings: dict[str, Any], cases: Sequence[GeneratedCase],
                    rejected: Sequence[Rejected]) -> None:
    ordered = sorted(cases, key=lambda case: _index(case.name))
    manifest = {"format": _FORMAT, **settings, "cases": [case.to_json() for case in ordered],
                "rejected": [item.to_json() for item in sorted(rejected, key=lambda r: _index(r.spec.name))]}
    atomic_write_text(dest / MANIFEST, json.dumps(manifest, indent=1) + "\n")


def generate_cases(dest: Path, n: int, seed: int, *, kinds: Sequence[str] = GEOMETRY_KINDS,
                   resolution: float = 1.0, workers: int = 1, run_own: bool = True,
                   keep_unconverged: bool = False,
                   progress: Callable[[GeneratedCase | Rejected], None] | None = None,
                   openfoam: OpenFOAM | None = None) -> list[GeneratedCase]:
    """Generate ``n`` accepted cases in ``dest`` (see the module docstring); returns them in index order.

    Specs are drawn with indices 0, 1, 2, ... (sample_specs' order) until ``n`` are accepted or
    ``3 n`` have been drawn; cases already in dest's manifest (same seed, kinds, resolution) are kept and
    not made again. ``workers`` cases are made at once, each in its own process; a spec is only started
    while fewer than ``n`` are accepted or under way, so the accepted set is the one a serial run makes.
    ``progress`` is called with each case made or rejected. ``keep_unconverged``: keep a case whose own
    run reaches its endTime without meeting its criterion (see the module docstring).
    """
    kinds = check_kinds(kinds)
    if n < 1 or workers < 1 or not resolution > 0:
        raise ValueError(f"n = {n}, workers = {workers}, resolution = {resolution}: expected n >= 1, "
                         f"workers >= 1, resolution > 0")
    openfoam = openfoam or find_openfoam()
    dest = Path(dest).resolve()
    dest.mkdir(parents=True, exist_ok=True)
    cases, rejected = _resume(dest, seed, kinds, resolution, run_own, keep_unconverged)
    shutil.rmtree(dest / SCRATCH, ignore_errors=True)  # an interrupted call's half-written cases
    settings = {"seed": seed, "kinds": list(kinds), "resolution": resolution, "run_own": run_own,
                "keep_unconverged": keep_unconverged}
    known = {case.name for case in cases} | {item.spec.name for item in rejected}
    todo = (spec for spec in (draw_spec(seed, k, kinds) for k in range(MAX_DRAWS_PER_CASE * n))
            if spec.name not in known)

    def record(result: GeneratedCase | Rejected) -> None:
        (cases if isinstance(result, GeneratedCase) else rejected).append(result)  # type: ignore[arg-type]
        _write_manifest(dest, settings, cases, rejected)
        if progress is not None:
            progress(result)

    if workers == 1:
        while len(cases) < n and (spec := next(todo, None)) is not None:
            record(make_case(spec, dest, resolution, openfoam, run_own, keep_unconverged))
    else:
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            running: set[Future] = set()
            while True:
                while len(cases) + len(running) < n and (spec := next(todo, None)) is not None:
                    running.add(pool.submit(make_case, spec, dest, resolution, openfoam, run_own,
                                            keep_unconverged))
                if not running:
                    break
                finished, running = wait(running, return_when=FIRST_COMPLETED)
                for future in finished:
                    record(future.result())
    shutil.rmtree(dest / SCRATCH, ignore_errors=True)
    _write_manifest(dest, settings, cases, rejected)
    return sorted(cases, key=lambda case: _index(case.name))[:n]
