"""The no-training rules (jaxsimrl.apps.foam.solve.rules): their logic on made-up residuals, then ``solve
--controller`` on a coarse SIMPLEC and a coarse plain-SIMPLE case with the real simpleFoam."""

from __future__ import annotations

import json
import math
import random
import re
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from foam_marks import needs_openfoam
from test_solve import _coarse_step, _marked_processes

from foam_bridge import FoamEnvConfig
from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.rules import (
    GROWTH_DECADES,
    HOVER_STEPS,
    RAISE_SHARE,
    RISE_SHARE,
    SWITCH_DECADES,
    Bandit,
    GuardedRise,
    OwnFactors,
    RandomFactors,
    ResidualRule,
    RulePolicy,
)
from jaxsimrl.apps.foam.solve.settings import CaseSettings, check_factor, own_action, with_own
from jaxsimrl.apps.foam.solve.watchdog import WatchdogSettings, for_interval

CRITERION = {"U": 1e-3, "p": 1e-2}
OWN, LOW, HIGH = (0.7, 0.3, 0.7), (0.35, 0.15, 0.35), (0.875, 0.375, 0.875)


def _residuals(decades: float) -> dict[str, float]:
    """Residuals whose worst field is ``decades`` above the criterion (U the worst)."""
    return {"U": 1e-3 * 10**decades, "p": 1e-2 * 10 ** (decades - 0.5)}


def _raised(action: list[float], share: float = RAISE_SHARE) -> list[float]:
    return [a + share * (h - a) for a, h in zip(action, HIGH, strict=True)]


def test_the_residual_rule_raises_below_its_best_and_goes_back_to_own_for_good_on_growth():
    rule = ResidualRule(CRITERION, OWN, LOW, HIGH, simplec=False)
    assert rule.act(None, None) == list(OWN)  # plain SIMPLE: the case's own factors first
    assert rule.act(None, _residuals(3.0)) == list(OWN)  # the first boundary: the start-up transient
    first = rule.act(None, _residuals(2.5))  # below the best: half-way up to the top
    assert first == pytest.approx(_raised(list(OWN)))
    assert rule.act(None, _residuals(2.7)) == first  # 0.2 decade above the best: a transient, held
    second = rule.act(None, _residuals(2.4))
    assert second == pytest.approx(_raised(first))
    assert rule.act(None, _residuals(2.8)) == list(OWN)  # 0.4 decade above the best: back to own ...
    assert rule.act(None, _residuals(1.5)) == list(OWN)  # ... for good


def test_the_residual_rule_starts_a_simplec_case_at_its_box_top_and_freezes_near_its_criterion():
    rule = ResidualRule(CRITERION, (0.9, 1.0, 0.9), (0.2,) * 3, (0.95,) * 3, simplec=True)
    assert rule.act(None, None) == [0.95] * 3
    assert rule.act(None, _residuals(2.0)) == [0.95] * 3
    assert rule.act(None, _residuals(0.4)) == [0.95] * 3  # within a decade: no change, whatever comes
    assert rule.act(None, _residuals(0.9)) == [0.95] * 3
    assert rule.act(None, _residuals(1.1)) == [0.95] * 3  # 0.2 decade above the best (0.9): held
    assert rule.act(None, _residuals(1.1 + GROWTH_DECADES)) == [0.9, 0.95, 0.9]  # own, in the box


def test_the_bandit_tries_its_arms_upward_drops_an_arm_that_grew_and_plays_the_best():
    bandit = Bandit(CRITERION, OWN, LOW, HIGH)
    assert bandit.act(None, None) == list(OWN)
    assert bandit.act(None, _residuals(3.0)) == list(OWN)  # the start-up transient: no reward
    assert bandit.act(None, _residuals(2.9)) == pytest.approx(bandit.arm(1))  # own paid 0.1: try arm 1
    assert bandit.act(None, _residuals(2.5)) == pytest.approx(bandit.arm(2))  # arm 1 paid 0.4: try arm 2
    assert bandit.act(None, _residuals(3.0)) == pytest.approx(bandit.arm(1))  # arm 2 grew 0.5: gone
    for _ in range(20):  # arm 1 keeps paying more than own: it is played (with UCB's rare look at own)
        bandit.act(None, _residuals(bandit._last - (0.3 if bandit._arm == 1 else 0.1)))
    assert bandit._pulls[1] > 3 * bandit._pulls[0] and bandit._pulls[2] == 1


@pytest.mark.parametrize("rule_type", [ResidualRule, Bandit, RandomFactors, GuardedRise, OwnFactors])
@pytest.mark.parametrize("simplec", [False, True])
def test_a_rule_never_leaves_its_box(rule_type: type, simplec: bool) -> None:
    rule, rng = rule_type(CRITERION, (1.0, 0.9, 1.0), LOW, HIGH, simplec), random.Random(0)
    actions = [rule.act(None, None)]  # own factors above the box: clipped
    actions += [rule.act(None, _residuals(rng.uniform(-1, 4))) for _ in range(200)]
    assert all(lo <= a <= hi for action in actions for a, lo, hi in zip(action, LOW, HIGH, strict=True))
    assert actions[0] == list(HIGH) or rule_type is RandomFactors


