"""One OpenFOAM case = one environment: the paper's solver-control MDP on a persistent simpleFoam.

MDP (Pawar & Maulik, "Solver convergence acceleration"):

- action: (alpha_u, alpha_p), or (alpha_u, alpha_p, alpha_t) with ``relax_k_omega="action"``, clipped
  into ``[action_low, action_high]`` (a bound's float32 value, as a float32 box or policy gives it, is
  that bound exactly: foam_bridge._spaces.clip_to_box); alpha_u relaxes the velocity equation (and
  k/omega when they follow it), alpha_p the pressure field, alpha_t the turbulence fields.
- observation: ``(mean_inlet |U|^2 + mean_cells |U|^2) / state_scale`` (arithmetic means over the inlet
  faces and over all cells, as the paper's state; ``state_scale`` = 44.2**2 by default, or the
  episode's inlet mean |U|^2 with ``scale_free_state``), then optionally the log10 initial residuals of
  the last ``residual_features`` step boundaries, K / max_iterations (``observe_progress``) and the
  factors in force (``observe_action``).
- reward: -(K_t - K_{t-1}), K = SIMPLE iterations actually run; the return is minus the total. With
  ``cfg.reward`` "linear-iterations" or "solver-time", K is that cost instead (the linear solvers'
  inner iterations, the solver's CPU seconds, as the log counts them up to iteration K).
- episode end: the solver's own ``SIMPLE.residualControl`` met (``converged``, terminated; with
  ``confirm_alpha_u`` only once a check at that relaxation confirms it, foam_bridge._confirm), the case's
  own runTimeControl function object ending the run (``converged`` too, by the case's criterion: its
  cause says which, CASE_STOP; no residual check, it did not stop on residuals), the
  ``max_iterations`` cap (outcome ``truncated``, but *terminated*: the cap is the task's budget, not a
  time limit, so the learner does not bootstrap past it and a capped run costs exactly its K, as much
  as a failure's default penalty charges; bootstrapping there would score reaching the cap below
  crashing), or a failure (terminated, reward :func:`failure_reward`):
  ``crashed`` (solver died, broken case), ``diverged`` (NaN/Inf or an initial residual above
  ``divergence_threshold``, or a state term above ``state_divergence_ratio`` x the inlet's |U|^2),
  ``hung`` (the step watchdog fired).
- K on failure is deterministic: the solver's whole output is read to EOF (after its death, or after
  the bridge killed it) before anything is accounted, and K is the iteration in which the failure shows
  in the log: the first bad iteration (diverged), the iteration the solver died in (crashed) or the
  last one it started (hung; only a watchdog that fires on a slow but live solver stays timing-
  dependent, by nature). The cause text names the same iteration.
- the observation is always finite float32: every entry is clipped into +-OBSERVATION_BOUND (1e6), a
  last line of defence; the state divergence check ends an episode long before (an observed state is
  at most 2 x state_divergence_ratio x the inlet's |U|^2 / state_scale, ~4.3e3 at the defaults and
  65 m/s).

One simpleFoam process runs per episode (no restarts: bit-identical to an uninterrupted run with
the same factors, tested). It pauses itself exactly between iterations K and K+1 for every K that is a
multiple of ``interval``: a function object touches fvSolution after iteration K, OpenFOAM v1912 re-reads
modified files right after executing function objects (before iteration K+1 starts), and fvSolution
#includes a FIFO from which the solver reads the relaxation factors; it blocks there until the bridge
writes them (foam_bridge._episode_case, foam_bridge._solver). So the action given at K governs iterations
K+1 .. K+interval, exactly as in the paper's restart-based MDP (tested: the residuals of iteration K+1
already change with the new factors). The first action of an episode is read at solver start-up.
The state of iteration K is printed by stock function objects before the pause, in full precision.

Why one module of ~530 lines: it is one class, the episode's state machine (reset, step, the
solver's faults, the confirmation restart, the freeze near the criterion, the episode record), whose
methods share its state; the case files, the solver process, the log and the action and observation
boxes (foam_bridge._spaces) are in their own modules already.
"""

from __future__ import annotations

