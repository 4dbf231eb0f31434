"""CFD model validation of the built-in backward-facing step (the paper's "velocity_profile" and "cp_cf").

Runs simpleFoam (SIMPLEC, k-omega SST, U_ref = 44.2 m/s, constant factors alpha_u = alpha_p = 0.95 and
k/omega 0.8) for a fixed number of iterations, writing the fields every ``--write-every``, then
post-processes every written time with OpenFOAM's own function objects in one
``simpleFoam -postProcess -dict`` call (wallShearStress, ``sets`` along vertical lines, ``surfaces`` on
the lower wall and on the mid-plane; see foam_bridge._validation) and writes, into ``--out``:

- fig_cfd_contours.png: |U|/U_ref on the mid-plane near the step;
- fig_cfd_profiles.png: U/U_ref against y/h at x/h = 1, 4, 6, 10;
- fig_cfd_wall.png: lower-wall Cp and Cf against x/h, with the reattachment length beside the
  experiment's 6.26 +- 0.10 h (Driver & Seegmiller) and NASA TMR's SST value;
- cfd_validation.json: the numbers (cells, iterations, residuals, reattachment per written time, ...).

The experimental profiles and wall data cannot be downloaded here, so every curve is this run's alone;
only the reattachment lengths are compared (their values as the paper and TMR state them).

``--step-height 0.0254`` runs the paper's second test geometry, 2h (the step deepened, the floor behind
it moved down by h; foam_bridge._template.mesh_parameters) and writes the same files with a ``_2h`` suffix.
Lengths are then in units of that geometry's own step height H (x/H from the step, y/H from the floor
behind it), as one reports a step flow; the experiment and TMR references belong to h only.

    python experiments/paper/fig_cfd_validation.py                       # full mesh, 2000 iterations
    python experiments/paper/fig_cfd_validation.py --step-height 0.0254  # the 2h geometry
    python experiments/paper/fig_cfd_validation.py --mesh-scale 0.4 --iterations 1000 --out /tmp/v

~500 lines because the paper's figures are one script each (experiments/paper/README.md): this one runs
the case, post-processes it and draws its three figures.
"""

from __future__ import annotations

import argparse
import datetime
import io
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFile

from foam_bridge import _base_case as base_case
from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge import _validation as val
from foam_bridge._config import (
    NEVER_CONVERGED,
    STEP_HEIGHT_H,
    TEST_CONVERGENCE,
    TRAIN_CONVERGENCE,
    U_REF,
    FoamEnvConfig,
)
from foam_bridge._logparse import LogParser, field_residual
from foam_bridge._openfoam import OpenFOAM, find_openfoam
from foam_bridge._solver import run_to_end
from jaxsimrl.runs.atomic import atomic_write_bytes, atomic_write_json

STATIONS_XH = (1.0, 4.0, 6.0, 10.0)
FACTORS = (0.95, 0.95)
RELAX_K_OMEGA = 0.8
#: The mesh's upper wall is at y/h = 9 and the step's top at y/h = 1 for every step height (the floor
#: behind the step is at 1 - H/h); the mesh is one cell deep, z from 0 to h, so the mid-plane is z = h/2.
UPPER_WALL_Y_H = 9.0
MID_PLANE_Z = 0.5 * STEP_HEIGHT_H
SOLVER_TIMEOUT_S = 3600.0
#: Points per profile line: 0.02 h apart over the 9 h channel.
PROFILE_POINTS = 451


@dataclass(frozen=True)
class Geometry:
    """The step of height ``step_height`` (m) and the change from the mesh's units (h = 0.0127 m, y = 0
    at the h-step's floor) to the geometry's own: x/H from the step, y/H from the floor behind it."""

    step_height: float = STEP_HEIGHT_H

    @property
    def ratio(self) -> float:
        """H / h."""
        return self.step_height / STEP_HEIGHT_H

    @property
    def floor_h(self) -> float:
        """y/h of the floor behind the step."""
        return 1.0 - self.ratio

    @property
    def top(self) -> float:
        """y/H of the upper wall."""
        return self.y(UPPER_WALL_Y_H)

    @property
    def suffix(self) -> str:
        """File-name suffix: "" for h, "_2h" for 2h."""
        return "" if np.isclose(self.ratio, 1.0) else f"_{self.ratio:g}h"

    def x(self, x_h: Any) -> Any:
        return np.asarray(x_h) / self.ratio

    def y(self, y_h: Any) -> Any:
        return (np.asarray(y_h) - self.floor_h) / self.ratio

    @property
    def unit(self) -> str:
        """The length unit in labels: "h", or "H" for another step height."""
        return "H" if self.suffix else "h"

    @property
    def name(self) -> str:
        """The geometry in titles: "h" or "2h"."""
        return "h" if not self.suffix else f"{self.ratio:g}h"