def test_the_default_rule_holds_the_case_own_factors_whatever_the_residuals():
    rule, rng = OwnFactors(CRITERION, OWN, LOW, HIGH, simplec=False), random.Random(1)
    assert {tuple(rule.act(None, None if k == 0 else _residuals(rng.uniform(-1, 4)))) for k in range(50)} \
        == {OWN}
    assert RulePolicy("own").env_params.interval == 100


def test_the_guarded_rise_rises_after_its_warmup_and_hands_the_rest_to_the_case_own_factors():
    mid = [a + RISE_SHARE * (h - a) for a, h in zip(OWN, HIGH, strict=True)]
    rule = GuardedRise(CRITERION, OWN, LOW, HIGH, simplec=False)
    assert rule.act(None, None) == list(OWN)
    assert rule.act(None, _residuals(3.0)) == pytest.approx(mid)  # the warm-up step done: half-way up
    assert rule.act(None, _residuals(2.5)) == pytest.approx(mid) and rule.switched is None
    assert rule.act(None, _residuals(SWITCH_DECADES - 0.1)) == list(OWN)  # near the criterion: own ...
    assert rule.switched[1].startswith("planned: within")
    assert rule.act(None, _residuals(3.0)) == list(OWN)  # for good
    hover = GuardedRise(CRITERION, OWN, LOW, HIGH, simplec=False)
    hover.act(None, None)
    actions = [hover.act(None, _residuals(2.0)) for _ in range(HOVER_STEPS + 2)]  # no new best
    assert actions[1] == pytest.approx(mid) and actions[-1] == list(OWN)
    assert hover.switched[1] == f"detector: no new best in {HOVER_STEPS} steps"
    grown = GuardedRise(CRITERION, OWN, LOW, HIGH, simplec=False)
    grown.act(None, None)
    grown.act(None, _residuals(2.0))
    assert grown.act(None, _residuals(2.0 + GROWTH_DECADES + 0.1)) == list(OWN)
    assert "above its best" in grown.switched[1]


def test_the_random_baseline_draws_anew_each_step_the_same_for_every_run_and_holds_near_the_criterion():
    first, second = (RandomFactors(CRITERION, OWN, LOW, HIGH) for _ in range(2))
    distances = [3.0, 2.5, 2.0, 1.5, 0.5, 0.4]
    draws = [[rule.act(None, None if d is None else _residuals(d)) for d in [None, *distances]]
             for rule in (first, second)]
    assert draws[0] == draws[1]  # seeded: every run and case draws the same
    assert draws[0][1] == draws[0][0]  # the first step's start-up transient judges nothing, as for the rules
    assert len({tuple(a) for a in draws[0][1:5]}) == 4  # then a new draw each step far from the criterion
    assert draws[0][5] == draws[0][4] == draws[0][6]  # held within FREEZE_DECADES
    assert RulePolicy("random").provenance()["seed"] == 0


@pytest.mark.parametrize(("own", "check"), [(0.7, 0.7), (0.95, 0.95), (None, 0.9), (1.0, 0.9)])
def test_solve_confirms_at_the_case_own_alpha_u(own: float | None, check: float) -> None:
    settings = CaseSettings(factors=(own, 0.3, 0.7), flat=True, budget=None)
    assert check_factor(settings) == check


def test_a_rule_is_named_and_keeps_the_watchdog_stall_window_in_iterations():
    with pytest.raises(ValueError, match="no rule 'nope'"):
        RulePolicy("nope")
    rule, bandit = RulePolicy("residual-rule"), RulePolicy("bandit")
    assert rule.env_params.interval == 50 and rule.env_params.relax_k_omega == "action"
    # solve keeps the watchdog's stall window in iterations for every controller (watchdog.for_interval)
    assert for_interval(WatchdogSettings(), rule.env_params.interval).stall_steps == 6  # 3 of 100 = 6 of 50
    assert bandit.env_params.interval == 25
    assert for_interval(WatchdogSettings(), bandit.env_params.interval).stall_steps == 12
    assert bandit.provenance()["arms"] == 3 and "raise_share" in rule.provenance()


def _watching_the_plot(out: Path, lines: list[str]) -> Callable[[str], None]:
    """A ``say`` that, at the second step's line, waits (the solver paused) for the live solve.png that
    the first step's end asked for, while solve.json still says the solve is in progress."""
    def say(line: str) -> None:
        lines.append(line)
        if sum(bool(re.match(r"\s+\d+ it  factors", text)) for text in lines) != 2:
            return
        deadline = time.monotonic() + 30.0
        while not (out / "solve.png").is_file() and time.monotonic() < deadline:
            time.sleep(0.05)
        if (out / "solve.png").read_bytes()[:4] == b"\x89PNG" and \
                json.loads((out / "solve.json").read_text())["status"] == "incomplete":
            lines.append("solve.png drawn while solving")
    return say


