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

This module is the episode's state machine (reset, step, the solver's faults, the confirmation restart,
the freeze near the criterion, the episode record). What it draws at reset is in
foam_bridge._episode_draws, how a solver event becomes an outcome in foam_bridge._outcomes, the
observation in foam_bridge._observation and the env directory's lock in foam_bridge._env_lock; the case
files, the solver process, the log and the action and observation boxes (foam_bridge._spaces) are in
their own modules.
"""

from __future__ import annotations

import math
import shutil
import time
from collections import OrderedDict
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from foam_bridge import _base_case as base_case
from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge._config import FoamEnvConfig, cost_per_iteration, failure_reward
from foam_bridge._confirm import confirm, meets, step_turbulence_factor
from foam_bridge._env_lock import claim_directory
from foam_bridge._episode_draws import episode_height, episode_velocity
from foam_bridge._episode_settle import answer_stop, episode_monitor
from foam_bridge._logparse import LogParser, criterion_distance, field_residual
from foam_bridge._observation import EpisodeObservation
from foam_bridge._openfoam import find_openfoam
from foam_bridge._outcomes import CASE_STOP, FAILURES, OUTCOMES, classify
from foam_bridge._records import EpisodeRecord
from foam_bridge._solver import PAUSED, FoamSolver
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
        self._lock = claim_directory(self.root)
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
        self._monitor = None  # the episode's answer monitor (FoamEnvConfig.settle)
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
        velocity = episode_velocity(self.cfg, self._rng, options or {}, self.base, self.openfoam)
        # the height is drawn after the velocity (see FoamEnvConfig.step_height)
        self._use_height(episode_height(self.cfg, self._rng, options or {}))
        episode_case.write_episode_case(self.base, self.case_dir, self.cfg, velocity, self.case_info,
                                         self.openfoam)
        self._monitor = episode_monitor(self.cfg, self.case_dir, self.case_info.solved_fields)
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
        self._episode = {"env_id": self.env_id, "seed": seed, "inlet_velocity": velocity,
                         "step_height": math.nan if self._height is None else self._height, "actions": [],
                         "return": 0.0, "steps": 0, "solver_idle_s": 0.0, "started": time.monotonic()}
        if self.cfg.confirm_alpha_u is not None:
            self._episode["confirmations"] = []
        self._done = self._frozen = False
        self._observed = EpisodeObservation(self.cfg, inlet, cells)
        self._factors = (np.asarray(self.cfg.action_low, np.float64) + np.asarray(self.cfg.action_high)) / 2
        self._obs = self._observed.vector(self._iterations, self._factors)
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
        outcome, cause, iterations = classify(event, code, self._parser, self.cfg, self._target)
        if self.cfg.confirm_alpha_u is not None:
            outcome, cause, iterations = self._confirmed(outcome, cause, iterations, alpha, text)
        stop = answer_stop(self._monitor, self._parser) if outcome == "running" else None
        if stop is not None:  # FoamEnvConfig.settle: the answer has settled, or oscillates steadily
            (outcome, cause), _ = stop, self._stop_solver()
        previous, self._iterations = self._iterations, max(iterations, self._iterations)
        spent, self._cost = self._cost, self._episode_cost()
        if outcome in FAILURES:
            rate = cost_per_iteration(self.cfg, self._cost, self._parser.completed)
            reward = failure_reward(self.cfg, previous, rate) * self.cfg.reward_scale
        else:
            reward = -(self._cost - spent) * self.cfg.reward_scale
        residuals = self._residuals()
        self._frozen = self._frozen or self._near_criterion(residuals)
        self._observed.update(outcome, residuals, self._parser)
        self._obs = self._observed.vector(self._iterations, self._factors)
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
            outcome, cause, iterations = classify(event, code, self._parser, self.cfg, self._target)

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


