"""eval-foam's figures, drawn from the eval.json report (matplotlib's Agg canvas, written atomically).

- ``box_V<v>.png`` per velocity: the paper's box plot, SIMPLE iterations to convergence per controller,
  one panel per geometry; every run is also drawn as a dot, and runs that did not converge are counted
  above their controller.
- ``mean_V<v>.png`` per velocity: mean +- std per controller of the costs of the converged runs
  (rows: SIMPLE iterations, wall time, solver CPU time, linear-solver iterations, and with reference
  runs the U error), one column per geometry.
- ``factors.png``: the learned policy's relaxation factors alpha_u, alpha_p (and alpha_t) against the SIMPLE
  iteration (each action holds for ``interval`` iterations), per geometry and velocity: the
  deterministic run bold, the stochastic samples thin; the best constant dashed.
- ``velocities.png``: SIMPLE iterations against the inlet velocity per controller (the mean of the
  converged runs as a line, every converged run as a dot), one panel per geometry: with many
  velocities it shows how rugged the landscape is between the protocol's three.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from jaxsimrl.runs.atomic import atomic_write_bytes

LABELS = {"learned_deterministic": "learned\n(mean)", "learned_stochastic": "learned\n(sampled)",
          "best_constant": "best\nconstant", "tutorial_defaults": "tutorial\ndefaults", "random": "random",
          "residual_rule": "residual\nrule", "bandit": "bandit", "case_oracle": "case\noracle"}
COLOURS = {"learned_deterministic": "tab:blue", "learned_stochastic": "tab:cyan",
           "best_constant": "tab:green", "tutorial_defaults": "tab:olive", "random": "tab:red",
           "residual_rule": "tab:orange", "bandit": "tab:brown", "case_oracle": "indigo"}
#: (controller, line width, opacity) of the factor trajectories: the samples thin, the mean action bold.
#: The action's factors, one row of factors.png each (alpha_t only for a run with the k/omega action).
FACTOR_KEYS = ("alpha_u", "alpha_p", "alpha_t")
LEARNED_STYLE = (("learned_stochastic", 0.8, 0.35), ("learned_deterministic", 2.2, 1.0))
PALETTE = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:gray")
#: (key in a cell summary, axis label) of the mean +- std figure's rows.
COSTS = (("iterations", "SIMPLE iterations"), ("wall_time_s", "wall time (s)"),
         ("cpu_time_s", "solver CPU time (s)"), ("linear_iterations", "linear-solver iterations"))
#: The extra row with reference runs (eval-foam --reference-iterations).
U_ERROR = ("u_error", "U error vs reference")


def plot_all(report: dict[str, Any], out: Path) -> list[Path]:
    """Every figure of the report into ``out``; returns their paths."""
    paths = []
    for velocity in report["velocities"]:
        paths.append(plot_boxes(report, velocity, out / f"box_V{velocity:g}.png"))
        paths.append(plot_means(report, velocity, out / f"mean_V{velocity:g}.png"))
    paths.append(plot_factors(report, out / "factors.png"))
    paths.append(plot_velocities(report, out / "velocities.png"))
    return paths


def _cells(report: dict[str, Any], geometry: str, velocity: float) -> dict[str, dict[str, Any]]:
    return {c: report["results"][c][geometry][f"{velocity:g}"] for c in report["results"]}


def _figure(rows: int, columns: int, width: float, height: float) -> tuple[Figure, np.ndarray]:
    fig = Figure(figsize=(width * columns, height * rows))
    FigureCanvasAgg(fig)
    axes = np.asarray(fig.subplots(rows, columns, squeeze=False))
    return fig, axes


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def plot_boxes(report: dict[str, Any], velocity: float, path: Path) -> Path:
    """The paper's box plot of iterations to convergence at one velocity (see the module docstring)."""
    shapes = list(report["geometries"])
    fig, axes = _figure(1, len(shapes), 6.0, 4.6)
    for ax, geometry in zip(axes[0], shapes, strict=True):
        cells = _cells(report, geometry, velocity)
        names = list(cells)
        for x, name in enumerate(names, start=1):
            runs = cells[name]["runs"]
            done = [r["iterations"] for r in runs if r["outcome"] == "converged"]
            if done:
                ax.boxplot([done], positions=[x], widths=0.55, showfliers=False,
                           medianprops={"color": COLOURS[name], "linewidth": 2})
                spread = np.linspace(-0.12, 0.12, len(done)) if len(done) > 1 else np.zeros(1)
                ax.scatter(x + spread, done, s=12, color=COLOURS[name], zorder=3)
            failed = len(runs) - len(done)
            if failed:
                ax.annotate(f"{failed}/{len(runs)}\nnot conv.", (x, 1.0), xycoords=("data", "axes fraction"),
                            ha="center", va="top", fontsize=7, color="tab:red")
        ax.set_xticks(range(1, len(names) + 1), [LABELS.get(n, n) for n in names], fontsize=8)
        ax.set_xlim(0.4, len(names) + 0.6)
        ax.set_ylabel("SIMPLE iterations to convergence")
        ax.set_title(f"{geometry}, V = {velocity:g} m/s", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    return _save(fig, path)


def plot_means(report: dict[str, Any], velocity: float, path: Path) -> Path:
    """Mean +- std of every cost per controller at one velocity (converged runs)."""
    shapes = list(report["geometries"])
    costs = COSTS + ((U_ERROR,) if report.get("reference") is not None else ())
    fig, axes = _figure(len(costs), len(shapes), 6.0, 2.8)
    for column, geometry in enumerate(shapes):
        cells = _cells(report, geometry, velocity)
        names = list(cells)
        for row, (key, label) in enumerate(costs):
            ax = axes[row, column]
            means = [cells[n][key]["mean"] for n in names]
            heights = [np.nan if m is None else m for m in means]
            errors = [cells[n][key]["std"] or 0.0 for n in names]
            ax.bar(range(len(names)), heights, yerr=errors, capsize=4, color=[COLOURS[n] for n in names])
            for x, name in enumerate(names):
                runs, done = len(cells[name]["runs"]), cells[name]["converged"]
                if done < runs:
                    ax.annotate(f"{done}/{runs} conv.", (x, 0.98), xycoords=("data", "axes fraction"),
                                ha="center", va="top", fontsize=7, color="tab:red")
            ax.set_xticks(range(len(names)), [LABELS.get(n, n) for n in names] if row == len(costs) - 1
                          else [""] * len(names), fontsize=8)
            ax.set_ylabel(label, fontsize=9)
            ax.grid(axis="y", alpha=0.3)
            if row == 0:
                ax.set_title(f"{geometry}, V = {velocity:g} m/s (mean +- std of converged runs)", fontsize=10)
    return _save(fig, path)


def plot_velocities(report: dict[str, Any], path: Path) -> Path:
    """SIMPLE iterations against the inlet velocity, per controller and geometry (converged runs)."""
    shapes = list(report["geometries"])
    velocities = report["velocities"]
    fig, axes = _figure(1, len(shapes), 6.5, 4.2)
    for ax, geometry in zip(axes[0], shapes, strict=True):
        for name, by_velocity in report["results"].items():
            cells = [by_velocity[geometry][f"{v:g}"] for v in velocities]
            means = [np.nan if c["iterations"]["mean"] is None else c["iterations"]["mean"] for c in cells]
            ax.plot(velocities, means, "-", color=COLOURS[name], lw=1.5,
                    label=LABELS.get(name, name).replace("\n", " "))
            for velocity, cell in zip(velocities, cells, strict=True):
                done = [r["iterations"] for r in cell["runs"] if r["outcome"] == "converged"]
                ax.scatter([velocity] * len(done), done, s=10, color=COLOURS[name], zorder=3)
        ax.set_xlabel("inlet velocity (m/s)")
        ax.set_ylabel("SIMPLE iterations to convergence")
        ax.set_title(f"{geometry}: iterations against the inlet velocity", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return _save(fig, path)


def factor_steps(actions: Sequence[Sequence[float]], iterations: int, interval: int, which: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(iteration edges, factor) of one run for ``ax.step(..., where="post")``: action t holds from
    iteration t * interval to (t + 1) * interval, the last one up to the run's final iteration
    (``actions`` must not be empty)."""
    values = np.array([a[which] for a in actions], float)
    edges = np.arange(len(values) + 1, dtype=float) * interval
    edges[-1] = max(iterations, edges[-2])  # an episode ends within its last step
    return edges, np.append(values, values[-1])


def plot_factors(report: dict[str, Any], path: Path) -> Path:
    """The learned policy's (alpha_u, alpha_p[, alpha_t]) against the SIMPLE iteration (see the module
    docstring); one row per factor of the action."""
    shapes = list(report["geometries"])
    interval = int(report["case"]["interval"])
    keys = FACTOR_KEYS[:len(report["action_box"]["low"])]
    fig, axes = _figure(len(keys), len(shapes), 6.0, 3.2)
    for column, geometry in enumerate(shapes):
        for index, velocity in enumerate(report["velocities"]):
            colour = PALETTE[index % len(PALETTE)]
            cells = _cells(report, geometry, velocity)
            for name, width, alpha in LEARNED_STYLE:
                label = f"V = {velocity:g} m/s" if name == "learned_deterministic" else None
                style = {"color": colour, "lw": width, "alpha": alpha}
                for run in cells.get(name, {"runs": []})["runs"]:
                    _draw_factors(axes[:, column], run, interval, style, label)
        baseline = report["baseline"]
        for row, key in enumerate(keys):
            ax = axes[row, column]
            if baseline is not None and baseline.get(key) is not None:
                ax.axhline(baseline[key], color="tab:green", ls="--", lw=1,
                           label="best constant" if row == 0 else None)
            ax.set_ylabel(rf"$\alpha_{key[-1]}$")
            ax.set_ylim(*_factor_limits(report, key))
            ax.set_xlabel("SIMPLE iteration")
            ax.grid(alpha=0.3)
        axes[0, column].set_title(f"learned factors, {geometry} (bold: mean action; thin: samples)",
                                  fontsize=10)
        if axes[0, column].get_legend_handles_labels()[0]:  # nothing to name without a learned run
            axes[0, column].legend(fontsize=7, loc="lower right")
    return _save(fig, path)


def _factor_limits(report: dict[str, Any], key: str) -> tuple[float, float]:
    """The training action box of one factor (and the best constant), with a margin."""
    index = FACTOR_KEYS.index(key)
    box = report["action_box"]
    baseline = report["baseline"]
    low, high = box["low"][index], box["high"][index]
    if baseline is not None and baseline.get(key) is not None:
        low, high = min(low, baseline[key]), max(high, baseline[key])
    return low - 0.03, high + 0.03


def _draw_factors(axes: np.ndarray, run: dict[str, Any], interval: int, style: dict[str, Any],
                  label: str | None) -> None:
    """One run's alpha_u (axes[0]) and alpha_p (axes[1]) as step lines; nothing for a run with no step."""
    if not run["actions"]:
        return
    for row, ax in enumerate(axes):
        edges, values = factor_steps(run["actions"], run["iterations"], interval, row)
        ax.step(edges, values, where="post", label=label if row == 0 else None, **style)