@dataclass
class SolverRun:
    """One uninterrupted simpleFoam run: its case, parsed log, states per iteration and timing."""

    case: Path
    parser: LogParser
    returncode: int
    wall_s: float
    cells: int
    states: dict[int, float] = field(default_factory=dict)  # iteration -> state / U_ref^2


def validation_config(mesh_scale: float, iterations: int,
                      step_height: float = STEP_HEIGHT_H) -> FoamEnvConfig:
    """The built-in case at U_ref with SIMPLEC, k/omega 0.8, and no residualControl stop."""
    return FoamEnvConfig(mesh_scale=mesh_scale, step_height=step_height, simple_variant="SIMPLEC",
                         relax_k_omega=RELAX_K_OMEGA, inlet_velocity=U_REF, max_iterations=iterations,
                         convergence={name: NEVER_CONVERGED for name in TRAIN_CONVERGENCE}).validate()


def run_uninterrupted(cfg: FoamEnvConfig, root: Path, alpha_u: float, alpha_p: float,
                      openfoam: OpenFOAM, write_every: int | None = None) -> SolverRun:
    """Mesh the case under ``root/base``, run it start to end in ``root/case`` with constant factors.

    The episode case is the env's (foam_bridge._episode_case.write_episode_case) without the pause, so its
    iterations are those of an env episode with the same constant action (tests/test_foam_env.py).
    ``write_every``: also write the fields every that many iterations (default: only at the end).
    """
    base, case = root / "base", root / "case"
    info = base_case.build_base_case(cfg, base, openfoam)
    episode_case.write_episode_case(base, case, cfg, U_REF, info)
    episode_case.make_uninterrupted(case, cfg, alpha_u, alpha_p)
    if write_every is not None:
        # the bridge's run control lives in the file its controlDict include reads last
        with FoamFile(case / "system" / episode_case.CONTROL_INCLUDE) as control:
            control["writeInterval"] = write_every
    parser = new_parser(cfg)
    code, wall = run_to_end(case, openfoam, parser, timeout_s=SOLVER_TIMEOUT_S)
    states = state_history((case / "log.simpleFoam").read_bytes(), cfg)
    return SolverRun(case, parser, code, wall, template.cell_count(base), states)


def new_parser(cfg: FoamEnvConfig) -> LogParser:
    """A parser with the env's divergence limits for a U_ref inlet."""
    return LogParser(episode_case.CELLS_FUNCTION, episode_case.INLET_FUNCTION, cfg.divergence_threshold,
                     cfg.state_divergence_ratio * U_REF**2)


def state_history(log: bytes, cfg: FoamEnvConfig) -> dict[int, float]:
    """The paper's state (inlet + cells mean |U|^2) / U_ref^2 at every iteration of a solver log.

    The log is fed to a fresh LogParser line by line; both terms of an iteration are printed after it
    (the later one overwrites the half-updated sum).
    """
    parser, states = new_parser(cfg), {}
    for line in log.decode(errors="replace").splitlines(keepends=True):
        parser.feed(line)
        if parser.state_iteration and parser.cells_state is not None and parser.inlet_state is not None:
            states[parser.state_iteration] = (parser.cells_state + parser.inlet_state) / U_REF**2
    return states


def residual_history(parser: LogParser, fields: Sequence[str]) -> dict[str, np.ndarray]:
    """Initial residual per finished iteration (1, 2, ...) of each field (vectors: largest component)."""
    def value(row: dict[str, float], name: str) -> float:
        found = field_residual(row, name)
        return np.nan if found is None else found

    return {name: np.array([value(row, name) for row in parser.history]) for name in fields}


def first_iteration_meeting(parser: LogParser, criterion: Mapping[str, float]) -> int | None:
    """The first iteration whose initial residuals are all below ``criterion`` (None if none is)."""
    for index, row in enumerate(parser.history):
        values = [field_residual(row, name) for name in criterion]
        if all(v is not None and v < criterion[name] for v, name in zip(values, criterion, strict=True)):
            return index + 1
    return None


