"""``solve_case``: converge a user's case with a controller, never worse than the case's own settings.

Layout of ``out`` afterwards: the user's case as a normal OpenFOAM case (their system/, constant/, 0/, the
time directory it started from when a later one, the converged time directory, ``log.simpleFoam``;
foam_bridge._export), ``solve.json`` and ``solve.png``
(jaxsimrl.apps.foam.solve.report), and with ``compare`` the comparison runs under ``compare/``. ``solve.json``
is written first with status "incomplete": a run killed before its end says so; Ctrl-C leaves
"interrupted"; only a finished run says "complete".
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foam_bridge import (
    DEFAULT_TOLERANCE,
    FAILURES,
    OpenFOAMNotFoundError,
    export_case,
    shares_of,
    solved_field_names,
)
from jaxsimrl.apps.foam.solve.agreement import compare_results, measure_spread
from jaxsimrl.apps.foam.solve.controller import BackgroundLoad, Controller, as_controller, policy_env_config
from jaxsimrl.apps.foam.solve.criterion import (
    Residual,
    converged_by,
    describe,
    own_converged_by,
    reported,
    source_of,
    write_criterion,
)
from jaxsimrl.apps.foam.solve.drive import ControlledRun, LearnedActor, drive
from jaxsimrl.apps.foam.solve.fields import observed_mapping
from jaxsimrl.apps.foam.solve.live import LivePlot
from jaxsimrl.apps.foam.solve.mpi import (
    INPUT_DIR,
    check_ranks,
    export_source,
    keep_processors,
    prepared_input,
    runs_side_by_side,
)
from jaxsimrl.apps.foam.solve.own import OwnProcess, OwnRun, Settle
from jaxsimrl.apps.foam.solve.report import (
    SolveReport,
    build_report,
    preload_plotting,
    write_report,
    write_status,
)
from jaxsimrl.apps.foam.solve.rules import DEFAULT_RULE, RulePolicy
from jaxsimrl.apps.foam.solve.settings import (
    DEFAULT_MAX_ITERATIONS,
    OWN_CHECK,
    CheckedCase,
    check_factor,
    not_applicable,
    nudged_factors,
    observation_factor,
    own_action,
    read_case_settings,
    solve_config,
    start_of,
    turbulence_check,
    with_own,
)
from jaxsimrl.apps.foam.solve.solvers import make_lean
from jaxsimrl.apps.foam.solve.watchdog import WatchdogSettings, for_interval
from jaxsimrl.runs.signals import stop_word

WORK_DIR = ".solve-work"
COMPARE_DIR = "compare"
#: The comparison run at the case's own factors with alpha_u nudged (``--compare``'s spread).
SPREAD = "spread"
#: ``solves``: the controlled run's linear solves lean (jaxsimrl.apps.foam.solve.solvers) or the case's own.
LEAN, OWN_SOLVES = "lean", "own"
#: What the default does, as solve says it: the case's own run (no stepping, no confirmation: it is the run
#: the user would make, so its iterations and its answer are theirs exactly).
OWN_SETTINGS = ("the default: the case's own settings, run as they are (no controller measured is safe on "
                "every case: docs/solve.md; --controller NAME for one)")


def solve_case(case: str | Path, out: str | Path, policy: Any = None,
               compare: bool = False, compare_constant: Sequence[float] | None = None,
               max_iterations: int | None = None, confirm_alpha_u: float | str | None = OWN_CHECK,
               watchdog: WatchdogSettings | None = None,
               action_box: tuple[Sequence[float], Sequence[float]] | None = None,
               step_timeout_s: float = 300.0, inlet_patch: str | None = None,
               say: Callable[[str], None] | None = None, residual: Residual | str | None = None,
               from_time: float | None = None, rule: str | None = None, ranks: int | None = None,
               keep_decomposed: bool = False, spread: bool = True, solves: str = "own",
               settle: float | None = DEFAULT_TOLERANCE) -> SolveReport:
    """Run ``case`` with a controller into ``out``; see the module docstring. The controller: ``rule`` (a
    no-training rule, jaxsimrl.apps.foam.solve.rules), else ``policy`` (a train-foam run directory, a
    :class:`Controller` or a policy from ``jaxsimrl.load_policy``; the shipped one is
    jaxsimrl.apps.foam.solve.controller.DEFAULT_CONTROLLER), else the default: the case's own factors
    (rules.DEFAULT_RULE): the user's own run, its iterations and its answer. Bad
    input (a missing or decomposed case, a non-empty ``out``, a case the bridge cannot drive, a bad
    policy): one-line ValueError before any result is claimed. ``confirm_alpha_u``: the convergence
    check's alpha_u (foam_bridge._confirm; "own", the default: the case's own alpha_u and, for a
    controller that sets alpha_t, its own turbulence factor, see
    :func:`jaxsimrl.apps.foam.solve.settings.check_factor` and ``turbulence_check``; None: no check).
    ``action_box`` replaces the case's own box (experiments only); ``inlet_patch``: the patch whose
    mean |U|^2 the controller observes (None: the case's ``inlet``, if it has one);
    ``residual``: the convergence criterion instead of the case's residualControl, for every run of the
    solve and written into ``out``'s fvSolution (jaxsimrl.apps.foam.solve.criterion: ``1e-4``, ``{"p": 1e-3}``
    or ``"p=1e-3,U=1e-4"``); ``from_time``: the case's time directory to start from (default its latest:
    a partly converged run goes on; iterations and the budget count from there); ``rule``: a
    no-training rule (a key of jaxsimrl.apps.foam.solve.rules.RULES) instead of ``policy``; ``ranks``: MPI
    ranks of every run (jaxsimrl.apps.foam.solve.mpi; a decomposed case needs its own count),
    ``keep_decomposed``: leave the ranks' processor* directories in ``out`` too; ``spread`` (with
    ``compare``): also run the case at its own factors with alpha_u a little off
    (jaxsimrl.apps.foam.solve.settings.nudged_factors), to measure how far two legitimate runs end apart
    at its criterion (jaxsimrl.apps.foam.solve.agreement.measure_spread): a third run beside the two;
    ``solves``: OWN_SOLVES (the case's own linear solves, the default) or LEAN (no tighter than
    jaxsimrl.apps.foam.solve.solvers says: the same answer, less work per iteration, but on the coarse step
    21 % more iterations); ``settle``: the relative tolerance of the stop on the answer (foam_bridge's
    AnswerMonitor watches the case's own run and ends it once every field and function-object value is
    within it of where the run settles, or oscillates with a steady mean and range; None: the plain run,
    ended only by its criterion, its own function objects or its budget)."""
    if solves not in (LEAN, OWN_SOLVES):
        raise ValueError(f"solves: expected {LEAN!r} or {OWN_SOLVES!r}, got {solves!r}")
    if rule is None and policy is None:
        rule = DEFAULT_RULE
    say = say or (lambda text: None)
    case, out = _check_paths(case, out)
    ranks = check_ranks(case, ranks)
    started = time.monotonic()
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    write_status(out, "incomplete", case)
    others: list[OwnProcess] = []
    try:
        source = prepared_input(case, out)
        report = _solve(source, out, policy, compare, compare_constant, max_iterations, confirm_alpha_u,
                        watchdog or WatchdogSettings(), (action_box, step_timeout_s, inlet_patch), residual,
                        start_of(source, from_time), say, started, others, rule, (ranks, keep_decomposed),
                        spread, solves, settle)
    except KeyboardInterrupt as stop:  # Ctrl-C or SIGTERM: the finally blocks below stop every solver
        write_status(out, "interrupted", case, stop_word(stop))
        raise
    except (ValueError, OpenFOAMNotFoundError) as err:  # bad input, before any result: leave nothing
        for process in others:
            process.stop()
        _discard(out, created, case, str(err))
        raise
    except RuntimeError as err:
        write_status(out, "failed", case, str(err))
        raise
    finally:
        for process in others:
            process.stop()
        shutil.rmtree(out / WORK_DIR, ignore_errors=True)
        shutil.rmtree(out / INPUT_DIR, ignore_errors=True)
    return report


def _discard(out: Path, created: bool, case: Path, error: str) -> None:
    """Remove ``out`` if this solve created it, else say in its solve.json why it holds no result."""
    if created:
        shutil.rmtree(out, ignore_errors=True)
    else:
        write_status(out, "failed", case, error)


def _check_paths(case: str | Path, out: str | Path) -> tuple[Path, Path]:
    case, out = Path(case).expanduser().resolve(), Path(out).expanduser().resolve()
    if not case.is_dir():
        raise ValueError(f"case {case} is not a directory")
    if out == case or case in out.parents:
        raise ValueError(f"--out {out} must be outside the case {case} (the case is never modified)")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"--out {out} exists and is not empty; choose a new directory")
    return case, out


#: How often the state's function objects run for a controller that does not observe the state (their
#: one use is then the divergence check): every 5 iterations, 3-5 % of a small case's CPU less.
UNOBSERVED_STATE_INTERVAL = 5


def state_interval(cfg: Any, rule: str | None) -> int:
    """FoamEnvConfig.state_interval of a controlled run: every iteration where the controller observes
    the state (a policy with observe_state) or where UNOBSERVED_STATE_INTERVAL does not divide the step's
    interval; else every UNOBSERVED_STATE_INTERVAL."""
    if rule is None and cfg.observe_state:
        return 1
    return math.gcd(cfg.interval, UNOBSERVED_STATE_INTERVAL)


def _solve(case: Path, out: Path, policy: Any, compare: bool, constant: Sequence[float] | None,
           max_iterations: int | None, confirm: float | str | None, watchdog: WatchdogSettings,
           env: tuple[Any, float, str], residual: Residual | str | None, begin: tuple[int, str],
           say: Callable[[str], None], started: float, others: list[OwnProcess],
           rule: str | None, parallel_run: tuple[int, bool], spread: bool = True,
           solves: str = "own", settle: float | None = None) -> SolveReport:
    # What waits on what: the controller loads (JAX, its acting arrays, the first action compiled) in a
    # thread from here on, beside the case check (copy, mesh, one SIMPLE iteration: once, the controlled
    # run's env starts from its build) and the worker's start; the first step waits for both, every
    # later one only for the solver. Then the thread imports the report's plotting.
    phases: dict[str, float] = {}
    mark = time.monotonic()
    policy = as_controller(policy) if rule is None else rule_controller(rule)
    loading = None if isinstance(policy, Controller) else BackgroundLoad(policy, then=preload_plotting)
    trained = policy.policy.env_params if isinstance(policy, Controller) else policy_env_config(policy)
    start, started_from = begin
    settings = read_case_settings(case, start)
    if start and settings.budget is None and max_iterations is None:
        raise ValueError(f"case {case}: its endTime is not after the time {start} it starts from: give "
                         f"--max-iterations N (or --from-time)")
    budget = max_iterations or settings.budget or DEFAULT_MAX_ITERATIONS
    # the check holds a controller's factors to the case's own normalisation: the case's own factors need none
    own_check = confirm == OWN_CHECK and rule != DEFAULT_RULE
    confirm = None if rule == DEFAULT_RULE else check_factor(settings) if own_check else confirm
    ranks, keep_decomposed = parallel_run
    cfg, checked = solve_config(case, trained, out / WORK_DIR, budget, confirm, *env, residual=residual,
                                start_time=start, settings=settings,
                                confirm_alpha_t=turbulence_check(settings) if own_check else None)
    cfg = dataclasses.replace(cfg, ranks=ranks, state_interval=state_interval(cfg, rule)).validate()
    if rule is not None:  # a rule goes back to the case's own factors: exactly them
        cfg = with_own(cfg, settings)
    solved = solved_field_names(checked.info.solved_fields)
    lean = make_lean(checked.directory, solved) if solves == LEAN else {}
    phases["case_check_s"], mark = time.monotonic() - mark, time.monotonic()
    own = Own(settings.flat, None if residual is None else dict(cfg.convergence), start, ranks,
              nudged_factors(settings) if compare and spread else None,
              None if settle is None else Settle(settle, tuple(solved)), max_iterations)
    parallel = runs_side_by_side(ranks)  # else the runs would share cores: one after the other
    comparisons = _start_comparisons(case, out, compare, constant, own, others) if parallel else {}
    observed = observed_mapping(trained, checked.info.solved_fields)[0]
    criterion_from = source_of(cfg.convergence, residual)
    say(f"solve {case}: criterion {describe(reported(cfg.convergence), criterion_from)}, box "
        f"{cfg.action_low}-{cfg.action_high}, {started_from}, budget {budget} iterations"
        + (f", observes {observed}" if observed else ""))
    controller = policy if loading is None else loading
    episode = out / WORK_DIR / "env_0" / "episode"
    live = LivePlot(out, case, reported(cfg.convergence), list(cfg.convergence), episode / "log.simpleFoam")
    try:
        run = _controlled(cfg, trained, settings, controller, watchdog, say, checked, live.update,
                          plain=rule == DEFAULT_RULE and solves == OWN_SOLVES)
    finally:
        live.close()
    controller = controller if loading is None else loading.result()
    phases["controlled_run_s"], mark = time.monotonic() - mark, time.monotonic()
    rescue = None
    if run.outcome == "not run" or run.outcome in FAILURES:  # a run that reached the budget keeps its fields
        rescue = _own_rescue(case, out, comparisons, run, own, say)
    run_case = Path(rescue.case) if rescue is not None else episode
    time_name = export_case(export_source(run_case, case, out / WORK_DIR, ranks if rescue is None else 1),
                            case, out, log=run_case / "log.simpleFoam", start_time=start)
    if keep_decomposed:
        keep_processors(run_case, out)
    if own.criterion is not None:  # a plain simpleFoam restart of out stops where this solve did
        write_criterion(out, own.criterion)
    phases["fallback_and_export_s"] = time.monotonic() - mark
    wall = time.monotonic() - started
    if not parallel:
        comparisons = _start_comparisons(case, out, compare, constant, own, others)
    results = {name: process.result(24 * 3600.0) for name, process in comparisons.items()}
    nudged = results.pop(SPREAD, None)
    report = build_report(case, out, controller, cfg, run, rescue, time_name, wall, results, episode,
                          observed if run.outcome != "not run" else None)
    mark = time.monotonic()
    spread_found = _spread(results.get("own"), nudged, own, solved, cfg.convergence)
    _add_agreement(report, out, results, cfg.convergence, solved, "own" if rescue is not None else None,
                   spread_found)
    phases["agreement_s"] = time.monotonic() - mark
    report.data["result"]["phases"] = phases
    report.data["settings"]["criterion"] = reported(cfg.convergence)
    report.data["settings"]["criterion_from"] = criterion_from
    report.data["settings"]["started_from"] = started_from
    report.data["settings"]["algorithm"] = settings.variant
    report.data["settings"]["linear_solves"] = {"mode": solves, "relTol": lean}
    report.data["result"]["converged_by"] = converged_by(run, rescue, criterion_from)
    for name, other in results.items():
        report.data["compare"][name]["converged_by"] = own_converged_by(other, criterion_from)
    report.data["compare_parallel"] = parallel
    report.data["settings"]["ranks"] = ranks
    write_report(out, report)
    return report


def _controlled(cfg: Any, trained: Any, settings: Any, controller: Any, watchdog: WatchdogSettings,
                say: Callable[[str], None], checked: CheckedCase,
                on_step: Callable[[ControlledRun], None], plain: bool = False) -> ControlledRun:
    """The controlled run, or none (outcome "not run") when the controller does not apply to the case or
    ``plain`` (the default: the case's own run is the result, _own_rescue).
    ``controller``: a Controller, or its BackgroundLoad (waited for once the worker has built the case)."""
    if plain:
        say(OWN_SETTINGS)
        event = {"kind": "own settings", "at_iteration": 0, "reason": OWN_SETTINGS,
                 "then": "the case's own run"}
        return ControlledRun(outcome="not run", events=[event])
    fallback = own_action(settings, cfg, len(cfg.action_low))
    watchdog = for_interval(watchdog, cfg.interval)  # its stall window in iterations, whoever steps
    rule = controller.policy if isinstance(controller, Controller) else None
    if isinstance(rule, RulePolicy):  # a rule reads residuals only: it applies to any case
        made = rule.for_case(dict(cfg.convergence), fallback, cfg.action_low, cfg.action_high,
                             settings.variant == "SIMPLEC")
        return drive(cfg, lambda speed: made, fallback, watchdog, say, checked, on_step)
    skip = not_applicable(trained, settings, checked.info.solved_fields, cfg.inlet_patch)
    if skip is not None:
        say(skip)
        return ControlledRun(outcome="not run", events=[{"kind": "not applicable", "at_iteration": 0,
                                                         "reason": skip, "then": "the case's own run"}])
    if cfg.action_share:  # the controller acts in shares of the case's box: so must its fallback
        fallback = shares_of(cfg, fallback).tolist()

    def actor(speed: float) -> LearnedActor:
        loaded = controller if isinstance(controller, Controller) else controller.result()
        return LearnedActor(loaded.policy, observation_factor(trained, speed),
                            getattr(trained, "freeze_decades", None), cfg.convergence)

    return drive(cfg, actor, fallback, watchdog, say, checked, on_step)


def rule_controller(name: str) -> Controller:
    """A no-training rule (jaxsimrl.apps.foam.solve.rules) as solve's controller; its provenance names it."""
    rule = RulePolicy(name)
    return Controller(rule, rule.provenance())


@dataclass(frozen=True)
class Own:
    """How the case's own runs (comparisons, fallback) run: whether its relaxationFactors are flat, the
    criterion given to solve (None: the case's own residualControl) and the time they start from, which
    they must share with the controlled run to be comparable."""

    flat: bool
    criterion: dict[str, float] | None
    start: int = 0
    ranks: int = 1
    nudged: tuple[tuple[float, ...], str] | None = None
    settle: Settle | None = None  # the case's own run in place of a controller's stops on its answer
    budget: int | None = None  # --max-iterations: the own run in place of a controller's stops there


def _start_comparisons(case: Path, out: Path, compare: bool, constant: Sequence[float] | None, own: Own,
                       others: list[OwnProcess]) -> dict[str, OwnProcess]:
    """The comparison runs (the case's own controlDict, budget included; solve's criterion), started now:
    they run beside the controlled one, and the report gives the cores the runs shared."""
    wanted: dict[str, Sequence[float] | None] = {}
    if compare:
        wanted["own"] = None
    if constant is not None:
        wanted["constant"] = constant
    if compare and own.nudged is not None:
        wanted[SPREAD] = own.nudged[0]
    started = {}
    for name, factors in wanted.items():
        dest = out / COMPARE_DIR / name
        dest.parent.mkdir(parents=True, exist_ok=True)
        started[name] = OwnProcess(case, dest, name, 24 * 3600.0, factors, own.flat, own.criterion, own.start,
                                   own.ranks)
        others.append(started[name])
    return started


def _add_agreement(report: SolveReport, out: Path, results: dict[str, OwnRun], criterion: dict[str, float],
                   fields: list[str], rescued_by: str | None, spread: dict[str, Any] | None = None) -> None:
    """Each comparison's ``agreement``: is the result in ``out`` the same answer as its run's
    (jaxsimrl.apps.foam.solve.agreement), within the larger of the tolerance and the measured ``spread``
    (kept under ``compare.own.spread``); ``rescued_by``: the comparison whose run ``out`` holds
    (_own_rescue)."""
    for name, other in results.items():
        report.data["compare"][name]["agreement"] = compare_results(
            out, Path(other.case), fields, criterion, (report.converged, other.converged), name,
            same_run=name == rescued_by, spread=spread)
    if spread is not None and "own" in report.data["compare"]:
        report.data["compare"]["own"]["spread"] = spread


def _spread(own_run: OwnRun | None, nudged: OwnRun | None, own: Own, fields: list[str],
            criterion: dict[str, float]) -> dict[str, Any] | None:
    """measure_spread of the own run against the nudged one, with the nudged run's figures; None without
    a spread run."""
    if own_run is None or nudged is None or own.nudged is None:
        return None
    found = measure_spread(Path(own_run.case), Path(nudged.case), fields, criterion,
                           (own_run.converged, nudged.converged), own.nudged[1])
    return {**found, "factors": list(own.nudged[0]), "iterations": nudged.iterations,
            "solver_cpu_time_s": nudged.cpu_time_s, "case": nudged.case}


def _own_rescue(case: Path, out: Path, comparisons: dict[str, OwnProcess], run: Any, own: Own,
                say: Callable[[str], None]) -> OwnRun:
    """The case run with its own settings from its initial fields, stopped on its answer where
    ``own.settle`` says so (else the comparison's own run if there is one: the same plain run)."""
    if run.outcome != "not run":
        say(f"the controlled run ended {run.outcome} at {run.iterations}: running the case's own settings")
    if "own" in comparisons and own.settle is None and own.budget is None:  # --compare's: the plain run
        result = comparisons["own"].result(24 * 3600.0)
    else:
        process = OwnProcess(case, out / WORK_DIR / "own", "own", 24 * 3600.0, None, False, own.criterion,
                             own.start, own.ranks, own.settle, own.budget)
        try:
            result = process.result(24 * 3600.0)
        finally:
            process.stop()
    if run.outcome != "not run":
        run.events.append({"kind": "rerun", "at_iteration": run.iterations,
                           "reason": f"the controlled run ended {run.outcome}: {run.cause}".rstrip(": "),
                           "then": "the case with its own settings from its initial fields"})
    return result

