"""The convergence check relaxation cannot move (FoamEnvConfig.confirm_alpha_u), on the real simpleFoam.

The coarse mesh (0.4) at 50 m/s with the training criterion: (0.95, 0.875) converges at iteration 161.
Dropping alpha_u to 0.2 after the first 100 iterations "converges" at 259 with the U field far from the
solution: checked at alpha_u 0.9, its U residual is ~6x the threshold. With alpha_t an action the
turbulence fields are checked when the step relaxed them below the check's factor (alpha_t 0.3 on a
last step is caught), not at or above it. T3A (kOmegaSSTLM), whose every restart reads k ~3e-2 on its
first iteration, is confirmed where its criterion is met: tests/test_solve_fields.py solves it.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge import sample_specs, write_case
from foam_bridge._config import FoamEnvConfig, without_convergence_test
from foam_bridge._confirm import _checked_fields, meets, step_turbulence_factor
from foam_bridge._env import FoamCaseEnv
from foam_bridge._logparse import LogParser, solver_cost
from jaxsimrl.cli.main import main

HONEST = [(0.95, 0.875)]
#: alpha_u 0.2 from iteration 100 to 300, then back to 0.95.
DROP = [(0.95, 0.875), (0.2, 0.875), (0.2, 0.875), (0.95, 0.875)]


def _cfg(tmp_path, **overrides) -> FoamEnvConfig:
    base = dict(mesh_scale=0.4, inlet_velocity=50.0, max_iterations=1500, step_timeout_s=60.0,
                work_dir=tmp_path)
    return FoamEnvConfig(**{**base, **overrides})


def _episode(cfg: FoamEnvConfig, schedule) -> tuple[list[dict], dict, list[dict]]:
    """(per-step infos, the episode record, the solver's residual history) of one episode."""
    infos = []
    with FoamCaseEnv(cfg) as env:
        env.reset(seed=0)
        while True:
            _, reward, terminated, truncated, info = env.step(schedule[min(len(infos), len(schedule) - 1)])
            infos.append({**info, "reward": reward})
            if terminated or truncated:
                return infos, info["episode"], list(env.parser.history)


@pytest.mark.slow  # real runs and their checks
@needs_openfoam
def test_an_honest_run_is_confirmed_where_the_solver_stopped(tmp_path):
    plain, plain_record, _ = _episode(_cfg(tmp_path / "plain"), HONEST)
    infos, record, _ = _episode(_cfg(tmp_path / "checked", confirm_alpha_u=0.9), HONEST)
    assert [(i["iterations"], i["outcome"], i["reward"]) for i in infos] == [
        (i["iterations"], i["outcome"], i["reward"]) for i in plain]
    assert "confirmations" not in plain_record
    (check,) = record["confirmations"]
    cfg = _cfg(tmp_path)
    assert check["passed"] and check["iteration"] == record["iterations"] and meets(cfg, check["residuals"])
    # normalised at a lower alpha_u than the run's 0.95, its U residual reads lower, not equal
    assert check["residuals"]["U"] < check["solver_residuals"]["U"]


@pytest.mark.slow  # real runs and their checks
@needs_openfoam
def test_a_relaxation_artefact_fails_the_check_and_the_run_goes_on(tmp_path):
    plain, _, plain_history = _episode(_cfg(tmp_path / "plain"), DROP)
    fooled = plain[-1]["iterations"]
    assert plain[-1]["outcome"] == "converged" and 200 < fooled < 300  # the solver's own test was fooled

    cfg = _cfg(tmp_path / "checked", confirm_alpha_u=0.9)
    infos, record, history = _episode(cfg, DROP)
    first, *later = record["confirmations"]
    assert first["iteration"] == fooled and not first["passed"]
    assert first["residuals"]["U"] > 3 * cfg.convergence["U"] >= first["solver_residuals"]["U"]
    # the episode went on, step by step, and ended at the first boundary whose check passed
    assert [i["iterations"] for i in infos] == [100 * (t + 1) for t in range(len(infos))]
    assert infos[-1]["outcome"] == "converged" and record["return"] == -infos[-1]["iterations"]
    assert [c["passed"] for c in later] == [False] * (len(later) - 1) + [True]
    assert all(c["iteration"] % cfg.interval == 0 for c in later)
    assert all(not meets(cfg, c["residuals"]) for c in record["confirmations"][:-1])
    # the solver went on from the fields it stopped at: an uninterrupted run (no test at all) agrees
    _, _, reference = _episode(without_convergence_test(_cfg(tmp_path / "ref", max_iterations=400)), DROP)
    assert len(history) == infos[-1]["iterations"]
    for mine, theirs in zip(history[fooled - 5:], reference[fooled - 5:len(history)], strict=True):
        assert mine.keys() == theirs.keys()
        assert all(mine[f] == pytest.approx(theirs[f], rel=1e-3) for f in mine)
    assert history[:fooled] == plain_history[:fooled]


def test_turbulence_fields_are_checked_only_when_the_step_relaxed_them_below_the_check():
    cfg = FoamEnvConfig(relax_k_omega="action", confirm_alpha_u=0.9)
    lm = ("k", "omega", "ReThetat", "gammaInt")
    for alpha_t, checked in ((0.95, ("U",)), (0.9, ("U",)), (float(np.float32(0.9)), ("U",)),
                             (0.89, ("U", *lm)), (0.3, ("U", *lm))):
        factor = step_turbulence_factor(cfg, (0.95, 0.9, alpha_t))
        assert factor == alpha_t and _checked_fields(cfg, lm, factor) == checked, alpha_t
    assert _checked_fields(cfg, lm) == ("U", *lm)  # the step's factor not known: checked
    follow = dataclasses.replace(cfg, relax_k_omega="alpha_u")  # the step's alpha_u is theirs
    assert _checked_fields(follow, None, step_turbulence_factor(follow, (0.5, 0.9))) == ("U", "k", "omega")
    assert _checked_fields(follow, None, step_turbulence_factor(follow, (0.95, 0.3))) == ("U",)
    fixed = dataclasses.replace(cfg, relax_k_omega=0.3)  # not the agent's: the solver's test stands
    assert step_turbulence_factor(fixed, (0.95, 0.9)) is None and _checked_fields(fixed) == ("U",)


@pytest.mark.slow  # real runs and their checks
@needs_openfoam
def test_alpha_t_dropped_below_the_check_on_the_last_step_is_caught(tmp_path):
    """A criterion whose binding field is k (its residual at 0.95 levels off at ~3.5e-4 > 2.5e-4):
    alpha_t 0.3 from iteration 200 lowers the k residual the solver reads ~3x at once, and it stops;
    the check at 0.9 reads k over the threshold, so the run goes on until a check reads k under it."""
    criterion = {"U": 1e-3, "p": 5e-2, "k": 2.5e-4, "omega": 1e-3}
    schedule = [(0.95, 0.875, 0.95)] * 2 + [(0.95, 0.875, 0.3)]
    base = dict(relax_k_omega="action", convergence=criterion, max_iterations=400)
    plain, _, _ = _episode(_cfg(tmp_path / "plain", **base), schedule)
    fooled = plain[-1]["iterations"]
    assert plain[-1]["outcome"] == "converged" and 200 < fooled < 300  # the solver's own test was fooled

    cfg = _cfg(tmp_path / "checked", confirm_alpha_u=0.9, **base)
    infos, record, _ = _episode(cfg, schedule)
    first, *later = record["confirmations"]
    assert first["iteration"] == fooled and not first["passed"] and later
    assert first["residuals"]["k"] > criterion["k"] >= first["solver_residuals"]["k"]
    assert meets(cfg, first["residuals"], ("U",))  # U alone would have passed: k failed it
    assert infos[-1]["outcome"] == "converged" and infos[-1]["iterations"] == later[-1]["iteration"] > fooled
    assert later[-1]["passed"] and meets(cfg, later[-1]["residuals"])


def test_the_check_factor_is_validated():
    for bad in (0, 1, 1.2, -0.5, True, "0.9"):
        with pytest.raises(ValueError, match="confirm_alpha_u"):
            FoamEnvConfig(confirm_alpha_u=bad).validate()
    assert FoamEnvConfig(confirm_alpha_u=0.9).validate().confirm_alpha_u == 0.9
    for bad in (0, 1.2, True, "0.8"):
        with pytest.raises(ValueError, match="confirm_alpha_t"):
            FoamEnvConfig(confirm_alpha_u=0.9, confirm_alpha_t=bad).validate()
    with pytest.raises(ValueError, match="confirm_alpha_t"):  # a turbulence check without a check
        FoamEnvConfig(confirm_alpha_t=0.8).validate()
    cfg = FoamEnvConfig(confirm_alpha_u=0.9, confirm_alpha_t=1.0).validate()  # unrelaxed k: read at 1
    assert FoamEnvConfig.from_json(cfg.to_json()) == cfg
    assert "confirm_alpha_t" not in FoamEnvConfig(confirm_alpha_u=0.9).to_json()  # old runs' JSON as it was


def test_the_turbulence_fields_are_judged_at_their_own_check_factor():
    """confirm_alpha_t (solve: the case's own turbulence factor) replaces confirm_alpha_u for k/epsilon/
    omega when alpha_t is an action: a step at or above it is not re-read, one below it is."""
    cfg = FoamEnvConfig(relax_k_omega="action", confirm_alpha_u=0.81, confirm_alpha_t=0.77)
    assert cfg.turbulence_check_factor == 0.77
    for alpha_t, checked in ((0.77, ("U",)), (0.8, ("U",)), (0.76, ("U", "k", "omega"))):
        assert _checked_fields(cfg, None, step_turbulence_factor(cfg, (0.81, 1.0, alpha_t))) == checked
    follow = dataclasses.replace(cfg, relax_k_omega="alpha_u")  # alpha_u's factor, alpha_u's check
    assert follow.turbulence_check_factor == 0.81
    assert _checked_fields(follow, None, step_turbulence_factor(follow, (0.8, 1.0))) == ("U", "k", "omega")
    assert dataclasses.replace(cfg, confirm_alpha_t=None).turbulence_check_factor == 0.81


@pytest.mark.slow  # three real runs of a generated case
@needs_openfoam
def test_a_controller_at_the_own_factors_converges_where_the_own_run_does(tmp_path, monkeypatch):
    """A generated SIMPLEC case (own alpha_u 0.81, turbulence 0.77, 113 iterations) driven at its own
    factors in steps of 25: checked at the own alpha_u, k/epsilon read higher than the user's run reads
    them, the check fails and the run goes on to the next boundary; at the own turbulence factor (solve's
    default check) it stops where the own run stops."""
    from jaxsimrl.apps.foam.solve import rules, runner, solve_case
    from jaxsimrl.apps.foam.solve.own import run_own

    spec = sample_specs(12, 1)[9]
    assert spec.algorithm == "SIMPLEC" and dict(spec.factors)["turbulence"] < dict(spec.factors)["U"]
    case = write_case(spec, tmp_path / "case", resolution=1.0)
    own = run_own(case, tmp_path / "own", "own", 600.0)
    assert own.converged and own.iterations % 25  # its criterion is met between two step boundaries
    monkeypatch.setitem(rules.INTERVALS, "own", 25)  # the own rule, stepped as a controller steps
    monkeypatch.setattr(runner, "DEFAULT_RULE", "(none)")  # (solve runs its default plain)
    stepped = solve_case(case, tmp_path / "stepped", rule="own")
    settings = json.loads((tmp_path / "stepped" / "solve.json").read_text())["settings"]
    assert settings["confirm_alpha_u"] == 0.81 and settings["confirm_alpha_t"] == 0.77
    assert settings["state_interval"] == 5  # a rule observes no state: only the divergence check reads it
    assert stepped.iterations == own.iterations
    strict = solve_case(case, tmp_path / "strict", rule="own", confirm_alpha_u=0.81)  # k checked at 0.81
    assert strict.iterations == 25 * math.ceil(own.iterations / 25) > own.iterations


@pytest.mark.parametrize("command", [["train-foam"], ["eval-foam", "some_run"],
                                     ["grid-foam", "--alpha-u", "0.9", "--alpha-p", "0.9", "--out", "x"]])
def test_a_bad_check_factor_is_a_one_line_error(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([*command, "--confirm-alpha-u", "1"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--confirm-alpha-u" in err and "(0, 1)" in err


_LOG = "".join(f"Time = {k}\nsmoothSolver:  Solving for Ux, Initial residual = 0.1, Final residual = 0.01, "
               f"No Iterations 2\nExecutionTime = {t} s  ClockTime = 1 s\n\n"
               for k, t in ((1, 0.5), (2, 1.25), (3, 0.25), (4, 0.75)))


def test_cpu_time_of_a_restarted_run_adds_up_its_processes():
    """A run restarted from its fields prints ExecutionTime from 0 again: 1.25 s, then 0.75 s more."""
    parser = LogParser("cells", "inlet")
    parser.feed(_LOG)
    assert parser.execution_time == pytest.approx(2.0) and parser.completed == 4
    cost = solver_cost(_LOG)
    assert cost.cpu_time_s == pytest.approx(2.0) and cost.of("U") == 8


def test_eval_spec_passes_the_check_to_every_run(tmp_path):
    from jaxsimrl.apps.foam.evaluation.eval_spec import EvalSpec, eval_config

    spec = EvalSpec(run_dir=tmp_path, confirm_alpha_u=0.9).validate()
    cfg = eval_config(FoamEnvConfig(), spec, 0.0254, [(0.95, 0.3)])
    assert cfg.confirm_alpha_u == 0.9 and cfg.step_height == 0.0254
    plain = eval_config(FoamEnvConfig(), EvalSpec(run_dir=tmp_path), None, [(0.9, 0.8)])
    assert plain.confirm_alpha_u is None
    with pytest.raises(ValueError, match="confirm_alpha_u"):
        dataclasses.replace(spec, confirm_alpha_u=1.0).validate()