def sample(case: Path, openfoam: OpenFOAM, stations_xh: Sequence[float],
           geometry: Geometry = Geometry()) -> None:
    """Run the validation function objects on every written time but 0 (log in log.postProcess);
    ``stations_xh`` in units of h (the mesh's)."""
    dictionary = case / "system" / "validationDict"
    dictionary.write_text(val.sampling_dict(stations_xh, (geometry.floor_h, UPPER_WALL_Y_H), MID_PLANE_Z,
                                            points=PROFILE_POINTS))
    log = case / "log.postProcess"
    with open(log, "wb") as out:
        result = subprocess.run([openfoam.executable("simpleFoam"), "-case", str(case), "-postProcess",
                                 "-dict", str(dictionary), "-noZero"], cwd=case,
                                env=openfoam.environment(case), stdout=out, stderr=subprocess.STDOUT,
                                check=False)
    if result.returncode != 0:
        tail = " | ".join(log.read_text(errors="replace").strip().splitlines()[-5:])
        raise RuntimeError(f"simpleFoam -postProcess failed in {case} (exit {result.returncode}): {tail}")


def written_times(case: Path) -> list[str]:
    """The time directories the wall sampling wrote, in iteration order."""
    directory = case / "postProcessing" / val.WALL_FUNCTION
    return sorted((p.name for p in directory.iterdir() if p.is_dir()), key=float)


def wall_at(case: Path, time_name: str, geometry: Geometry = Geometry()) -> val.WallCoefficients:
    """Cp and Cf along the lower wall at one written time, against x/H (Cp zeroed at x/h = 40)."""
    directory = case / "postProcessing" / val.WALL_FUNCTION / time_name
    wall = val.wall_coefficients(val.read_raw(directory / f"p_{val.WALL_PATCH}.raw"),
                                 val.read_raw(directory / f"wallShearStress_{val.WALL_PATCH}.raw"))
    return val.WallCoefficients(geometry.x(wall.x_h), wall.cp, wall.cf)


def profiles_at(case: Path, time_name: str, stations: Sequence[float],
                geometry: Geometry = Geometry()) -> dict[float, tuple]:
    """x/H -> (y/H, U/U_ref) at one written time."""
    directory = case / "postProcessing" / val.PROFILES_FUNCTION / time_name
    profiles = {}
    for x_H in stations:
        raw = val.read_raw(directory / f"{val.station_name(x_H * geometry.ratio)}_U.xy")
        y_h, u = val.velocity_profile(raw)
        profiles[x_H] = (geometry.y(y_h), u)
    return profiles


def plane_at(case: Path, time_name: str, geometry: Geometry = Geometry()) -> tuple[np.ndarray, ...]:
    """(x/H, y/H, |U|/U_ref) on the mid-plane at one written time."""
    path = case / "postProcessing" / val.PLANE_FUNCTION / time_name / f"U_{val.PLANE_SURFACE}.raw"
    x_h, y_h, speed = val.plane_velocity(val.read_raw(path))
    return geometry.x(x_h), geometry.y(y_h), speed


@dataclass
class Validation:
    """Everything the figures and the JSON need, from one run and its post-processing."""

    run: SolverRun
    stations_xh: tuple[float, ...]  # x/H
    wall: val.WallCoefficients
    profiles: dict[float, tuple]
    reattachment_by_iteration: dict[int, float]

    @property
    def reattachment_xh(self) -> float:
        """The reattachment length (x/H) at the last written time."""
        return self.reattachment_by_iteration[max(self.reattachment_by_iteration)]

    geometry: Geometry = Geometry()


def validate(mesh_scale: float, iterations: int, root: Path, write_every: int | None = None,
             stations_xh: Sequence[float] = STATIONS_XH, openfoam: OpenFOAM | None = None,
             step_height: float = STEP_HEIGHT_H) -> Validation:
    """Solve the case under ``root``, sample every written time, and collect the validation numbers
    (stations and lengths in units of the geometry's step height)."""
    openfoam = openfoam or find_openfoam()
    geometry = Geometry(step_height)
    cfg = validation_config(mesh_scale, iterations, step_height)
    run = run_uninterrupted(cfg, root, *FACTORS, openfoam, write_every)
    if run.returncode != 0 or run.parser.completed != iterations:
        raise RuntimeError(f"simpleFoam stopped at iteration {run.parser.completed} of {iterations} "
                           f"(exit {run.returncode}, {run.parser.error or run.parser.diverged})")
    sample(run.case, openfoam, [x * geometry.ratio for x in stations_xh], geometry)
    times = written_times(run.case)
    reattachment = {int(float(t)): val.reattachment_length(w.x_h, w.cf)
                    for t in times for w in [wall_at(run.case, t, geometry)]}
    return Validation(run, tuple(stations_xh), wall_at(run.case, times[-1], geometry),
                      profiles_at(run.case, times[-1], stations_xh, geometry), reattachment, geometry)


