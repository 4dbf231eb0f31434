"""eval-foam's protocol: what is evaluated (EvalSpec), the controllers' names, the configs of the runs.

The protocol (Pawar & Maulik, "Solver convergence acceleration", test): inlet velocities 25, 50 and
75 m/s (25 and 75 lie outside the training range), the test criterion (TEST_CONVERGENCE), step heights
h and 2h, the full mesh. Every other case setting (SIMPLE variant, k/omega relaxation, interval,
action box, residual features, iteration cap, ...) is the training run's own.

Controllers, all in the same run (see foam_controllers):

- ``learned_deterministic``: the policy's mean action; one run per (geometry, velocity): the solver is
  deterministic, so repeats would be identical;
- ``learned_stochastic``: actions sampled from the policy, ``samples`` runs (the paper: 10);
- ``best_constant``: the converged cell with the fewest iterations of a grid-foam grid.csv (of a grid
  over several conditions: the cell best for that family, jaxsimrl.apps.foam.evaluation.family), or of a small
  grid eval-foam runs itself at the first velocity on the first geometry; one run per cell;
- ``tutorial_defaults``: the tutorial's (U 0.9, p 0.8, and on a run with the k/omega action k/omega
  0.8, backwardFacingStep2D's ".*" 0.8; a 2-action run keeps its own k/omega factor); one run;
- ``random``: factors uniform in the action box at every step, ``samples`` runs (the paper's baseline);
- ``residual_rule`` and ``bandit`` (only when asked for): ``jaxsimrl solve``'s no-training rules
  (jaxsimrl.apps.foam.solve.rules), starting from the tutorial's defaults, in the training box, each at its
  own step length (the protocol's other controllers act every ``interval`` iterations); one run per cell;
- ``case_oracle`` (only when asked for: it costs a grid per case): the best constant of a grid on each
  test case itself, and what that grid cost (foam_oracle).

With ``reference_iterations`` N, every (geometry, velocity) first gets a reference run: the best
constant (the tutorial's defaults without one) for exactly N iterations, with no convergence test.
Every run then reports ``u_error``, the relative L2 distance of the U field it ended with from that
reference (foam_bridge._fields says why iterations alone can mislead). With ``reference_cache`` the
references are reused from (and stored in) a directory (foam_reference_cache).

Every episode's uid is a hash of (controller, geometry, velocity, sample); it seeds the episode's
random actions, so the same command gives the same numbers, and an episode stays the same when other
velocities, geometries or samples are added to the command. foam_eval.evaluate_foam runs it and
writes ``eval.json``, ``eval.csv`` and the figures (foam_report, foam_plots).
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from foam_bridge import STEP_HEIGHT_H, TEST_CONVERGENCE, FoamEnvConfig, grid_config
from jaxsimrl.apps.foam.evaluation import oracle as foam_oracle

EVAL_DIR = "eval"
EVAL_JSON = "eval.json"
EVAL_CSV = "eval.csv"
GRID_CSV = "baseline_grid.csv"
GRID_PNG = "baseline_grid.png"
DEFAULT_VELOCITIES = (25.0, 50.0, 75.0)
DEFAULT_STEP_HEIGHTS = (STEP_HEIGHT_H, 2 * STEP_HEIGHT_H)
#: The grid eval-foam runs for the best constant when no --baseline-grid is given (both axes).
DEFAULT_GRID = (0.8, 0.9, 0.95)
#: backwardFacingStep2D's own relaxation factors (U 0.9, p 0.8; k and omega as the case sets them).
TUTORIAL_DEFAULTS = (0.9, 0.8)
#: Controller keys, in the order of tables and figures.
CONTROLLERS = ("learned_deterministic", "learned_stochastic", "best_constant", "tutorial_defaults", "random",
               "residual_rule", "bandit", foam_oracle.ORACLE)
#: Those run without --controllers: the oracle's grid per case and the rules are run only when asked.
DEFAULT_CONTROLLERS = CONTROLLERS[:5]
#: The no-training rules of the protocol, by the name jaxsimrl.apps.foam.solve.rules gives them.
RULE_CONTROLLERS = {"residual_rule": "residual-rule", "bandit": "bandit"}
#: FoamEnvConfig fields left out of the report's "case": they vary per cell, or the report gives them
#: apart ("action_box": the training box; the env's own box is widened to hold the constants).
CASE_OMITTED = ("work_dir", "keep_cases", "step_height", "inlet_velocity", "action_low", "action_high")
CSV_COLUMNS = ("controller", "geometry", "step_height", "velocity", "sample", "outcome", "cause",
               "iterations", "wall_time_s", "cpu_time_s", "linear_iterations", "p_linear_iterations",
               "u_error", "failed_checks", "steps", "actions")
#: Controller name of the reference runs (not a controller of the protocol: no row in the tables).
REFERENCE = "reference"


@dataclass(frozen=True)
class EvalSpec:
    """What to evaluate and how; ``step_heights=None`` -> h and 2h (a user's case: its own geometry)."""

    run_dir: Path
    velocities: tuple[float, ...] = DEFAULT_VELOCITIES
    step_heights: tuple[float, ...] | None = None
    mesh_scale: float = 1.0
    samples: int = 10
    pool: int = 1
    seed: int = 0
    baseline_grid: Path | None = None
    grid_alpha_u: tuple[float, ...] = DEFAULT_GRID
    grid_alpha_p: tuple[float, ...] = DEFAULT_GRID
    #: alpha_t of that grid for a run with the k/omega action (None: the paper's 0.8 only).
    grid_alpha_t: tuple[float, ...] | None = None
    out: Path | None = None
    controllers: tuple[str, ...] = DEFAULT_CONTROLLERS
    reference_iterations: int | None = None
    #: A directory of reference runs to reuse and add to (foam_reference_cache); None: run them all.
    reference_cache: Path | None = None
    #: FoamEnvConfig.confirm_alpha_u of every run (None: the training config's own, the paper's test).
    confirm_alpha_u: float | None = None
    #: Axes of the per-case oracle's grid (None: --baseline-grid's, else the small grid's; foam_oracle).
    oracle_alpha_u: tuple[float, ...] | None = None
    oracle_alpha_p: tuple[float, ...] | None = None
    oracle_alpha_t: tuple[float, ...] | None = None

    def validate(self) -> EvalSpec:
        """One-line ValueError naming the first bad field; returns self."""
        _positive("velocities", self.velocities)
        if self.step_heights is not None:
            _positive("step_heights", self.step_heights)
            _distinct("step_heights", [geometry_name(h) for h in self.step_heights])
        _distinct("velocities", [f"{v:g}" for v in self.velocities])
        _positive("mesh_scale", (self.mesh_scale,))
        unknown = [c for c in self.controllers if c not in CONTROLLERS]
        if not self.controllers or unknown:
            raise ValueError(f"controllers must be some of {', '.join(CONTROLLERS)}, got "
                             f"{list(self.controllers)}")
        _distinct("controllers", self.controllers)
        if self.confirm_alpha_u is not None and not 0 < self.confirm_alpha_u < 1:
            raise ValueError(f"confirm_alpha_u must be a relaxation factor in (0, 1), "
                             f"got {self.confirm_alpha_u!r}")
        if self.reference_cache is not None:
            if self.reference_iterations is None:
                raise ValueError("reference_cache needs reference_iterations (there are no references to "
                                 "cache without it)")
            if Path(self.reference_cache).exists() and not Path(self.reference_cache).is_dir():
                raise ValueError(f"reference_cache {self.reference_cache}: exists and is not a directory")
        optional = ("reference_iterations",) if self.reference_iterations is not None else ()
        for name in ("samples", "pool", *optional):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        given = [n for n in ("grid_alpha_t", "oracle_alpha_u", "oracle_alpha_p", "oracle_alpha_t")
                 if getattr(self, n) is not None]
        if any(n.startswith("oracle") for n in given) and foam_oracle.ORACLE not in self.controllers:
            raise ValueError(f"oracle_alpha_u/p/t set the grid of the {foam_oracle.ORACLE} controller: add "
                             "it to the controllers, or leave them out")
        for name in ("grid_alpha_u", "grid_alpha_p", *given):
            values = getattr(self, name)
            if not values or not all(math.isfinite(v) and 0 < v <= 1 for v in values):
                raise ValueError(f"{name}: relaxation factors must be in (0, 1], got {list(values)}")
        return self

    @property
    def output_dir(self) -> Path:
        return Path(self.out) if self.out is not None else Path(self.run_dir) / EVAL_DIR


def _positive(name: str, values: Sequence[float]) -> None:
    if not values or not all(isinstance(v, int | float) and math.isfinite(v) and v > 0 for v in values):
        raise ValueError(f"{name} must be numbers > 0, got {list(values)}")


def _distinct(name: str, labels: Sequence[str]) -> None:
    if len(set(labels)) != len(labels):
        raise ValueError(f"{name} must be distinct, got {list(labels)}")


def geometry_name(step_height: float | None) -> str:
    """"h", "2h", "1.5h" for the built-in case's step heights; "case" for a user's case (None)."""
    if step_height is None:
        return "case"
    ratio = step_height / STEP_HEIGHT_H
    return "h" if math.isclose(ratio, 1.0) else f"{ratio:.4g}h"


def geometries(spec: EvalSpec, train: FoamEnvConfig) -> dict[str, float | None]:
    """Geometry name -> step height (None: a user's case, whose geometry is its own)."""
    if train.case_dir is not None:
        if spec.step_heights is not None:
            raise ValueError("step heights apply to the built-in case only; this run trained on "
                             f"{train.case_dir}")
        return {"case": None}
    heights = DEFAULT_STEP_HEIGHTS if spec.step_heights is None else spec.step_heights
    return {geometry_name(h): float(h) for h in heights}


def eval_config(train: FoamEnvConfig, spec: EvalSpec, step_height: float | None,
                constants: Sequence[tuple[float, float]]) -> FoamEnvConfig:
    """The training config under the test protocol: test criterion (checked at the spec's
    confirm_alpha_u, if it has one), this geometry and the spec's mesh; its action box widened to hold
    the constant factors (they must not be clipped; learned and random actions lie in the training box
    anyway)."""
    cfg = dataclasses.replace(train, mesh_scale=spec.mesh_scale, convergence=dict(TEST_CONVERGENCE),
                              work_dir=None, keep_cases=False)
    if spec.confirm_alpha_u is not None:
        cfg = dataclasses.replace(cfg, confirm_alpha_u=spec.confirm_alpha_u)
    if step_height is not None:
        cfg = dataclasses.replace(cfg, step_height=step_height)
    third = [c[2] for c in constants] if cfg.action_size == 3 else None
    return grid_config(cfg, [c[0] for c in constants], [c[1] for c in constants], third)


def episode_uid(controller: str, geometry: str, velocity: float, sample: int) -> int:
    """A stable 31-bit id of one episode of the protocol (it seeds the episode)."""
    return zlib.crc32(f"{controller}/{geometry}/{velocity:g}/{sample}".encode()) & 0x7FFFFFFF
