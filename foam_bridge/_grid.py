"""Constant-factor grid study: iterations to convergence for every (alpha_u, alpha_p) on a grid, or
every (alpha_u, alpha_p, alpha_t) with the k/omega factor as a third axis.

This is the tuned-constant baseline the paper never reported: every cell is one episode with the same
action (alpha_u, alpha_p) at every step, run in parallel on the local worker pool (one env per pool
slot; a slot takes the next cell when its episode ends). Results go to ``grid.csv`` (columns
GRID_COLUMNS, written atomically) and ``grid.png`` (a heatmap in the style of the paper's Fig. 3:
iterations annotated in every cell, crashed and non-converged cells hatched and labelled, the best
cell framed). A 3-D grid (``alpha_t`` given) has an ``alpha_t`` column after ``alpha_p`` (GRID_COLUMNS_3D)
and one heatmap per alpha_t (:func:`plot_grid_slices`); read_grid_csv reads both kinds.

A grid over several conditions (``run_grid(..., conditions=[(step_height, inlet_velocity), ...])``)
runs every factor cell on every condition, on one pool (each job reset with its condition). Cells of
run_grid carry their condition and the iteration cap: grid.csv then starts with ``step_height`` and
``inlet_velocity`` and ends with ``max_iterations`` (CONDITION_COLUMNS); files without them still load
(their cells have None there).

Cells whose episode ends with a failure keep the iteration count at which it happened ("crash @ K");
a cell that hit ``max_iterations`` is shown as ">K". The action box of the config is widened to the
grid so that constant factors are never clipped.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import os
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from atomicfile import atomic_write_bytes, atomic_write_text
from foam_bridge._config import K_OMEGA_ACTION, FoamEnvConfig
from foam_bridge._episodes import EpisodeJob, EpisodeRun, check_pool, run_episodes

__all__ = ["CONDITION_COLUMNS", "GRID_COLUMNS", "GRID_COLUMNS_3D", "GRID_SEED", "LEGEND_HEIGHT_IN",
           "MIN_FIGURE_WIDTH_IN", "TITLE_FONTSIZE", "Condition", "GridCell", "best_cell", "cell_label",
           "check_factors", "grid_config", "heatmap_figure", "plot_grid", "plot_grid_slices", "read_grid_csv",
           "run_grid", "write_grid_csv"]

GRID_COLUMNS = ("alpha_u", "alpha_p", "iterations", "outcome", "wall_time_s")
GRID_COLUMNS_3D = ("alpha_u", "alpha_p", "alpha_t", "iterations", "outcome", "wall_time_s")
#: The columns a grid with conditions adds: the first two before the factors, the cap at the end.
CONDITION_COLUMNS = ("step_height", "inlet_velocity", "max_iterations")
#: (step height in m, inlet velocity in m/s) of a grid's case; None: the config's (a range or the case's).
Condition = tuple[float | None, float | None]
TITLE_FONTSIZE = 10
MIN_FIGURE_WIDTH_IN = 6.0
LEGEND_HEIGHT_IN = 0.35
GRID_SEED = 0  # fixed inlet velocity makes the seed irrelevant to the physics; fixed for reproducibility


@dataclass(frozen=True)
class GridCell:
    """Result of one constant-factor episode."""

    alpha_u: float
    alpha_p: float
    iterations: int
    outcome: str
    wall_time_s: float
    cause: str = ""
    alpha_t: float | None = None  # the k/omega factor of a 3-D grid; None: the config's fixed one
    step_height: float | None = None  # the cell's condition; None: not recorded (older grid.csv files)
    inlet_velocity: float | None = None
    max_iterations: int | None = None  # the cap the cell ran under; None: not recorded

    @property
    def condition(self) -> Condition:
        """(step_height, inlet_velocity) of the cell's case."""
        return self.step_height, self.inlet_velocity

    @property
    def factors(self) -> tuple[float, ...]:
        """(alpha_u, alpha_p) or (alpha_u, alpha_p, alpha_t): the cell's constant action."""
        third = () if self.alpha_t is None else (self.alpha_t,)
        return (self.alpha_u, self.alpha_p, *third)