def summary(result: Validation, mesh_scale: float) -> dict[str, Any]:
    """The numbers of cfd_validation.json."""
    run, wall, by_iteration = result.run, result.wall, result.reattachment_by_iteration
    final = {name: field_residual(run.parser.residuals, name) for name in ("U", "p", "k", "omega")}
    behind = wall.x_h > 0
    profiles = {}
    for x_h, (y_h, u) in result.profiles.items():
        profiles[f"{x_h:g}"] = {"min_u_over_uref": float(u.min()), "y_h_at_min": float(y_h[np.argmin(u)]),
                                "max_u_over_uref": float(u.max())}
    height = result.geometry.step_height
    return {
        "created_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "load_average_1_5_15": [round(v, 2) for v in os.getloadavg()],
        "lengths_in": "step heights H of this geometry (x/H from the step, y/H from the floor behind it)",
        "case": {"mesh_scale": mesh_scale, "cells": run.cells, "step_height_m": height,
                 "u_ref_m_s": U_REF, "re_h": round(U_REF * height / template.KINEMATIC_VISCOSITY),
                 "turbulence_model": "kOmegaSST", "simple_variant": "SIMPLEC", "alpha_u": FACTORS[0],
                 "alpha_p": FACTORS[1], "alpha_k_omega": RELAX_K_OMEGA},
        "solver": {"iterations": run.parser.completed, "wall_time_s": round(run.wall_s, 2),
                   "final_initial_residuals": final,
                   "first_iteration_train_criterion": first_iteration_meeting(run.parser, TRAIN_CONVERGENCE),
                   "first_iteration_test_criterion": first_iteration_meeting(run.parser, TEST_CONVERGENCE)},
        "reattachment_xh": result.reattachment_xh,
        "reattachment_xh_by_iteration": {str(k): v for k, v in sorted(by_iteration.items())},
        "references": None if result.geometry.suffix else {
                       "experiment_reattachment_xh": val.EXPERIMENT_REATTACHMENT_XH,
                       "experiment_reattachment_error_xh": val.EXPERIMENT_REATTACHMENT_ERROR_XH,
                       "tmr_sst_reattachment_xh": val.TMR_SST_REATTACHMENT_XH,
                       "experiment": "Driver & Seegmiller (1985), as stated by the paper and NASA TMR",
                       "tmr": "https://turbmodels.larc.nasa.gov/backstep_val_sst.html (SSTm, CFL3D/FUN3D)"},
        "wall": {"cf_min": float(wall.cf[behind].min()),
                 "x_h_at_cf_min": float(wall.x_h[behind][np.argmin(wall.cf[behind])]),
                 "cp_min": float(wall.cp.min()), "x_h_at_cp_min": float(wall.x_h[np.argmin(wall.cp)]),
                 "cp_reference_xh": val.CP_REFERENCE_XH},
        "profiles": profiles,
    }


# ------------------------------------------------------------------------------------------- figures

