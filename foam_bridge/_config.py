"""FoamEnvConfig: every constant of one simpleFoam solver-control environment.

The environment (Pawar & Maulik, "Solver convergence acceleration"): a steady simpleFoam run of a 2D
turbulent backward-facing step (k-omega SST). Every ``interval`` SIMPLE iterations the agent sets the
under-relaxation factors (alpha_u, alpha_p); the reward is -(K_t - K_{t-1}), K = SIMPLE iterations run,
so an episode's return is minus its total iterations (or minus another cost of the run: ``reward``).

The config is a frozen dataclass: it is hashable by identity of its values, picklable (it travels to
worker processes) and validated by :meth:`FoamEnvConfig.validate`, which raises a one-line
``ValueError`` naming the bad field. Constructing a config does not validate it (so that
``dataclasses.replace`` chains stay cheap); :class:`foam_bridge._env.FoamCaseEnv` validates on
construction. :meth:`FoamEnvConfig.to_json` / :meth:`FoamEnvConfig.from_json` are its one JSON codec (the
"foam" section of a train-foam run's config.json).

Over 450 lines (~550) because it is one dataclass whose docstring documents each of its ~45 fields (~190
lines), with its validation, its derived properties and its codec, which belong together; the reward
helpers below are a few lines each.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

#: The paper's reference velocity (m/s); the observation divides |U|^2 by U_REF**2.
U_REF = 44.2
#: The tutorial's (and the paper's) step height h in metres.
STEP_HEIGHT_H = 0.0127
#: The paper's training criterion: initial residuals of U, k, omega < 1e-3 and p < 5e-2.
TRAIN_CONVERGENCE: Mapping[str, float] = MappingProxyType({"U": 1e-3, "k": 1e-3, "omega": 1e-3, "p": 5e-2})
#: The paper's test criterion: U, k, omega < 5e-4 (p < 5e-2).
TEST_CONVERGENCE: Mapping[str, float] = MappingProxyType({"U": 5e-4, "k": 5e-4, "omega": 5e-4, "p": 5e-2})

#: A convergence threshold no residual meets: a run with it goes on to its iteration count.
NEVER_CONVERGED = 1e-30

SIMPLE_VARIANTS = ("SIMPLE", "SIMPLEC")
#: The action's entries, in order (the third only with relax_k_omega="action").
ACTION_NAMES = ("alpha_u", "alpha_p", "alpha_t")
#: ``relax_k_omega`` value that relaxes the turbulence fields with alpha_u (the agent's momentum factor).
FOLLOW_ALPHA_U = "alpha_u"
#: ``relax_k_omega`` value that makes the turbulence fields' factor a third action, alpha_t.
K_OMEGA_ACTION = "action"
#: The built-in action box per factor (the paper's): [0.2, 0.95] for alpha_u, alpha_p (and alpha_t).
BUILTIN_ACTION_BOUNDS = (0.2, 0.95)
#: The built-in case's defaults, the paper's code's (and the tutorial's): SIMPLEC, k/omega relaxed at
#: 0.8, inlet speed uniform in [35, 65] m/s, inlet turbulence from intensity 6.1e-4 and nu_t/nu 0.009.
BUILTIN_SIMPLE_VARIANT = "SIMPLEC"
BUILTIN_RELAX_K_OMEGA = 0.8
BUILTIN_INLET_VELOCITY = (35.0, 65.0)
PAPER_INLET_TURBULENCE = (6.1e-4, 0.009)
#: Smallest mesh_scale of the built-in case measured usable (see FoamEnvConfig.mesh_scale).
MESH_SCALE_USABLE_MIN = 0.4
#: The costs a reward can count (FoamEnvConfig.reward): SIMPLE iterations (the paper's), the linear
#: solvers' inner iterations (every "No Iterations" of the log) or the solver's own CPU seconds.
REWARDS = ("iterations", "linear-iterations", "solver-time")
#: What a controller's share 0.5 stands for on a case (FoamEnvConfig.pivot_at).
PIVOTS = ("family", "own")
#: Every observation entry is clipped into [-OBSERVATION_BOUND, OBSERVATION_BOUND] (NaN -> the bound):
#: the last line of defence for a learner's normaliser; divergence detection ends episodes long before.
OBSERVATION_BOUND = 1e6


@dataclass(frozen=True)
class FoamEnvConfig:
    """Configuration of one simpleFoam solver-control environment.

    Case:
        case_dir: ``None`` -> the built-in backward-facing step template (foam_bridge/cases/
            backward_facing_step, derived from OpenFOAM's backwardFacingStep2D tutorial); otherwise the
            path of a user's simpleFoam case (``system/``, ``constant/`` with a mesh or a
            ``system/blockMeshDict``, and ``0/``). The user's case is copied, never modified.
        mesh_scale: resolution factor of the built-in case: every block's cell count is multiplied by it
            and rounded (at least 1 cell per direction). 1.0 = the tutorial's 20,540 cells; 0.4 gives
            3,276 cells, 0.5 gives 5,024. Use >= MESH_SCALE_USABLE_MIN (0.4; the tests use 0.4): measured
            at 50 m/s, 0.25 (1,264 cells) and 0.3 (1,866) diverge or oscillate to the cap with the
            high factors that are best on the full mesh ((0.95, 0.95) SIMPLEC; plain SIMPLE diverges
            with alpha_u >= 0.7 up to 0.35), and converge only with some low ones, so they are a
            different control problem; 0.35 is borderline. Ignored for a user's case.
        step_height: step height in metres of the built-in case. 0.0127 (h) is the paper's training
            geometry, 0.0254 (2h) its second test geometry: only the step is deepened (the downstream
            floor moves down), the inlet channel and the domain length stay the same. A ``(low, high)``
            range: a family of geometries, the height drawn uniformly per episode from the seeded
            episode RNG *after* the inlet velocity (so a fixed height draws exactly the velocities it
            always drew); ``reset(options={"step_height": x})`` fixes it for one episode. Each height's
            mesh is built by blockMesh when first met and a few are kept (foam_bridge._env).
        inlet_velocity: inlet speed in m/s: a ``(low, high)`` range sampled uniformly per episode from
            the seeded episode RNG, or a fixed float. ``reset(options={"inlet_velocity": v})``
            overrides it for one episode. ``None`` (default): the built-in case samples
            BUILTIN_INLET_VELOCITY (35-65 m/s); a user's case keeps its own inlet (changing it is
            opt-in; it needs a ``fixedValue`` inlet, whose direction is kept).
        inlet_turbulence: ``(intensity I, nu_t/nu)``: when the inlet speed is set, the inlet k and omega
            (fixedValue entries) become ``k = 1.5 (I U)^2`` and ``omega = k / (nu_t/nu * nu)``, with
            ``nu`` read from the case's constant/transportProperties. ``None`` (default): the built-in
            case uses PAPER_INLET_TURBULENCE (and also sets the internal k and omega); a user's case
            keeps its own turbulence boundary conditions.
        inlet_patch: name of the inlet patch (its U is set and its mean |U|^2 is observed); None for a
            case without an inlet (a cavity, a closed mixer): the state is the cells' mean |U|^2 alone and
            the inlet speed cannot be set.
        velocity_field, pressure_field: names of the fields relaxed by alpha_u and alpha_p.
        turbulence_fields: fields relaxed by ``relax_k_omega``, and set by ``inlet_turbulence``.
        simple_variant: "SIMPLE" (``consistent no``) or "SIMPLEC" (``consistent yes``). ``None``
            (default): SIMPLEC for the built-in case, the case's own choice for a user's case.
        start_time: the time directory of a user's case its episodes start from (0: ``0/``; a later
            one: a partly converged run goes on from its fields, as ``startFrom latestTime`` would).
            Iterations K are counted from it (the solver's time is start_time + K; the pauses, the
            budget, the writes and the confirmation's time directories follow), and the base case
            keeps that directory, without its ``uniform/time`` (its time index then counts from 0 at
            start_time, so that the writes every ``max_iterations`` or ``interval`` iterations of K
            fall where they do from 0). An integer: the bridge runs deltaT 1.
        ranks: MPI ranks of the episode's solver (1: plain simpleFoam; N > 1: the episode case is
            decomposed into N subdomains and runs ``mpirun -np N simpleFoam -parallel``, see
            foam_bridge._parallel). A user's case only.

    MDP:
        interval: SIMPLE iterations per env step (the paper: 100).
        max_iterations: iteration cap; reaching it ends the episode (outcome ``truncated``, terminated).
        action_low, action_high: box of the action (:attr:`action_size` entries: alpha_u, alpha_p and,
            with ``relax_k_omega="action"``, alpha_t); actions are clipped into it. Default: the
            built-in case's [0.2, 0.95]^2, which becomes [0.2, 0.95]^3 with the third action (any other
            box must have action_size entries); for a user's case foam_bridge._user_case.case_defaults
            gives a box its algorithm tolerates (train-foam applies it to ``--case``).
        relax_k_omega: relaxation factor of the turbulence fields: a float (fixed), FOLLOW_ALPHA_U
            (``"alpha_u"``: the agent's momentum factor) or K_OMEGA_ACTION (``"action"``: a third
            action alpha_t relaxes them; on a user's case "them" are the fields its dry run solved
            besides the velocity and pressure, e.g. k and epsilon). ``None`` (default): 0.8 for the
            built-in case, the case's own factors for a user's case. Every other field keeps the
            case's own factor.
        convergence: field -> threshold on the solver's initial residual (vector fields: the largest
            component), as simpleFoam's own ``SIMPLE.residualControl``. Default: the paper's training
            criterion (TRAIN_CONVERGENCE); TEST_CONVERGENCE is its test criterion. A user's case's own
            residualControl: foam_bridge._user_case.case_defaults (train-foam applies it to ``--case``).
        confirm_alpha_u: a convergence test that relaxation cannot move. simpleFoam normalises each
            initial residual with the relaxed matrix, whose diagonal grows as 1/alpha_u, so lowering
            alpha_u lowers the residuals the criterion reads at once, field unchanged (on 2h at 50 m/s,
            alpha_u 0.2 met the test criterion at a U field 21 % from the solution,
            experiments/foam/README.md). ``None`` (default, the paper's): converged when the solver's
            own test is met. A factor in (0, 1), e.g. 0.9 (the tutorial's alpha_u): the criterion must
            also hold for the residuals normalised at that relaxation. When the solver meets it at K,
            the bridge runs one SIMPLE iteration from the fields of K in a scratch copy, with this
            alpha_u (the step's alpha_p, the case's k/omega factor), and reads its initial residuals
            (foam_bridge._confirm). If they meet the criterion the episode is converged at K. If not,
            the solver restarts from the fields of K with the step's factors and without its own
            test, and the check runs at every later step boundary whose residuals meet the criterion;
            the first one that passes ends the episode (converged at that boundary). Every check is
            in the episode record's "confirmations".
        confirm_alpha_t: the check's factor for the turbulence fields when alpha_t is an action
            (``relax_k_omega`` "action"); ``None`` (default): ``confirm_alpha_u``. solve
            sets the case's own turbulence factor, so that k/epsilon/omega are held to the normalisation
            the user's own run reads, as U is: checked at the own alpha_u, a SIMPLEC case whose own
            turbulence factor is below its alpha_u (0.77 and 0.89) failed the check at its own factors,
            and its run went on to the next step boundary (1.10-1.21x own iterations on 4 of 12
            generated cases;
            experiments/controller/generated-v1-setup/control-overhead-alpha-u-check.jsonl).
        residual_features: extra observation entries: log10 of the latest initial residual of each
            observed field (:attr:`observed`) at each of the last N step boundaries (0 = the paper's 1-D
            state; before the first boundaries: 0). Their trends are the differences of these levels,
            which the policy's first (linear) layer forms exactly, so they are not observed separately.
        observed_fields: the fields whose residuals the residual features hold, in order. ``None``
            (default): the ``convergence`` fields in its order (every run before this field). Set apart
            from the criterion so that a controller run on a user's case (jaxsimrl solve) sees the
            fields it was trained on, in its order, while the case keeps its own criterion; a field
            the solver does not solve reads as a residual of 1 (log 0).
        observe_progress: one more observation entry, K / max_iterations (0 at reset, 1 at the cap).
        observe_action: action_size more entries, the factors in force (the last action after
            clipping; at reset, before any action: the box centre (action_low + action_high) / 2).
        observe_gain: one more entry, after the factors: the last step's gain, the decades by which the
            criterion distance (the worst criterion field's log10(residual / threshold)) fell over it
            (negative where it rose; 0 at reset and after the first step; clipped to +-5). With the
            factors in force it says what the last choice earned on this case, so a recurrent policy
            can probe and settle within one run (issue 47); residual features hold levels, not the
            criterion's distance, which differs by case.
        scale_free_state: the state is divided by the episode's own inlet mean |U|^2 (at reset)
            instead of ``state_scale``: 1 + mean_cells |U|^2 / mean_inlet |U|^2, the same at 10 and
            50 m/s for similar flows (a user's case whose inlet has no value: ``state_scale``).
            Observation layout: state, residual features, progress, algorithm, action, gain.
        state_scale: the observed state is (mean_inlet |U|^2 + mean_cells |U|^2) / state_scale
            (default U_REF**2 = 44.2**2, so the state is O(1)).
        observe_state: False leaves the flow state out of the observation (a controller for many
            geometries, or a case without an inlet: the state's scale is one flow's).
        observe_algorithm: one more observation entry after the progress: 1 for SIMPLEC, 0 for plain
            SIMPLE (``simple_variant`` must then be set), so one controller can act on both.
        action_share: the action is a share of the box, a in [0, 1] per factor, and the factors are
            action_low + a (action_high - action_low) (:func:`factors_of`): one controller acts in each
            case's own box (plain SIMPLE's is the case's own factors' neighbourhood,
            foam_bridge._user_case), where absolute factors would mean a different thing in each.
        action_pivot: with ``action_share``, the factors at share 0.5 (the case's own, so that one
            controller's "0.5" is every case's own settings, above it more aggressive, below more
            cautious); the map is linear from action_low to it and from it to action_high. None: linear
            over the whole box.
        action_radius: with ``action_share``, the factors at share a are pivot + (2a - 1) x
            action_radius, clipped into the box (the pivot: ``action_pivot``, else the box's centre):
            one share moves every factor alike both ways. The piecewise map above moves alpha_u below a
            pivot of 0.7 in a box from 0.2 twice as far as above it, so a policy's symmetric exploration
            around share 0.5 drifts cautious (issue 47: experiments/controller/generated-v1-setup/
            exploration.py). None: that piecewise map.
        pivot_at: what a controller's share 0.5 stands for on a case of its own (the application's rule
            that sets ``action_pivot`` for each case, recorded with the policy so that training and use
            agree): "family" (default), the training family's constant for the case's algorithm; "own",
            the case's own factors, so that the initial policy is the user's own run (issue 47). The
            env itself reads only ``action_pivot``.
        reward_scale: every step's reward (a failure's too) is multiplied by it; a family of cases that
            differ tenfold in iterations weighs each alike with 100 / the case's own iterations.
        freeze_decades: once the run is within this many decades of its criterion (the worst
            criterion field's log10(residual / threshold) at a step's end), every later step keeps the
            factors in force whatever the action (None: never). A change of alpha_u there changes the
            discrete problem the solver iterates on and the run re-converges: airFoil2D's own factors
            jittered by +-0.03 share every 50 iterations took 569 iterations against 292
            (experiments/controller/family-v3-setup/jitter.json); jaxsimrl.apps.foam.solve.rules freezes at 1.
        reward: the cost whose increase is the negative reward of a step, one of REWARDS:
            "iterations" (default, the paper's: SIMPLE iterations K), "linear-iterations" (the inner
            iterations of every linear solve, all fields: what one SIMPLE iteration costs changes with
            the factors, e.g. 10.8-11.3 near (0.95, 0.9) and 8.6-10.2 with random factors on the full
            mesh) or "solver-time" (the
            solver's ExecutionTime, CPU seconds: it does not count the pauses between steps nor a
            busy pool's waiting, but it varies from run to run, so a run with it is not bit-
            reproducible). Every episode record holds all three costs whatever the reward.
        failure_penalty: reward of the step on which the solver failed (crashed, diverged, hung);
            ``None`` -> as if it had run to max_iterations: -(max_iterations - K_{t-1}) SIMPLE
            iterations, each at the episode's mean cost per iteration so far for the other rewards,
            so that the episode's return is about minus the cost of a run to the cap. A penalty above
            that (nearer 0) makes failing pay better than running on to the cap.
        divergence_threshold: an initial residual above this (or NaN/Inf) ends the episode as
            ``diverged``.
        state_divergence_ratio: a state term (mean |U|^2 over the cells or over the inlet) above this
            multiple of the inlet's |U|^2 (or NaN/Inf) ends the episode as ``diverged``. Healthy runs
            measured at mesh_scale 0.25-0.4 peaked at 13 x (typically 1-6 x), diverging ones reached
            1e26 x within ~50 iterations; the default 1e3 catches a blow-up long before the observation
            leaves float32's range. (The observation is also clipped to +-OBSERVATION_BOUND.)
        state_interval: the state's function objects (mean |U|^2 over the cells and the inlet) run every
            this many iterations of OpenFOAM's time index (a divisor of ``interval``; a run started from
            a later time counts from that time's index, so a step boundary may go without its state): 1
            (default) every iteration. They cost 3-5 % of a small case's solver CPU
            (experiments/controller/generated-v1-setup/function-objects.jsonl); solve runs them every 5
            for a controller that does not observe the state, whose only use of it is the divergence
            check above (a blow-up takes ~50 iterations to leave float32's range).

    Host:
        step_timeout_s: watchdog: wall-clock seconds one step may take before the solver counts as hung.
        work_dir: parent directory of the per-env case directories (``None`` -> a fresh temporary
            directory); nothing is written to the current directory.
        keep_cases: keep the case directories after close() (for debugging).
        openfoam_path: ``PATH`` used to locate simpleFoam/blockMesh (``None`` -> the caller's PATH).
            The solver itself runs with a clean environment built from it.
    """

    case_dir: Path | str | None = None
    mesh_scale: float = 1.0
    step_height: float | tuple[float, float] = STEP_HEIGHT_H
    inlet_velocity: tuple[float, float] | float | None = None
    inlet_patch: str | None = "inlet"
    velocity_field: str = "U"
    pressure_field: str = "p"
    turbulence_fields: tuple[str, ...] = ("k", "omega")
    simple_variant: str | None = None
    interval: int = 100
    max_iterations: int = 4000
    action_low: tuple[float, float] = (0.2, 0.2)
    action_high: tuple[float, float] = (0.95, 0.95)
    relax_k_omega: float | str | None = None
    convergence: Mapping[str, float] = field(default_factory=lambda: dict(TRAIN_CONVERGENCE))
    confirm_alpha_u: float | None = None
    confirm_alpha_t: float | None = None
    residual_features: int = 0
    reward: str = "iterations"
    observe_state: bool = True
    observe_algorithm: bool = False
    action_share: bool = False
    action_pivot: tuple[float, ...] | None = None
    action_radius: float | None = None
    pivot_at: str = "family"
    reward_scale: float = 1.0
    freeze_decades: float | None = None
    state_scale: float = U_REF**2
    failure_penalty: float | None = None
    divergence_threshold: float = 1e3
    state_divergence_ratio: float = 1e3
    state_interval: int = 1
    step_timeout_s: float = 120.0
    work_dir: Path | str | None = None
    keep_cases: bool = False
    openfoam_path: str | None = None
    inlet_turbulence: tuple[float, float] | None = None
    observe_progress: bool = False
    observe_action: bool = False
    observe_gain: bool = False
    scale_free_state: bool = False
    observed_fields: tuple[str, ...] | None = None
    start_time: int = 0
    ranks: int = 1

    def __post_init__(self) -> None:
        # the default box follows the action's size: [0.2, 0.95]^3 with alpha_t (see action_low)
        size = self.action_size
        for name, bound in zip(("action_low", "action_high"), BUILTIN_ACTION_BOUNDS, strict=True):
            value = getattr(self, name)
            if size == 3 and isinstance(value, tuple | list) and tuple(value) == (bound, bound):
                object.__setattr__(self, name, (bound,) * 3)

    def validate(self) -> FoamEnvConfig:
        """Check every field; raise a one-line ``ValueError`` naming the first bad one. Returns self."""
        _check(self.mesh_scale > 0 and math.isfinite(self.mesh_scale), "mesh_scale", self.mesh_scale)
        _check_height(self.step_height)
        if self.velocity_range is not None:
            low, high = self.velocity_range
            _check(0 < low <= high and math.isfinite(high), "inlet_velocity", self.inlet_velocity)
        if self.inlet_turbulence is not None:
            values = tuple(self.inlet_turbulence)
            _check(len(values) == 2 and all(v > 0 and math.isfinite(v) for v in values), "inlet_turbulence",
                   self.inlet_turbulence, "(intensity > 0, nu_t/nu > 0)")
        for name in ("inlet_patch", "velocity_field", "pressure_field"):
            value = getattr(self, name)
            none_ok = name == "inlet_patch" and value is None  # a case without an inlet
            _check(isinstance(value, str) and value != "" or none_ok, name, value,
                   "a non-empty name" + " (or None: the case has no inlet)" * (name == "inlet_patch"))
        _check(self.inlet_patch is not None or not (self.builtin or self.velocity_range is not None),
               "inlet_patch", None, "an inlet patch where the inlet speed is set (the built-in case sets it)")
        _check(self.simple_variant is None or self.simple_variant in SIMPLE_VARIANTS, "simple_variant",
               self.simple_variant, f"None or one of {SIMPLE_VARIANTS}")
        _check(_is_int(self.ranks) and self.ranks >= 1 and (self.ranks == 1 or not self.builtin), "ranks",
               self.ranks, "an integer >= 1 (> 1 only for a user's case_dir)")
        _check(_is_int(self.interval) and self.interval >= 1, "interval", self.interval, "an integer >= 1")
        _check(_is_int(self.state_interval) and self.state_interval >= 1
               and self.interval % self.state_interval == 0, "state_interval", self.state_interval,
               f"an integer >= 1 that divides interval ({self.interval})")
        _check(_is_int(self.max_iterations) and self.max_iterations >= self.interval, "max_iterations",
               self.max_iterations, "an integer >= interval")
        size = self.action_size
        _check(len(self.action_low) == size and len(self.action_high) == size, "action_low/action_high",
               (self.action_low, self.action_high),
               f"{size} values each ({', '.join(ACTION_NAMES[:size])})")
        for lo, hi in zip(self.action_low, self.action_high, strict=True):
            _check(0 < lo <= hi <= 1, "action_low/action_high", (self.action_low, self.action_high),
                   "0 < low <= high <= 1")
        if self.relax_k_omega not in (None, FOLLOW_ALPHA_U, K_OMEGA_ACTION):
            factor = self.relax_k_omega
            _check(isinstance(factor, int | float) and not isinstance(factor, str) and 0 < factor <= 1,
                   "relax_k_omega", factor,
                   f"None, {FOLLOW_ALPHA_U!r}, {K_OMEGA_ACTION!r} or a factor in (0, 1]")
        _check(len(self.convergence) > 0 and all(v > 0 for v in self.convergence.values()), "convergence",
               dict(self.convergence), "a non-empty {field: threshold > 0}")
        if self.confirm_alpha_u is not None:
            factor = self.confirm_alpha_u
            _check(isinstance(factor, int | float) and not isinstance(factor, bool) and 0 < factor < 1,
                   "confirm_alpha_u", factor, "None or a factor in (0, 1)")
        if self.confirm_alpha_t is not None:
            factor = self.confirm_alpha_t
            _check(isinstance(factor, int | float) and not isinstance(factor, bool) and 0 < factor <= 1
                   and self.confirm_alpha_u is not None, "confirm_alpha_t", factor,
                   "None, or a factor in (0, 1] beside a confirm_alpha_u")
        _check(_is_int(self.residual_features) and self.residual_features >= 0, "residual_features",
               self.residual_features, "an integer >= 0")
        if self.observed_fields is not None:
            names = self.observed_fields
            _check(isinstance(names, tuple) and len(names) > 0 and len(set(names)) == len(names)
                   and all(isinstance(name, str) and name != "" for name in names), "observed_fields",
                   names, "None or a non-empty tuple of distinct field names")
        _check(self.reward in REWARDS, "reward", self.reward, f"one of {REWARDS}")
        _check(self.reward_scale > 0 and math.isfinite(self.reward_scale), "reward_scale", self.reward_scale)
        _check(self.freeze_decades is None or not isinstance(self.freeze_decades, bool) and isinstance(
            self.freeze_decades, int | float) and 0 <= self.freeze_decades < math.inf, "freeze_decades",
            self.freeze_decades, "None or a number of decades >= 0")
        pivot = self.action_pivot
        _check(pivot is None or len(pivot) == len(self.action_low) and all(
            lo <= x <= hi for x, lo, hi in zip(pivot, self.action_low, self.action_high, strict=True)),
            "action_pivot", pivot, "None or one factor per action, each in the box")
        radius = self.action_radius
        _check(radius is None or not isinstance(radius, bool) and isinstance(radius, int | float)
               and 0 < radius <= 1, "action_radius", radius, "None or a factor step in (0, 1]")
        _check(self.pivot_at in PIVOTS, "pivot_at", self.pivot_at, f"one of {', '.join(PIVOTS)}")
        _check(not self.observe_algorithm or self.variant is not None, "observe_algorithm",
               self.observe_algorithm, "simple_variant set (the algorithm observed)")
        _check(_is_int(self.start_time) and self.start_time >= 0 and not (self.start_time and self.builtin),
               "start_time", self.start_time, "an integer >= 0 (0 for the built-in case)")
        for name in ("observe_progress", "observe_action", "observe_gain", "scale_free_state"):
            _check(isinstance(getattr(self, name), bool), name, getattr(self, name), "true or false")
        _check(self.state_scale > 0, "state_scale", self.state_scale)
        _check(self.step_timeout_s > 0, "step_timeout_s", self.step_timeout_s)
        _check(self.divergence_threshold > 0, "divergence_threshold", self.divergence_threshold)
        _check(self.state_divergence_ratio > 0 and math.isfinite(self.state_divergence_ratio),
               "state_divergence_ratio", self.state_divergence_ratio)
        if self.failure_penalty is not None:
            _check(math.isfinite(self.failure_penalty), "failure_penalty", self.failure_penalty, "finite")
        return self

    @property
    def builtin(self) -> bool:
        """True for the built-in backward-facing step (``case_dir`` None)."""
        return self.case_dir is None

    @property
    def velocity_range(self) -> tuple[float, float] | None:
        """(low, high) of the per-episode inlet velocity (low == high for a fixed one); None: the
        user's case keeps its own inlet."""
        chosen = self.inlet_velocity
        if chosen is None:
            return BUILTIN_INLET_VELOCITY if self.builtin else None
        if isinstance(chosen, int | float) and not isinstance(chosen, bool):
            return float(chosen), float(chosen)
        if isinstance(chosen, str) or len(chosen) != 2:
            raise ValueError(f"FoamEnvConfig.inlet_velocity: expected a float or (low, high), got {chosen!r}")
        return float(chosen[0]), float(chosen[1])

    @property
    def height_range(self) -> tuple[float, float] | None:
        """(low, high) of the per-episode step height; None for a fixed height."""
        if isinstance(self.step_height, tuple | list):
            return float(self.step_height[0]), float(self.step_height[1])
        return None

    @property
    def fixed_height(self) -> float:
        """The step height of an episode without a drawn one: the fixed height, or the range's low."""
        chosen = self.height_range
        return float(self.step_height) if chosen is None else chosen[0]  # type: ignore[arg-type]

    @property
    def action_size(self) -> int:
        """Entries of an action: 2 (alpha_u, alpha_p), 3 with relax_k_omega="action" (alpha_t too)."""
        return 3 if self.relax_k_omega == K_OMEGA_ACTION else 2

    @property
    def variant(self) -> str | None:
        """The SIMPLE variant the bridge sets; None: the user's case keeps its own."""
        if self.simple_variant is None and self.builtin:
            return BUILTIN_SIMPLE_VARIANT
        return self.simple_variant

    @property
    def k_omega_relaxation(self) -> float | str | None:
        """The turbulence fields' factor the bridge sets (a float or FOLLOW_ALPHA_U); None: the case's own."""
        if self.relax_k_omega is None and self.builtin:
            return BUILTIN_RELAX_K_OMEGA
        return self.relax_k_omega

    @property
    def turbulence_check_factor(self) -> float | None:
        """The factor the convergence check relaxes (and judges) the turbulence fields at when the agent
        sets them: ``confirm_alpha_t`` where set and alpha_t is an action, else ``confirm_alpha_u``."""
        if self.confirm_alpha_t is not None and self.k_omega_relaxation == K_OMEGA_ACTION:
            return self.confirm_alpha_t
        return self.confirm_alpha_u

    @property
    def turbulence_formula(self) -> tuple[float, float] | None:
        """(intensity, nu_t/nu) for the inlet k/omega when the inlet speed is set; None: keep the case's."""
        if self.inlet_turbulence is None and self.builtin:
            return PAPER_INLET_TURBULENCE
        return None if self.inlet_turbulence is None else tuple(float(v) for v in self.inlet_turbulence)

    def with_absolute_paths(self) -> FoamEnvConfig:
        """This config with ``case_dir`` and ``work_dir`` resolved against the current directory.

        Workers (spawned processes, Ray actors on other nodes) and OpenFOAM (run with ``-case`` from
        inside the case) do not share the caller's working directory: relative paths must not travel.
        """
        return dataclasses.replace(self, case_dir=_absolute(self.case_dir), work_dir=_absolute(self.work_dir))

    @property
    def observed(self) -> tuple[str, ...]:
        """The fields the residual features observe, in order: ``observed_fields``, else the criterion's."""
        return tuple(self.convergence) if self.observed_fields is None else tuple(self.observed_fields)

    @property
    def observation_size(self) -> int:
        """Length of the observation vector: the state, the residual features, the progress, the action."""
        return (int(self.observe_state) + self.residual_features * len(self.observed)
                + int(self.observe_progress) + int(self.observe_algorithm)
                + self.action_size * int(self.observe_action) + int(self.observe_gain))

    # ---- JSON (the "foam" section of a train-foam run's config.json) ----------------------------------
    def to_json(self) -> dict[str, Any]:
        """Every field by name as JSON-ready values (tuples as lists, ``convergence`` as a plain dict,
        paths as strings); the inverse of :meth:`from_json`. ``observed_fields`` only when set: a config
        without it writes the JSON it always wrote (config.json, reference cache keys)."""
        return {item.name: _to_json(getattr(self, item.name)) for item in dataclasses.fields(self)
                if not (item.name in _OMITTED_WHEN_NONE and getattr(self, item.name) is None
                        or item.name in _OMITTED_AT_DEFAULT and getattr(self, item.name) == item.default)}

    @classmethod
    def from_json(cls, data: Any) -> FoamEnvConfig:
        """The validated config of a :meth:`to_json` dict; one-line ValueError if bad.

        Fields missing from ``data`` take the defaults (a run written before a field existed still
        loads); the JSON lists of tuple fields (and of a velocity or height range) become tuples again.
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"the foam config must be a JSON object, got {type(data).__name__}")
        unknown = sorted(set(data) - {item.name for item in dataclasses.fields(cls)})
        if unknown:
            raise ValueError(f"unknown foam config key(s): {', '.join(unknown)}")
        values = dict(data)
        for name in _JSON_TUPLE_FIELDS:
            if values.get(name) is not None:
                values[name] = _as_tuple(name, values[name])
        for name in ("inlet_velocity", "step_height"):  # a number, or a range as a list
            if isinstance(values.get(name), list):
                values[name] = _as_tuple(name, values[name])
        if "convergence" in values:
            if not isinstance(values["convergence"], Mapping):
                raise ValueError(f"foam config convergence: expected {{field: threshold}}, got "
                                 f"{values['convergence']!r}")
            values["convergence"] = dict(values["convergence"])
        try:
            return cls(**values).validate()
        except TypeError as err:  # e.g. a string where a number belongs, met inside validate()
            raise ValueError(f"foam config: {err}") from None


#: Fields stored as JSON lists that FoamEnvConfig holds as tuples.
_JSON_TUPLE_FIELDS = ("action_low", "action_high", "turbulence_fields", "inlet_turbulence", "observed_fields",
                      "action_pivot")
#: Fields to_json leaves out at None (added after runs were written; their JSON stays byte-identical).
_OMITTED_WHEN_NONE = ("observed_fields", "action_pivot", "freeze_decades", "action_radius", "confirm_alpha_t")
#: Fields to_json leaves out at their default, for the same reason.
_OMITTED_AT_DEFAULT = ("observe_state", "observe_algorithm", "action_share", "reward_scale", "observe_gain",
                       "pivot_at", "state_interval")


def _to_json(value: Any) -> Any:
    if isinstance(value, tuple | list):
        return [_to_json(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _to_json(v) for k, v in value.items()}
    if isinstance(value, Path):
        return str(value)
    return value


def _as_tuple(name: str, value: Any) -> tuple:
    if not isinstance(value, list | tuple):
        raise ValueError(f"foam config {name}: expected a list, got {value!r}")
    return tuple(value)


def without_convergence_test(cfg: FoamEnvConfig) -> FoamEnvConfig:
    """``cfg`` with every threshold of its criterion at NEVER_CONVERGED: the solver never stops itself."""
    return dataclasses.replace(cfg, convergence={name: NEVER_CONVERGED for name in cfg.convergence})


def failure_reward(cfg: FoamEnvConfig, iterations_before: int, cost_per_iteration: float = 1.0) -> float:
    """Reward of the step on which the solver failed (crashed, diverged, hung, dead worker).

    ``cfg.failure_penalty`` if set; otherwise as if the episode had run to the cap:
    ``-(max_iterations - iterations_before) * cost_per_iteration``, with ``iterations_before`` = K at the
    start of that step, so that with the "iterations" reward (cost 1 per iteration) the episode's
    return is ``-max_iterations``.
    """
    if cfg.failure_penalty is not None:
        return float(cfg.failure_penalty)
    return -float(max(cfg.max_iterations - iterations_before, 0)) * float(cost_per_iteration)


def cost_per_iteration(cfg: FoamEnvConfig, cost: float, iterations: int) -> float:
    """An episode's mean cost per SIMPLE iteration so far in the reward's unit, for :func:`failure_reward`
    (1 for the "iterations" reward, and before any iteration ran)."""
    if cfg.reward == "iterations" or iterations <= 0 or cost <= 0:
        return 1.0
    return cost / iterations


def work_root(cfg: FoamEnvConfig, work_dir: Path | str | None = None,
              prefix: str = "foam_bridge_") -> tuple[Path, bool]:
    """The parent of the case directories and whether it is a fresh temporary directory.

    ``work_dir``, else ``cfg.work_dir`` (created if missing), else a new temporary directory named
    ``prefix...``, which the caller removes when it closes (unless ``cfg.keep_cases``). A path with
    whitespace is a one-line ValueError: OpenFOAM (v1912) cannot run a case there (its foamDictionary and
    solvers fail with "Could not find mandatory etc entry 'controlDict'"). A user's ``case_dir`` may have
    whitespace: it is only copied.
    """
    chosen = work_dir if work_dir is not None else cfg.work_dir
    if chosen is None:
        _check_no_whitespace(Path(tempfile.gettempdir()), "the temporary directory (TMPDIR)")
        return Path(tempfile.mkdtemp(prefix=prefix)).resolve(), True
    root = _absolute(chosen)
    _check_no_whitespace(root, "work_dir")
    root.mkdir(parents=True, exist_ok=True)
    return root, False


def _check_no_whitespace(path: Path, what: str) -> None:
    if any(char.isspace() for char in str(path)):
        raise ValueError(f"{what} {str(path)!r} contains whitespace, where OpenFOAM cannot run a case; "
                         f"choose a directory without spaces")


def _absolute(path: Path | str | os.PathLike[str] | None) -> Path | None:
    """``path`` made absolute (symlinks resolved), ``~`` expanded; None stays None."""
    return None if path is None else Path(path).expanduser().resolve()


def _check_height(height: object) -> None:
    """A step height > 0, or a range (low, high) with 0 < low <= high."""
    if isinstance(height, tuple | list):
        ok = len(height) == 2 and all(_is_number(h) and h > 0 and math.isfinite(h) for h in height) \
            and height[0] <= height[1]
        _check(ok, "step_height", height, "a height > 0 or a range (low, high) with 0 < low <= high")
        return
    _check(_is_number(height) and height > 0 and math.isfinite(height), "step_height", height)  # type: ignore[operator]


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _check(ok: bool, name: str, value: object, expected: str = "a finite number > 0") -> None:
    if not ok:
        raise ValueError(f"FoamEnvConfig.{name}: expected {expected}, got {value!r}")
