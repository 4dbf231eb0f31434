"""The no-training rules (jaxsimrl.solve.rules): their logic on made-up residuals, then ``solve
--controller`` on a coarse SIMPLEC and a coarse plain-SIMPLE case with the real simpleFoam."""

from __future__ import annotations

import json
import math
import random
from pathlib import Path

import pytest
from foam_marks import needs_openfoam
from test_solve import _coarse_step, _marked_processes

from jaxsimrl.solve import solve_case
from jaxsimrl.solve.rules import ResidualRule, RulePolicy
from jaxsimrl.solve.watchdog import WatchdogSettings

CRITERION = {"U": 1e-3, "p": 1e-2}
OWN, LOW, HIGH = (0.7, 0.3, 0.7), (0.35, 0.15, 0.35), (0.875, 0.375, 0.875)


def _residuals(decades: float) -> dict[str, float]:
    """Residuals whose worst field is ``decades`` above the criterion (U the worst)."""
    return {"U": 1e-3 * 10**decades, "p": 1e-2 * 10 ** (decades - 0.5)}


def test_the_residual_rule_holds_first_then_raises_on_progress_and_lowers_on_growth():
    rule = ResidualRule(CRITERION, OWN, LOW, HIGH)
    assert rule.act(None, None) == list(OWN)
    assert rule.act(None, _residuals(2.0)) == list(OWN)  # the first boundary: the start-up transient
    raised = rule.act(None, _residuals(1.5))  # progress: half-way up to the top
    assert raised == pytest.approx([o + 0.5 * (h - o) for o, h in zip(OWN, HIGH, strict=True)])
    assert rule.act(None, _residuals(1.6)) == raised  # a small rise: a developing flow's transient, held
    lowered = rule.act(None, _residuals(2.5))  # a real rise: a quarter of the way down
    assert lowered == pytest.approx([r - 0.25 * (r - lo) for r, lo in zip(raised, LOW, strict=True)])


def test_the_residual_rule_never_leaves_its_box():
    rule, rng = ResidualRule(CRITERION, (1.0, 0.9, 1.0), LOW, HIGH), random.Random(0)
    actions = [rule.act(None, None)]  # own factors above the box: clipped
    actions += [rule.act(None, _residuals(rng.uniform(-1, 4))) for _ in range(200)]
    assert all(lo <= a <= hi for action in actions for a, lo, hi in zip(action, LOW, HIGH, strict=True))
    assert actions[0] == list(HIGH)


def test_a_rule_is_named_and_keeps_the_watchdog_stall_window_in_iterations():
    with pytest.raises(ValueError, match="no rule 'nope'"):
        RulePolicy("nope")
    rule = RulePolicy("residual-rule")
    assert rule.env_params.interval == 50 and rule.env_params.relax_k_omega == "action"
    assert rule.watchdog(WatchdogSettings()).stall_steps == 6  # 3 steps of 100 = 6 of 50


@needs_openfoam
@pytest.mark.parametrize("name", ["residual-rule"])
@pytest.mark.parametrize("variant", ["SIMPLEC", "SIMPLE"])
def test_a_rule_converges_a_coarse_case_inside_its_box(tmp_path: Path, name: str, variant: str) -> None:
    case = _coarse_step(tmp_path / "step")
    if variant == "SIMPLE":  # the case's own factors (U 0.9, p 0.8) are too high for plain SIMPLE
        solution = case / "system" / "fvSolution"
        text = solution.read_text().replace("consistent      yes;", "consistent      no;")
        text = text.replace("fields { p 0.8; } equations { U 0.9;", "fields { p 0.3; } equations { U 0.7;")
        # plain SIMPLE at these factors stalls on this coarse mesh at p 0.14, U 5e-3 (its own run too)
        solution.write_text(text.replace("p               5e-2;", "p               0.3;")
                            .replace("U               1e-3;", "U               1e-2;"))
    report = solve_case(case, tmp_path / "out", rule=name, step_timeout_s=120)
    data = json.loads((tmp_path / "out" / "solve.json").read_text())
    assert report.converged and data["result"]["fields_from"] == "the controller"
    assert data["controller"]["rule"] == name
    assert data["settings"]["interval"] == RulePolicy(name).env_params.interval
    low, high = data["settings"]["action_low"], data["settings"]["action_high"]
    assert len(low) == 3 and all(len(step["action"]) == 3 for step in data["steps"])
    assert all(lo - 1e-9 <= a <= hi + 1e-9 for step in data["steps"]
               for a, lo, hi in zip(step["action"], low, high, strict=True))
    if variant == "SIMPLE":
        assert (low[1], high[1]) == pytest.approx((0.15, 0.375))  # own p 0.3: [own / 2, 1.25 own]


@needs_openfoam
def test_a_rule_that_crashes_the_solver_is_rescued_by_the_case_own_run(tmp_path: Path) -> None:
    """Plain SIMPLE forced to a box at 0.95 and above (experiments' action_box): the rule's first factors
    crash simpleFoam (NOTES: from alpha_u 0.7 / alpha_p 0.9); the case's own run replaces the result."""
    case = _coarse_step(tmp_path / "step")
    solution = case / "system" / "fvSolution"
    solution.write_text(solution.read_text().replace("consistent      yes;", "consistent      no;"))
    report = solve_case(case, tmp_path / "out", rule="residual-rule", step_timeout_s=120,
                        action_box=((0.98, 0.98, 0.98), (1.0, 1.0, 1.0)))
    data = json.loads((tmp_path / "out" / "solve.json").read_text())
    assert [event["kind"] for event in data["fallback"]][-1] == "rerun"
    assert data["result"]["fields_from"].startswith("the case's own settings")
    assert not math.isnan(report.iterations) and not _marked_processes(tmp_path)