def save_png(fig: Any, path: Path) -> None:
    """Write a figure as a PNG, atomically."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=130)
    atomic_write_bytes(path, buffer.getvalue())


def new_figure(width: float, height: float) -> Any:
    """A constrained-layout matplotlib Figure on the Agg canvas (no pyplot state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _draw_step(ax: Any, x_min: float) -> None:
    from matplotlib.patches import Rectangle

    ax.add_patch(Rectangle((x_min, 0.0), -x_min, 1.0, facecolor="0.55", edgecolor="black", zorder=3))


def plot_contours(case: Path, time_name: str, result: Validation, path: Path,
                  window_xh: tuple[float, float] = (-4.0, 20.0)) -> None:
    """|U|/U_ref filled contours near the step, the profile stations and the reattachment point."""
    import matplotlib.tri as mtri

    geometry, unit = result.geometry, result.geometry.unit
    x, y, speed = plane_at(case, time_name, geometry)
    inside = (x >= window_xh[0] - 1) & (x <= window_xh[1] + 1)
    triangulation = mtri.Triangulation(x[inside], y[inside])
    centroid_x = x[inside][triangulation.triangles].mean(axis=1)
    centroid_y = y[inside][triangulation.triangles].mean(axis=1)
    triangulation.set_mask((centroid_x < 0) & (centroid_y < 1.0))  # the solid block upstream of the step
    fig = new_figure(11, 4.3)
    ax = fig.add_subplot()
    filled = ax.tricontourf(triangulation, speed[inside], levels=np.linspace(0, 1.15, 24), cmap="viridis",
                            extend="max")
    fig.colorbar(filled, ax=ax, label=r"$|U|/U_\mathrm{ref}$", shrink=0.9)
    _draw_step(ax, window_xh[0])
    for x_h in result.stations_xh:
        ax.axvline(x_h, color="white", linestyle="--", linewidth=1)
        ax.text(x_h, geometry.top + 0.15, f"x/{unit}={x_h:g}", ha="center", va="bottom", fontsize=8)
    ax.plot([result.reattachment_xh], [0.05], marker="v", color="red", markersize=9, clip_on=False, zorder=4,
            label=f"reattachment x/{unit} = {result.reattachment_xh:.2f} (this run)")
    ax.set_xlim(*window_xh)
    ax.set_ylim(0, geometry.top)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x/{unit}")
    ax.set_ylabel(f"y/{unit}")
    ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    reynolds = U_REF * geometry.step_height / template.KINEMATIC_VISCOSITY
    ax.set_title(f"Velocity magnitude, step {geometry.name}, simpleFoam k-omega SST, {result.run.cells:,} "
                 f"cells, {result.run.parser.completed} SIMPLEC iterations (Re_{unit} = {reynolds:,.0f})",
                 fontsize=10, pad=18)
    save_png(fig, path)


def plot_profiles(result: Validation, path: Path, y_max_h: float = 4.0) -> None:
    """U/U_ref against y/h at the stations, one panel each."""
    unit = result.geometry.unit
    fig = new_figure(11, 4.2)
    axes = fig.subplots(1, len(result.stations_xh), sharey=True)
    for ax, x_h in zip(np.atleast_1d(axes), result.stations_xh, strict=True):
        y_h, u = result.profiles[x_h]
        ax.plot(u, y_h, color="tab:blue", label="simpleFoam SST (this run)")
        ax.axvline(0, color="0.6", linewidth=0.8)
        ax.set_title(f"x/{unit} = {x_h:g}", fontsize=10)
        ax.set_xlabel(r"$U/U_\mathrm{ref}$")
        ax.set_xlim(-0.3, 1.2)
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel(f"y/{unit}")
    np.atleast_1d(axes)[0].set_ylim(0, y_max_h)
    np.atleast_1d(axes)[0].legend(loc="upper left", fontsize=8)
    fig.suptitle(f"Stream-wise velocity profiles behind the step {result.geometry.name}: this run only "
                 "(Driver & Seegmiller's profiles are not available offline)", fontsize=10)
    save_png(fig, path)


def plot_wall(result: Validation, path: Path, window_xh: tuple[float, float] = (-5.0, 30.0)) -> None:
    """Lower-wall Cp and Cf against x/h; the reattachment length beside the experiment's and TMR's (for
    the h geometry; another step height has no reference)."""
    wall, unit = result.wall, result.geometry.unit
    # the faces just outside the window too, so the curves run to its edges (the downstream faces are
    # far apart); not the whole wall, whose leading-edge Cf spike at x/h = -110 would set the y scale
    shown = (wall.x_h >= window_xh[0] - 5) & (wall.x_h <= window_xh[1] + 10)
    fig = new_figure(11, 4.2)
    ax_cp, ax_cf = fig.subplots(1, 2)
    ax_cp.plot(wall.x_h[shown], wall.cp[shown], color="tab:blue", label="simpleFoam SST (this run)")
    ax_cp.set_ylabel(r"$C_p = (p - p_{x/h=40}) / (\frac{1}{2} U_\mathrm{ref}^2)$")
    ax_cf.plot(wall.x_h[shown], 1e3 * wall.cf[shown], color="tab:blue", label="simpleFoam SST (this run)")
    ax_cf.axhline(0, color="0.5", linewidth=0.8)
    if not result.geometry.suffix:
        _draw_references(ax_cf)
    ax_cf.plot([result.reattachment_xh], [0], marker="o", color="red", zorder=4,
               label=f"this run x_r/{unit} = {result.reattachment_xh:.2f}")
    ax_cf.set_ylabel(r"$10^3\, C_f = -10^3\,\tau_x / (\frac{1}{2} U_\mathrm{ref}^2)$")
    for ax in (ax_cp, ax_cf):
        ax.axvline(0, color="0.3", linewidth=0.8, linestyle=":")
        ax.set_xlabel(f"x/{unit}")
        ax.set_xlim(*window_xh)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    if result.geometry.suffix:
        fig.suptitle(f"Lower wall behind the step {result.geometry.name}: this run only (no measurement "
                     "of this geometry to compare with)", fontsize=10)
    else:
        fig.suptitle("Lower wall: curves are this run only (the experiment's Cp and Cf are not available "
                     "offline); only reattachment lengths are compared", fontsize=10)
    save_png(fig, path)


def _draw_references(ax: Any) -> None:
    """The experiment's reattachment band and TMR's SST value (the h geometry's)."""
    low = val.EXPERIMENT_REATTACHMENT_XH - val.EXPERIMENT_REATTACHMENT_ERROR_XH
    high = val.EXPERIMENT_REATTACHMENT_XH + val.EXPERIMENT_REATTACHMENT_ERROR_XH
    ax.axvspan(low, high, color="tab:orange", alpha=0.35,
               label=f"experiment x_r/h = {val.EXPERIMENT_REATTACHMENT_XH} ± "
                     f"{val.EXPERIMENT_REATTACHMENT_ERROR_XH}")
    ax.axvline(val.TMR_SST_REATTACHMENT_XH, color="tab:green", linestyle="--",
               label=f"NASA TMR SST x_r/h ≈ {val.TMR_SST_REATTACHMENT_XH:.2f}")


# ---------------------------------------------------------------------------------------------- CLI

def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh-scale", type=float, default=1.0, help="1.0 = 20,540 cells (default)")
    parser.add_argument("--iterations", type=int, default=2000, help="SIMPLE iterations (default 2000)")
    parser.add_argument("--write-every", type=int, default=500,
                        help="write and sample the fields every N iterations (reattachment per time)")
    parser.add_argument("--step-height", type=float, default=STEP_HEIGHT_H,
                        help="step height in m (default 0.0127 = h; 0.0254 = 2h, files suffixed _2h)")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent, help="directory for PNGs + JSON")
    parser.add_argument("--work-dir", type=Path, default=None, help="case directory (default: temporary)")
    args = parser.parse_args(argv)
    if not (args.mesh_scale > 0 and np.isfinite(args.mesh_scale)):
        parser.error(f"--mesh-scale must be > 0, got {args.mesh_scale}")
    if not (args.step_height > 0 and np.isfinite(args.step_height)):
        parser.error(f"--step-height must be > 0, got {args.step_height}")
    if args.iterations < 100 or args.write_every < 1:
        parser.error("--iterations must be >= 100 and --write-every >= 1")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run, post-process, write the three figures and cfd_validation.json (suffixed for 2h)."""
    args = parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    suffix = Geometry(args.step_height).suffix
    with tempfile.TemporaryDirectory(prefix="cfd_validation_") as scratch:
        root = args.work_dir or Path(scratch)
        start = time.monotonic()
        result = validate(args.mesh_scale, args.iterations, root, args.write_every,
                          step_height=args.step_height)
        last = written_times(result.run.case)[-1]
        plot_contours(result.run.case, last, result, args.out / f"fig_cfd_contours{suffix}.png")
    plot_profiles(result, args.out / f"fig_cfd_profiles{suffix}.png")
    plot_wall(result, args.out / f"fig_cfd_wall{suffix}.png")
    numbers = summary(result, args.mesh_scale)
    numbers["script_wall_time_s"] = round(time.monotonic() - start, 1)
    atomic_write_json(args.out / f"cfd_validation{suffix}.json", numbers)
    unit = result.geometry.unit
    references = "" if suffix else " (experiment 6.26 +- 0.10, TMR SST 6.50)"
    print(f"{result.run.cells} cells, {result.run.parser.completed} iterations in {result.run.wall_s:.1f} s; "
          f"reattachment x/{unit} = {result.reattachment_xh:.3f}{references}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