import contextlib
import fcntl
import math
import os
import shutil
import signal
import time
from collections import OrderedDict, deque
from functools import partial
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from foam_bridge import _base_case as base_case
from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge._config import FoamEnvConfig, cost_per_iteration, failure_reward
from foam_bridge._confirm import confirm, meets, step_turbulence_factor
from foam_bridge._logparse import LogParser, criterion_distance, field_residual
from foam_bridge._openfoam import find_openfoam
from foam_bridge._records import EpisodeRecord
from foam_bridge._solver import DIVERGED, EXITED, HUNG, MISSED, PAUSED, FoamSolver
from foam_bridge._spaces import (
    BoxSpec,
    action_spec,
    action_values,
    bounded_observation,
    factors_of,
    observation_spec,
    shares_of,
)
from foam_bridge._work_dirs import work_root

#: Every value of ``info["outcome"]``.
OUTCOMES = ("running", "converged", "truncated", "crashed", "diverged", "hung")
#: Outcomes that are a failure of the solver (terminated, with the failure penalty).
FAILURES = ("crashed", "diverged", "hung")
#: The cause of a "converged" episode that the case's own function object ended (a runTimeControl with
#: ``satisfiedAction end``: its criterion, e.g. a settled force coefficient), followed by its name.
CASE_STOP = "ended by the case's own function object"
#: The observed gain's bound in decades (FoamEnvConfig.observe_gain): a blow-up or a restart's jump says
#: no more than "a great loss" or "a great gain".
GAIN_BOUND = 5.0
#: Lock file held (fcntl.flock) by the FoamCaseEnv that owns an env directory.
LOCK_FILE = ".foam_bridge.lock"
#: The sub-directory of an env directory that holds the running episode's case (read by the episode pool).
EPISODE_DIR = "episode"
#: Meshes of a step-height family one env keeps. A new height costs one blockMesh (template.mesh_builtin):
#: a reset took 0.40-0.44 s instead of 0.08-0.09 s at mesh 0.5-1.0 (measured on a busy 2-core machine),
#: against 3 s (mesh 0.5) to 30 s (full mesh) for an episode; continuous draws never repeat a height, so
#: the cache only spares repeats, e.g. an evaluation's fixed heights.
BASE_CACHE = 4

__all__ = ["CASE_STOP", "FAILURES", "OUTCOMES", "FoamCaseEnv", "action_spec", "bounded_observation",
           "factors_of", "failure_reward", "observation_spec", "shares_of"]