_SLOW = pytest.mark.slow  # a real solve of the coarse step (20-40 s); one combination stays in the quick tier


@needs_openfoam
@pytest.mark.parametrize(("name", "variant"), [
    ("residual-rule", "SIMPLEC"), pytest.param("residual-rule", "SIMPLE", marks=_SLOW),
    pytest.param("bandit", "SIMPLEC", marks=_SLOW), pytest.param("bandit", "SIMPLE", marks=_SLOW)])
def test_a_rule_converges_a_coarse_case_inside_its_box(tmp_path: Path, name: str, variant: str) -> None:
    case = _coarse_step(tmp_path / "step")
    if variant == "SIMPLE":  # the case's own factors (U 0.9, p 0.8) are too high for plain SIMPLE
        solution = case / "system" / "fvSolution"
        text = solution.read_text().replace("consistent      yes;", "consistent      no;")
        text = text.replace("fields { p 0.8; } equations { U 0.9;", "fields { p 0.3; } equations { U 0.7;")
        # plain SIMPLE at these factors stalls on this coarse mesh at p 0.14, U 5e-3 (its own run too)
        solution.write_text(text.replace("p               5e-2;", "p               0.3;")
                            .replace("U               1e-3;", "U               1e-2;"))
    lines: list[str] = []
    report = solve_case(case, tmp_path / "out", rule=name, step_timeout_s=120,
                        say=_watching_the_plot(tmp_path / "out", lines))
    data = json.loads((tmp_path / "out" / "solve.json").read_text())
    assert report.converged and data["result"]["fields_from"] == "the controller"
    assert "solve.png drawn while solving" in lines  # solve.png is there before the run ends
    # every step's line shows the criterion's residuals where the run stands (a user watches it converge)
    step_lines = [line for line in lines if re.match(r"\s+\d+ it  factors", line)]
    assert len(step_lines) == len(data["steps"])
    last = data["steps"][-1]["residuals"]
    assert f"U {last['U']:.1e}/" in step_lines[-1] and f"p {last['p']:.1e}/" in step_lines[-1]
    assert data["controller"]["rule"] == name
    assert data["settings"]["interval"] == RulePolicy(name).env_params.interval
    low, high = data["settings"]["action_low"], data["settings"]["action_high"]
    assert len(low) == 3 and all(len(step["action"]) == 3 for step in data["steps"])
    assert all(lo - 1e-9 <= a <= hi + 1e-9 for step in data["steps"]
               for a, lo, hi in zip(step["action"], low, high, strict=True))
    # converged as the case's own criterion reads it at the case's own alpha_u (0.7 plain, 0.9 SIMPLEC)
    assert data["settings"]["confirm_alpha_u"] == (0.7 if variant == "SIMPLE" else 0.9)
    assert data["settings"]["algorithm"] == variant
    if variant == "SIMPLE":
        assert (low[1], high[1]) == pytest.approx((0.15, 0.375))  # own p 0.3: [own / 2, 1.25 own]


@needs_openfoam
@pytest.mark.slow  # a crash, then the case's own run of the coarse step (~40 s each)
@pytest.mark.parametrize("name", ["residual-rule", "bandit"])
def test_a_rule_that_crashes_the_solver_is_rescued_by_the_case_own_run(tmp_path: Path, name: str) -> None:
    """Plain SIMPLE forced to a box at 0.95 and above (experiments' action_box): the rule's first factors
    crash simpleFoam (NOTES: from alpha_u 0.7 / alpha_p 0.9); the case's own run replaces the result."""
    case = _coarse_step(tmp_path / "step")
    solution = case / "system" / "fvSolution"
    solution.write_text(solution.read_text().replace("consistent      yes;", "consistent      no;"))
    report = solve_case(case, tmp_path / "out", rule=name, step_timeout_s=120,
                        action_box=((0.98, 0.98, 0.98), (1.0, 1.0, 1.0)))
    data = json.loads((tmp_path / "out" / "solve.json").read_text())
    assert [event["kind"] for event in data["fallback"]][-1] == "rerun"
    assert data["result"]["fields_from"].startswith("the case's own settings")
    assert not math.isnan(report.iterations) and not _marked_processes(tmp_path)


def test_a_rule_box_holds_the_case_own_factors_exactly() -> None:
    cfg = FoamEnvConfig(relax_k_omega="action", action_low=(0.2, 0.2, 0.2), action_high=(0.95, 0.95, 0.95))
    simplec = CaseSettings(factors=(0.9, None, 0.7), flat=False, budget=None, variant="SIMPLEC")
    widened = with_own(cfg, simplec)  # p unrelaxed is 1, above the box's 0.95: the box takes it in
    assert widened.action_high == (0.95, 1.0, 0.95) and widened.action_low == (0.2, 0.2, 0.2)
    assert own_action(simplec, widened, 3) == [0.9, 1.0, 0.7]  # the own factors sent, not p 0.95
    assert own_action(simplec, cfg, 3) == [0.9, 0.95, 0.7]  # what the narrow box made of them