def check_factors(values: Sequence[float], name: str) -> tuple[float, ...]:
    """The factors as a tuple; one-line ValueError if empty or a value is outside (0, 1]."""
    if len(values) == 0:
        raise ValueError(f"{name}: give at least one relaxation factor")
    for value in values:
        if not (math.isfinite(value) and 0 < value <= 1):
            raise ValueError(f"{name}: relaxation factors must be in (0, 1], got {value!r}")
    return tuple(float(v) for v in values)


def grid_config(cfg: FoamEnvConfig, alpha_u: Sequence[float], alpha_p: Sequence[float],
                alpha_t: Sequence[float] | None = None) -> FoamEnvConfig:
    """``cfg`` with its action box widened to cover the grid (constant factors must not be clipped);
    ``alpha_t`` makes the k/omega factor the action's third entry (relax_k_omega="action")."""
    if alpha_t is not None and cfg.action_size == 2:
        cfg = dataclasses.replace(cfg, relax_k_omega=K_OMEGA_ACTION,
                                  action_low=(*cfg.action_low, min(alpha_t)),
                                  action_high=(*cfg.action_high, max(alpha_t)))
    axes = [alpha_u, alpha_p] + ([alpha_t] if cfg.action_size == 3 else [])
    if len(axes) == 3 and alpha_t is None:
        raise ValueError("alpha_t: a config with the k/omega factor as an action needs its grid values too")
    low = tuple(min(min(a), b) for a, b in zip(axes, cfg.action_low, strict=True))
    high = tuple(max(max(a), b) for a, b in zip(axes, cfg.action_high, strict=True))
    return dataclasses.replace(cfg, action_low=low, action_high=high).validate()


def run_grid(
    cfg: FoamEnvConfig,
    alpha_u: Sequence[float],
    alpha_p: Sequence[float],
    pool: int = 1,
    work_dir: str | os.PathLike[str] | None = None,
    on_cell: Callable[[GridCell], None] | None = None,
    alpha_t: Sequence[float] | None = None,
    conditions: Sequence[Condition] | None = None,
) -> list[GridCell]:
    """Run every (alpha_u, alpha_p) pair (every triple with ``alpha_t``, the k/omega factor) with
    constant factors on the episode pool, on every (step_height, inlet_velocity) of ``conditions``
    (default: the config's own case, reset without options); cells come back condition by condition,
    each in row-major grid order (alpha_t varying fastest)."""
    alpha_u, alpha_p = check_factors(alpha_u, "alpha_u"), check_factors(alpha_p, "alpha_p")
    alpha_t = None if alpha_t is None else check_factors(alpha_t, "alpha_t")
    check_pool(pool)
    cfg = grid_config(cfg, alpha_u, alpha_p, alpha_t).with_absolute_paths()  # workers need no shared cwd
    thirds = [(a,) for a in alpha_t] if alpha_t else [()]
    pairs = [(u, p, *t) for u in alpha_u for p in alpha_p for t in thirds]
    cases = [(_own_condition(cfg), None)] if conditions is None else \
        [(c, {"step_height": c[0], "inlet_velocity": c[1]}) for c in conditions]
    jobs = [EpisodeJob(len(pairs) * i + j, factors, seed=GRID_SEED, options=options, tag=condition)
            for i, (condition, options) in enumerate(cases) for j, factors in enumerate(pairs)]
    report = on_cell or (lambda cell: None)
    cap = cfg.max_iterations
    runs = run_episodes(cfg, jobs, pool, work_dir=work_dir, prefix="foam_grid_",
                        keep_temporary=cfg.keep_cases, on_result=lambda run: report(_cell(run, cap)))
    return [_cell(run, cap) for run in runs]