class FoamCaseEnv:
    """One case directory, one persistent simpleFoam per episode; gymnasium-style, host side.

    ``FoamCaseEnv(cfg, work_dir=None, env_id=0)`` validates ``cfg`` (``ValueError``), locates
    OpenFOAM (``foam_bridge._errors.OpenFOAMNotFoundError`` naming how to install it), checks a user's
    ``case_dir`` (``foam_bridge._errors.CaseError``, a ValueError) and builds the base case (mesh) once
    under ``<work_dir or cfg.work_dir or a temporary dir>/env_<env_id>``. Every episode runs in a fresh
    copy of that base case. The env holds an exclusive lock (``fcntl.flock`` on ``LOCK_FILE`` in that
    directory) until close(): a second FoamCaseEnv on the same directory, in this process or another,
    is a one-line ``ValueError`` instead of two envs deleting each other's cases. The kernel drops the
    lock when its process dies, so a restarted worker can take the directory over.

    ``reset(seed=None, options=None) -> (obs, info)``: ends any running episode (kills the solver's
    process group), samples the inlet velocity from the episode RNG (re-seeded when ``seed`` is given;
    seeded with ``env_id`` before the first seed, so runs are reproducible; ``options={"inlet_velocity":
    v}`` fixes it; a user's case without ``inlet_velocity`` keeps its own inlet, and "inlet_velocity"
    reports its speed, NaN if it has no value), then the step height when ``step_height`` is a range
    (``options={"step_height": x}`` fixes it; built-in case only), and writes the case. The
    observation is the initial state (iteration 0) read from 0/U. The solver starts on the first step.

    ``step(action) -> (obs, reward, terminated, truncated, info)``; ``info`` has "iterations" (K),
    "residuals" ({field: latest initial residual}), "outcome" (one of OUTCOMES), "cause" (failure text,
    CASE_STOP and the function object's name, or ""), "inlet_velocity", "factors" (those in force
    over the step: the action's, or the held ones once ``freeze_decades`` froze them), and "episode"
    (the episode record) on the step that ended the episode.
    ``terminated`` is True on every episode end, the ``max_iterations`` cap included; ``truncated`` is
    always False (the env has no time limit). Stepping a finished episode raises ``RuntimeError`` (no
    auto-reset here).

    ``close()`` kills the solver's whole process group and removes the case (unless keep_cases); the
    env is also a context manager that closes itself.
    """

    def __init__(self, cfg: FoamEnvConfig, work_dir: Path | str | None = None, env_id: int = 0,
                 base: tuple[Path, episode_case.CaseInfo] | None = None) -> None:
        """``base``: the base case already built and checked by the caller (a directory that
        :func:`foam_bridge._base_case.check_case` built from ``cfg`` and its CaseInfo): copied, not built and
        dry-run again (jaxsimrl solve checks a case once)."""
        self.cfg = cfg = cfg.validate().with_absolute_paths()
        self.env_id = env_id
        self.openfoam = find_openfoam(cfg.openfoam_path)
        parent, temporary = work_root(cfg, work_dir)
        self._tmp = parent if temporary else None
        self.root = parent / f"env_{env_id}"
        self._lock = _claim_directory(self.root)
        self.base = self.root / "base"
        self.case_dir = self.root / EPISODE_DIR
        try:
            if base is None:
                self.case_info = base_case.build_base_case(cfg, self.base, self.openfoam)
            else:
                shutil.rmtree(self.base, ignore_errors=True)  # a restarted worker's leftover
                shutil.copytree(base[0], self.base, symlinks=True)
                self.case_info = base[1]
        except BaseException:
            self._release_directories()
            raise
        self._height = cfg.fixed_height if cfg.builtin else None  # the step height of self.base
        self._bases: OrderedDict[float | None, tuple[Path, episode_case.CaseInfo]] = OrderedDict(
            {self._height: (self.base, self.case_info)})
        self._turbulence = episode_case.turbulence_fields(cfg, self.case_info)  # what alpha_t relaxes
        self._rng = np.random.default_rng(env_id)
        self._solver: FoamSolver | None = None
        self._episode: dict[str, Any] = {}
        self._done = True
        self._closed = False

    @property
    def observation_space_spec(self) -> BoxSpec:
        """Box of the observation: the scaled state (>= 0) then the log10 residual features."""
        return observation_spec(self.cfg)

    @property
    def action_space_spec(self) -> BoxSpec:
        """Box of the action (alpha_u, alpha_p[, alpha_t]): ``[action_low, action_high]``."""
        return action_spec(self.cfg)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start a new episode; returns the initial observation (iteration 0) and info."""
        self._stop_solver()
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        velocity = self._episode_velocity(options or {})
        self._use_height(self._episode_height(options or {}))  # drawn after the velocity (see config)
        episode_case.write_episode_case(self.base, self.case_dir, self.cfg, velocity, self.case_info,
                                         self.openfoam)
        inlet, cells = episode_case.initial_state(self.case_info, velocity)
        if velocity is None:  # the user's case keeps its inlet: report its speed (NaN if it has none)
            velocity = math.nan if self.case_info.inlet_speed is None else self.case_info.inlet_speed
        # the state limit is relative to this episode's inlet, so it is as tight at 25 m/s as at 75 m/s
        reference = max(inlet, cells, 0.0 if math.isnan(velocity) else velocity**2)
        state_limit = self.cfg.state_divergence_ratio * reference if reference > 0 else math.inf
        self._parser = LogParser(episode_case.CELLS_FUNCTION, episode_case.INLET_FUNCTION,
                                 self.cfg.divergence_threshold, state_limit, start=self.cfg.start_time)
        self._iterations = self._target = 0
        self._restart_at: int | None = None  # a failed check: the solver goes on from these fields
        self._unconfirmed = False  # a check has failed: the boundaries are checked from now on
        self._cost = 0.0
        self._features: deque[np.ndarray] = deque(
            [np.zeros(len(self.cfg.observed))] * self.cfg.residual_features,
            maxlen=self.cfg.residual_features or None)
        self._distance: float | None = None  # the criterion distance at the last step boundary
        self._gain = 0.0
        self._episode = {"env_id": self.env_id, "seed": seed, "inlet_velocity": velocity,
                         "step_height": math.nan if self._height is None else self._height, "actions": [],
                         "return": 0.0, "steps": 0, "solver_idle_s": 0.0, "started": time.monotonic()}
        if self.cfg.confirm_alpha_u is not None:
            self._episode["confirmations"] = []
        self._done = self._frozen = False
        # the scale-free state is relative to this episode's inlet (state_scale if it has none)
        self._scale = inlet if self.cfg.scale_free_state and inlet > 0 else self.cfg.state_scale
        self._state = (inlet + cells) / self._scale
        self._factors = (np.asarray(self.cfg.action_low, np.float64) + np.asarray(self.cfg.action_high)) / 2
        self._obs = self._observation()
        return self._obs.copy(), self._info("running", "", {})

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Run ``interval`` SIMPLE iterations with the given factors; see the class docstring."""
        if self._done:
            raise RuntimeError("step() on a finished episode: call reset() first")
        alpha = factors_of(self.cfg, action_values(action, self.cfg.action_size))
        if self._frozen:  # within freeze_decades of the criterion: the factors in force hold
            alpha = self._factors
        self._episode["actions"].append([float(a) for a in alpha])
        self._factors = alpha
        alpha_t = float(alpha[2]) if len(alpha) == 3 else None
        text = episode_case.relaxation_text(self.cfg, alpha[0], alpha[1], self.case_info.flat_relaxation,
                                         alpha_t, self._turbulence)
        event = self._advance(text)
        # stop before accounting: the whole output is then parsed, whatever had been read so far
        code = self._stop_solver() if event != PAUSED else None
        outcome, cause, iterations = self._classify(event, code)
        if self.cfg.confirm_alpha_u is not None:
            outcome, cause, iterations = self._confirmed(outcome, cause, iterations, alpha, text)
        previous, self._iterations = self._iterations, max(iterations, self._iterations)
        spent, self._cost = self._cost, self._episode_cost()
        if outcome in FAILURES:
            rate = cost_per_iteration(self.cfg, self._cost, self._parser.completed)
            reward = failure_reward(self.cfg, previous, rate) * self.cfg.reward_scale
        else:
            reward = -(self._cost - spent) * self.cfg.reward_scale
        residuals = self._residuals()
        self._frozen = self._frozen or self._near_criterion(residuals)
        self._update_observation(outcome, residuals)
        self._episode["return"] += reward
        self._episode["steps"] += 1
        info = self._info(outcome, cause, residuals)
        if outcome != "running":
            self._done = True
            info["episode"] = self._episode_record(outcome, cause, residuals)
        # every end is terminated, the cap included (module docstring); no time limit truncates
        return self._obs.copy(), reward, outcome != "running", False, info

    def __enter__(self) -> FoamCaseEnv:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Kill the solver's process group (no orphans) and remove the case directories."""
        self._stop_solver()
        self._done = True
        if not self._closed:
            self._release_directories()
        self._closed = True

    def _release_directories(self) -> None:
        """Remove the env's directories (unless keep_cases), then drop its lock."""
        if not self.cfg.keep_cases:
            shutil.rmtree(self.root, ignore_errors=True)
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)
        self._lock.close()  # after the removal: nobody else may build in the directory before

    @property
    def parser(self) -> LogParser:
        """The log parser of the current (or last) episode: residual history, state, counters."""
        return self._parser

    @property
    def solver_idle_s(self) -> float:
        """Seconds the current episode's solver has waited on the bridge (see FoamSolver.idle_s)."""
        return 0.0 if self._solver is None else self._solver.idle_s

    @property
    def solver_pgid(self) -> int | None:
        """Process-group id of the running solver (None between episodes); for tests and monitoring."""
        return None if self._solver is None else self._solver.pgid

    def _episode_velocity(self, options: dict[str, Any]) -> float | None:
        """This episode's inlet speed: the option, else drawn from the config's range; None: the case's."""
        if options.get("inlet_velocity") is not None:
            velocity = float(options["inlet_velocity"])
            if not (math.isfinite(velocity) and velocity > 0):
                raise ValueError(f"options['inlet_velocity']: expected a speed > 0, got {velocity!r}")
            if self.cfg.case_dir is not None and self.cfg.velocity_range is None:
                base_case.check_inlet_settable(self.base, self.cfg, self.openfoam)
            return velocity
        if self.cfg.velocity_range is None:
            return None
        return float(self._rng.uniform(*self.cfg.velocity_range))

    def _episode_height(self, options: dict[str, Any]) -> float | None:
        """This episode's step height: the option, else drawn from the config's range, else the fixed
        one (None: a user's case, whose mesh is its own)."""
        if options.get("step_height") is not None:
            height = float(options["step_height"])
            if not self.cfg.builtin:
                raise ValueError("options['step_height'] applies to the built-in backward-facing step only "
                                 "(a case of your own keeps its own mesh)")
            if not (math.isfinite(height) and height > 0):
                raise ValueError(f"options['step_height']: expected a height > 0 in m, got {height!r}")
            return height
        if self.cfg.height_range is None:
            return self.cfg.fixed_height if self.cfg.builtin else None
        return float(self._rng.uniform(*self.cfg.height_range))

    def _use_height(self, height: float | None) -> None:
        """Make ``self.base`` (and its CaseInfo) the mesh of ``height``: built when first met, the last
        BASE_CACHE kept (the oldest removed)."""
        if height == self._height:
            return
        if height in self._bases:
            self._bases.move_to_end(height)
        else:
            base = self.root / f"base-{height!r}"  # only the built-in case has heights
            template.mesh_builtin(self.cfg, base, self.openfoam, height)
            self._bases[height] = (base, self.case_info)
            while len(self._bases) > BASE_CACHE:
                shutil.rmtree(self._bases.popitem(last=False)[1][0], ignore_errors=True)
        self.base, self.case_info = self._bases[height]
        self._height = height

    def _advance(self, text: bytes) -> str:
        """Feed the factors and run to the next pause; returns the solver event.

        The next pause is exactly ``interval`` iterations on (or the cap): the solver either pauses
        there or the step ends with the event that says why not (see foam_bridge._solver).
        """
        deadline = time.monotonic() + self.cfg.step_timeout_s
        self._target = self._iterations + self.cfg.interval
        if self._solver is None:
            fifo = partial(episode_case.relaxation_fifo, self.case_dir)
            self._solver = FoamSolver(self.case_dir, self.openfoam, self._parser, fifo, self.cfg.ranks)
            if self._restart_at is not None:  # after a failed check: no start-up pause, these factors
                episode_case.write_restart(self.case_dir, self.base, self.cfg, self._restart_at, text)
                self._restart_at = None
                self._solver.start()
                return self._solver.wait(self.cfg.step_timeout_s, self._target)
            self._solver.start()
            event = self._solver.wait(self.cfg.step_timeout_s, 0)  # start-up: the first fvSolution read
            if event != PAUSED:
                return event
        self._solver.release(text)
        return self._solver.wait(max(deadline - time.monotonic(), 0.0), self._target)

    def _confirmed(self, outcome: str, cause: str, iterations: int, alpha: np.ndarray, text: bytes
                   ) -> tuple[str, str, int]:
        """A step's (outcome, cause, K) under the check relaxation cannot move (cfg.confirm_alpha_u).

        The solver's own test met at K is checked; so is every step boundary whose residuals meet the
        criterion once a check has failed. A failed check at K < the step's boundary lets the solver go
        on from the fields of K with the step's factors, within this step.
        """
        if outcome == "converged" and cause.startswith(CASE_STOP):
            return outcome, cause, iterations  # the case's function object's criterion: no residual to check
        while True:
            at_boundary = outcome == "running" and self._unconfirmed and meets(self.cfg, self._residuals())
            if outcome != "converged" and not at_boundary:
                return outcome, cause, iterations
            check = confirm(self.case_dir, self.base, self.cfg, self.openfoam, iterations, float(alpha[1]),
                            self._residuals(), self.case_info.flat_relaxation, self._turbulence,
                            step_turbulence_factor(self.cfg, alpha))
            self._episode["confirmations"].append(check.record())
            if check.passed:
                self._stop_solver()
                return "converged", "", iterations
            self._unconfirmed = True
            if at_boundary:
                return outcome, cause, iterations
            self._parser.converged_at = None
            self._restart_at = iterations
            if iterations >= self._target:
                return "running", "", iterations
            event = self._advance(text)
            code = self._stop_solver() if event != PAUSED else None
            outcome, cause, iterations = self._classify(event, code)

    def _classify(self, event: str, code: int | None) -> tuple[str, str, int]:
        """(outcome, cause, K) of a solver event, from the fully parsed output of a stopped solver.

        A divergence in the log wins over the event that stopped the solver (a watchdog that fired
        while a NaN was still in the pipe is a divergence), so the outcome does not depend on timing.
        """
        parser, cfg = self._parser, self.cfg
        if event == PAUSED:
            return "running", "", parser.completed
        if parser.failed_at is not None:
            return "diverged", f"diverged: {parser.diverged}", parser.failed_at
        if event == MISSED or parser.completed > self._target:
            return "crashed", (f"missed the pause after iteration {self._target}: the solver went on to "
                               f"iteration {parser.completed} without reading its next factors"), \
                min(parser.completed, self._target)
        if event == HUNG:
            return "hung", (f"watchdog: no progress within step_timeout_s={cfg.step_timeout_s} s "
                            f"(last iteration started: {parser.iteration})"), parser.iteration
        assert event in (EXITED, DIVERGED)
        if parser.converged_at is not None:
            return "converged", "", parser.converged_at
        if parser.stopped_at is not None and code == 0:  # the case's own criterion, not residualControl's
            return "converged", f"{CASE_STOP} {parser.stopped_by} (runTimeControl)", parser.stopped_at
        if code == 0 and parser.completed >= cfg.max_iterations:
            return "truncated", "", parser.completed
        detail = parser.error or "no error message"
        if code is not None and code < 0:
            detail = f"killed by {signal.Signals(-code).name}; {detail}"
        elif code == 0:
            detail = "it ended without converging before max_iterations"
        cause = f"simpleFoam exited with code {code} at iteration {parser.iteration}: {detail}"
        return "crashed", cause, parser.iteration

    def _episode_cost(self) -> float:
        """The episode's cost so far in the reward's unit (cfg.reward; see FoamEnvConfig.reward)."""
        if self.cfg.reward == "linear-iterations":
            return float(self._parser.linear_iterations)
        if self.cfg.reward == "solver-time":
            return float(self._parser.execution_time)
        return float(self._iterations)

    def _residuals(self) -> dict[str, float]:
        found = {name: field_residual(self._parser.residuals, name) for name in self.cfg.convergence}
        return {name: float(value) for name, value in found.items() if value is not None}

    def _near_criterion(self, residuals: dict[str, float]) -> bool:
        """Whether the run is within cfg.freeze_decades of its criterion (False when it is None)."""
        limit = self.cfg.freeze_decades
        return limit is not None and criterion_distance(residuals, self.cfg.convergence) <= limit

    def _update_observation(self, outcome: str, residuals: dict[str, float]) -> None:
        if self.cfg.residual_features:
            # the observed fields, which need not be the criterion's (FoamEnvConfig.observed_fields): the
            # parser holds every solved field's residual; a field not solved reads as 1 (log 0)
            solved = self._parser.residuals
            levels = [residuals.get(name, field_residual(solved, name)) for name in self.cfg.observed]
            logs = [np.log10(max(level, 1e-30)) if level is not None and np.isfinite(level) else 0.0
                    for level in levels]
            self._features.append(np.asarray(logs))
        self._note_gain(residuals)
        parser = self._parser
        # a failed step keeps the last state read (the solver's last one may be a blow-up)
        inlet = parser.inlet_state if self.cfg.inlet_patch is not None else 0.0  # no inlet: the cells alone
        if outcome not in FAILURES and inlet is not None and parser.cells_state is not None:
            self._state = (inlet + parser.cells_state) / self._scale
        self._obs = self._observation()

    def _note_gain(self, residuals: dict[str, float]) -> None:
        """The last step's gain (FoamEnvConfig.observe_gain); a step without residuals keeps the last."""
        if not residuals:
            return
        distance = criterion_distance(residuals, self.cfg.convergence)
        if not np.isfinite(distance):
            return
        if self._distance is not None:
            self._gain = float(np.clip(self._distance - distance, -GAIN_BOUND, GAIN_BOUND))
        self._distance = distance

    def _observation(self) -> np.ndarray:
        """state, residual features, progress, factors in force (FoamEnvConfig's observation layout)."""
        cfg = self.cfg
        parts = [np.array([self._state])] if cfg.observe_state else []
        parts += list(self._features) if cfg.residual_features else []
        if cfg.observe_progress:
            parts.append(np.array([self._iterations / cfg.max_iterations]))
        if cfg.observe_algorithm:
            parts.append(np.array([float(cfg.variant == "SIMPLEC")]))
        if cfg.observe_action:  # as the policy acts: a share of the box with action_share
            parts.append(shares_of(cfg, self._factors))
        if cfg.observe_gain:
            parts.append(np.array([self._gain]))
        return bounded_observation(np.concatenate(parts))

    def _info(self, outcome: str, cause: str, residuals: dict[str, float]) -> dict[str, Any]:
        return {"iterations": self._iterations, "residuals": residuals, "outcome": outcome,
                "factors": [float(a) for a in self._factors],
                "cause": cause, "inlet_velocity": self._episode["inlet_velocity"],
                "step_height": self._episode["step_height"]}

    def _episode_record(self, outcome: str, cause: str, residuals: dict[str, float]) -> dict[str, Any]:
        episode = self._episode
        return EpisodeRecord(
            outcome=outcome, cause=cause, iterations=self._iterations, seed=episode["seed"],
            inlet_velocity=episode["inlet_velocity"], step_height=episode["step_height"],
            actions=episode["actions"], episode_return=episode["return"],
            linear_iterations=self._parser.linear_iterations, solver_time_s=self._parser.execution_time,
            wall_time_s=time.monotonic() - episode["started"], solver_idle_s=episode["solver_idle_s"],
            residuals=residuals, env_id=episode["env_id"], confirmations=episode.get("confirmations"),
        ).to_json()

    def _stop_solver(self) -> int | None:
        """Kill the solver (its output read to EOF); its exit status, None if none was running."""
        if self._solver is None:
            return None
        self._episode["solver_idle_s"] = self._solver.idle_s
        code = self._solver.kill()
        self._solver = None
        return code


def _claim_directory(root: Path) -> BinaryIO:
    """Create ``root`` and take the exclusive lock on its LOCK_FILE; returns the open lock file.

    One-line ValueError if another live FoamCaseEnv holds it. The lock lives as long as the file
    object (closed by close(), by garbage collection, or by the kernel when the process dies). If the
    owner removed the directory between our open and our lock (its close()), the lock is on a dead
    file: retry on the new one.
    """
    while True:
        root.mkdir(parents=True, exist_ok=True)
        path = root / LOCK_FILE
        try:
            lock = open(path, "ab")  # noqa: SIM115 (held until FoamCaseEnv.close)
        except FileNotFoundError:
            continue  # the directory vanished under us
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            raise ValueError(f"env directory {root} is in use by another FoamCaseEnv (same work_dir "
                             f"and env_id); give each env its own env_id or work_dir") from None
        with contextlib.suppress(FileNotFoundError):
            if os.path.samestat(os.fstat(lock.fileno()), os.stat(path)):
                return lock
        lock.close()