def _own_condition(cfg: FoamEnvConfig) -> Condition:
    """The config's (step height, inlet velocity) where each is one value; None where it is not."""
    height = cfg.fixed_height if cfg.builtin and cfg.height_range is None else None
    velocity = cfg.inlet_velocity
    fixed = isinstance(velocity, int | float) and not isinstance(velocity, bool)
    return height, float(velocity) if fixed else None  # type: ignore[arg-type]


def _cell(run: EpisodeRun, cap: int) -> GridCell:
    """The cell of a constant-factor episode; wall time from the episode record if there is one, else
    as the host saw it (reset included)."""
    wall = run.record.wall_time_s if run.record is not None else math.nan
    if math.isnan(wall):
        wall = run.host_wall_s + run.reset_s
    alpha_u, alpha_p, *alpha_t = (float(a) for a in run.job.controller)
    height, velocity = run.job.tag
    return GridCell(alpha_u, alpha_p, int(run.iterations), run.outcome, float(wall), run.cause,
                    alpha_t[0] if alpha_t else None, height, velocity, cap)


def write_grid_csv(cells: Sequence[GridCell], path: str | os.PathLike[str]) -> None:
    """``path`` <- one row per cell with GRID_COLUMNS (GRID_COLUMNS_3D), atomically; cells that record
    their condition add CONDITION_COLUMNS (an unknown value is an empty field)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    three = any(cell.alpha_t is not None for cell in cells)
    conditioned = any(cell.condition != (None, None) or cell.max_iterations is not None for cell in cells)
    head, tail = CONDITION_COLUMNS[:2], CONDITION_COLUMNS[2:]
    columns = GRID_COLUMNS_3D if three else GRID_COLUMNS
    writer.writerow((*head, *columns, *tail) if conditioned else columns)
    for cell in cells:
        row = (*cell.factors, cell.iterations, cell.outcome, f"{cell.wall_time_s:.3f}")
        blank = ["" if v is None else v for v in (*cell.condition, cell.max_iterations)]
        writer.writerow((*blank[:2], *row, *blank[2:]) if conditioned else row)
    atomic_write_text(path, buffer.getvalue())


def read_grid_csv(path: str | os.PathLike[str]) -> list[GridCell]:
    """Cells back from a grid.csv (for plotting again or comparing runs; 2-D or 3-D, with or without
    conditions)."""
    def number(row: dict[str, str], key: str, kind: Callable[[str], Any] = float) -> Any:
        return kind(row[key]) if row.get(key) else None

    with open(path, newline="") as handle:
        return [GridCell(float(r["alpha_u"]), float(r["alpha_p"]), int(r["iterations"]), r["outcome"],
                         float(r["wall_time_s"]), alpha_t=number(r, "alpha_t"),
                         step_height=number(r, "step_height"), inlet_velocity=number(r, "inlet_velocity"),
                         max_iterations=number(r, "max_iterations", int))
                for r in csv.DictReader(handle)]


def best_cell(cells: Sequence[GridCell]) -> GridCell | None:
    """The converged cell with the fewest iterations (ties: the first in grid order), or None."""
    converged = [c for c in cells if c.outcome == "converged"]
    return min(converged, key=lambda c: c.iterations) if converged else None


def cell_label(cell: GridCell) -> str:
    """Text written in a heatmap cell."""
    if cell.outcome == "converged":
        return str(cell.iterations)
    if cell.outcome == "truncated":
        return f">{cell.iterations}"
    return f"{cell.outcome}\n@{cell.iterations}"


def _fit_title(title: str, width_in: float, fontsize: float) -> str:
    """``title`` with each line wrapped to fit a figure ``width_in`` inches wide (whatever the grid size)."""
    # ~0.6 em per character is a safe average for DejaVu Sans; keep a margin of half an inch.
    chars = max(int((width_in - 0.5) * 72 / (0.6 * fontsize)), 10)
    return "\n".join(textwrap.fill(line, chars) for line in title.splitlines())


def plot_grid(cells: Sequence[GridCell], path: str | os.PathLike[str], title: str = "") -> None:
    """Heatmap of iterations (rows alpha_u, columns alpha_p) written atomically as a PNG to ``path``."""
    buffer = io.BytesIO()
    heatmap_figure(cells, title).savefig(buffer, format="png", dpi=120)
    atomic_write_bytes(path, buffer.getvalue())


def plot_grid_slices(cells: Sequence[GridCell], out: str | os.PathLike[str], title: str = "",
                     stem: str = "grid") -> list[str]:
    """One heatmap per alpha_t of a 3-D grid, ``out/<stem>_alpha_t_<value>.png``; returns the file names."""
    names = []
    for alpha_t in sorted({c.alpha_t for c in cells if c.alpha_t is not None}):
        name = f"{stem}_alpha_t_{alpha_t:g}.png"
        plot_grid([c for c in cells if c.alpha_t == alpha_t], os.path.join(out, name),
                  f"{title}\nalpha_t (k/omega) = {alpha_t:g}".strip())
        names.append(name)
    return names


def heatmap_figure(cells: Sequence[GridCell], title: str = "") -> Any:
    """The heatmap as a matplotlib Figure (Agg canvas); every text fits inside it, whatever the grid."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch, Rectangle

    us = sorted({c.alpha_u for c in cells})
    ps = sorted({c.alpha_p for c in cells})
    values = np.full((len(us), len(ps)), np.nan)
    for cell in cells:
        if cell.outcome == "converged":
            values[us.index(cell.alpha_u), ps.index(cell.alpha_p)] = cell.iterations
    # at least MIN_FIGURE_WIDTH_IN wide, so that the legend's three entries fit on a 1 x 1 grid too
    fig = Figure(figsize=(max(1.3 * len(ps) + 3.2, MIN_FIGURE_WIDTH_IN), 1.0 * len(us) + 2.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    finite = values[np.isfinite(values)]
    norm = Normalize(finite.min(), finite.max() if finite.max() > finite.min() else finite.min() + 1) \
        if finite.size else Normalize(0, 1)
    cmap = colormaps["RdYlGn_r"].with_extremes(bad="white")  # few iterations green, many red
    image = ax.imshow(np.ma.masked_invalid(values), cmap=cmap, norm=norm, origin="lower", aspect="auto")
    fig.colorbar(image, ax=ax, label="SIMPLE iterations to convergence")
    best = best_cell(cells)
    for cell in cells:
        row, col = us.index(cell.alpha_u), ps.index(cell.alpha_p)
        if cell.outcome != "converged":
            hatch, face = ("xx", "0.6") if cell.outcome != "truncated" else ("//", "0.85")
            ax.add_patch(Rectangle((col - 0.5, row - 0.5), 1, 1, facecolor=face, hatch=hatch, edgecolor="0.4",
                                   linewidth=0))
        is_best = cell == best
        ax.text(col, row, cell_label(cell), ha="center", va="center", fontsize=10,
                fontweight="bold" if is_best else "normal",
                bbox={"facecolor": "white", "alpha": 0.7, "edgecolor": "none", "pad": 1})
        if is_best:
            ax.add_patch(Rectangle((col - 0.47, row - 0.47), 0.94, 0.94, fill=False, edgecolor="blue",
                                   linewidth=3))
    ax.set_xticks(range(len(ps)), [f"{p:g}" for p in ps])
    ax.set_yticks(range(len(us)), [f"{u:g}" for u in us])
    ax.set_xlabel(r"$\alpha_p$ (pressure)")
    ax.set_ylabel(r"$\alpha_u$ (momentum)")
    fig.suptitle(_fit_title(title, fig.get_figwidth(), TITLE_FONTSIZE), fontsize=TITLE_FONTSIZE)
    handles = [Patch(facecolor="0.6", hatch="xx", edgecolor="0.4", label="crashed / diverged / hung"),
               Patch(facecolor="0.85", hatch="//", edgecolor="0.4", label="not converged (cap)"),
               Patch(fill=False, edgecolor="blue", linewidth=3, label="best")]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, LEGEND_HEIGHT_IN / fig.get_figheight(), 1, 1))  # the legend below the axes
    return fig
