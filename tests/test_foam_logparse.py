"""Unit tests of the incremental simpleFoam log parser on captured v1912 output (no solver needed)."""

from __future__ import annotations

import math

import pytest

from foam_bridge._logparse import LogParser, field_residual

# Captured from a real run of the bridge's case (mesh_scale 0.3, SIMPLEC): the last two iterations.
CONVERGED_TAIL = """\
Time = 149

smoothSolver:  Solving for Ux, Initial residual = 0.00026592830832036009, Final residual = 2.18e-05, No Iter 2
smoothSolver:  Solving for Uy, Initial residual = 0.001000313226273016, Final residual = 5.79e-05, No Iter 2
GAMG:  Solving for p, Initial residual = 0.0056383735303309696, Final residual = 0.000177, No Iter 2
time step continuity errors : sum local = 0.0043633562448113245, global = -0.000468, cumulative = 0.795
smoothSolver:  Solving for omega, Initial residual = 0.0003050593132845669, Final residual = 7e-6, No Iter 2
smoothSolver:  Solving for k, Initial residual = 0.00076348817440708165, Final residual = 3.7e-05, No Iter 2
bounding k, min: -1.2902867287626867 max: 63.249945820977032 average: 11.237677172183355
ExecutionTime = 0.60999999999999999 s  ClockTime = 1 s

volFieldValue foamBridgeCells write:
    average(region0) of foamBridgeMagSqrU = 940.24984963464237

surfaceFieldValue foamBridgeInlet write:
    average(inlet) of foamBridgeMagSqrU = 1953.6399999999999

Time = 150

smoothSolver:  Solving for Ux, Initial residual = 0.00026287118690121767, Final residual = 2.28e-05, No Iter 2
smoothSolver:  Solving for Uy, Initial residual = 0.00096732570252395351, Final residual = 5.74e-05, No Iter 2
GAMG:  Solving for p, Initial residual = 0.0058876053549067522, Final residual = 0.000192, No Iter 2
GAMG:  Solving for p, Initial residual = 0.0001, Final residual = 0.00001, No Iter 2
smoothSolver:  Solving for omega, Initial residual = 4.347757134754579e-05, Final residual = 3e-6, No Iter
smoothSolver:  Solving for k, Initial residual = 0.00073292526075982513, Final residual = 3.39e-05, No Iter 2
ExecutionTime = 0.60999999999999999 s  ClockTime = 1 s


SIMPLE solution converged in 150 iterations

volFieldValue foamBridgeCells write:
    average(region0) of foamBridgeMagSqrU = 940.44596865952565

surfaceFieldValue foamBridgeInlet write:
    average(inlet) of foamBridgeMagSqrU = 1953.6399999999999

End
"""

BANNER = "trapFpe: Floating point exception trapping enabled (FOAM_SIGFPE).\n"
SIGFPE_TRACE = """\
Time = 337

smoothSolver:  Solving for Ux, Initial residual = 0.34, Final residual = 0.01, No Iter 2
#0  Foam::error::printStack(Foam::Ostream&) at ??:?
#1  Foam::sigFpe::sigHandler(int) at ??:?
#2  ? in /lib/x86_64-linux-gnu/libc.so.6
"""

FATAL_IO = """\
Time = 101

--> FOAM FATAL IO ERROR:
Cannot open include file "foamBridgeRelaxation" for directive #include

file: /tmp/case/system/fvSolution at line 60.
"""


def _parser() -> LogParser:
    return LogParser("foamBridgeCells", "foamBridgeInlet", divergence_threshold=1e3)


def test_iterations_residuals_state_and_convergence() -> None:
    parser = _parser()
    parser.feed(CONVERGED_TAIL)
    parser.finish()
    assert (parser.iteration, parser.completed, parser.converged_at) == (150, 150, 150)
    assert len(parser.history) == 2
    # the first solve of p in an iteration is the one residualControl judges
    assert parser.residuals["p"] == pytest.approx(0.0058876053549067522, rel=1e-15)
    assert parser.history[0]["Ux"] == pytest.approx(0.00026592830832036009, rel=1e-15)
    assert parser.cells_state == pytest.approx(940.44596865952565, rel=1e-15)
    assert parser.inlet_state == pytest.approx(1953.6399999999999, rel=1e-15)
    assert parser.state_iteration == 150
    assert parser.error is None and parser.diverged is None


def test_byte_by_byte_feeding_gives_the_same_result() -> None:
    whole, pieces = _parser(), _parser()
    whole.feed(CONVERGED_TAIL)
    data = CONVERGED_TAIL.encode()
    for i in range(0, len(data), 7):
        pieces.feed(data[i:i + 7])
    assert pieces.history == whole.history
    assert (pieces.cells_state, pieces.inlet_state, pieces.converged_at) == (
        whole.cells_state, whole.inlet_state, whole.converged_at)


def test_vector_field_residual_is_its_largest_component() -> None:
    residuals = {"Ux": 1e-4, "Uy": 3e-3, "p": 0.2}
    assert field_residual(residuals, "U") == 3e-3
    assert field_residual(residuals, "p") == 0.2
    assert field_residual(residuals, "k") is None
    assert math.isnan(field_residual({"Ux": 1e-4, "Uy": math.nan}, "U"))


def test_crash_causes_and_not_the_banner() -> None:
    parser = _parser()
    parser.feed(BANNER + SIGFPE_TRACE)
    assert parser.error == "floating point exception (SIGFPE)"
    assert parser.iteration == 337 and parser.completed == 0
    fatal = _parser()
    fatal.feed(BANNER + FATAL_IO)
    expected = 'FOAM FATAL ERROR: Cannot open include file "foamBridgeRelaxation" for directive #include'
    assert fatal.error == expected


@pytest.mark.parametrize("value", ["nan", "-nan", "inf", "5e3"])
def test_divergence_from_residuals(value: str) -> None:
    parser = _parser()
    parser.feed(f"Time = 7\n\nsmoothSolver:  Solving for Ux, Initial residual = {value}, Final residual = 1, "
                "No Iterations 1\n")
    assert parser.diverged is not None and "Ux" in parser.diverged and "iteration 7" in parser.diverged


def test_divergence_from_an_exploding_state() -> None:
    text = "Time = 3\nvolFieldValue foamBridgeCells write:\n    average(region0) of foamBridgeMagSqrU = {}\n"
    parser = _parser()
    parser.feed(text.format("1e+35"))
    assert parser.diverged is not None and "foamBridgeCells" in parser.diverged
    healthy = _parser()
    healthy.feed(text.format("1e+5"))
    assert healthy.diverged is None and healthy.cells_state == 1e5


DIVERGING = """\
Time = 6

smoothSolver:  Solving for Ux, Initial residual = 0.5, Final residual = 0.01, No Iterations 1
GAMG:  Solving for p, Initial residual = 0.9, Final residual = 0.05, No Iterations 3
ExecutionTime = 0.1 s  ClockTime = 0 s

Time = 7

smoothSolver:  Solving for Ux, Initial residual = nan, Final residual = nan, No Iterations 1
GAMG:  Solving for p, Initial residual = 0.8, Final residual = 0.05, No Iterations 3
ExecutionTime = 0.2 s  ClockTime = 0 s

volFieldValue foamBridgeCells write:
    average(region0) of foamBridgeMagSqrU = 1e+40

Time = 8

smoothSolver:  Solving for Ux, Initial residual = 0.1, Final residual = 0.01, No Iterations 1
ExecutionTime = 0.3 s  ClockTime = 0 s
"""


def test_parser_freezes_at_the_first_bad_iteration_however_the_output_is_chunked() -> None:
    results = []
    for size in (1, 13, len(DIVERGING)):
        parser = _parser()
        data = DIVERGING.encode()
        for i in range(0, len(data), size):
            parser.feed(data[i:i + size])
        parser.finish()
        results.append((parser.failed_at, parser.diverged, parser.iteration, parser.completed,
                        parser.history, parser.cells_state))
    assert results[0] == results[1] == results[2]
    failed_at, diverged, iteration, completed, history, cells = results[0]
    # nothing after the NaN counts: not iteration 8, not the exploding state, not iteration 7's end
    assert (failed_at, iteration, completed, cells) == (7, 7, 6, None)
    assert diverged == "initial residual of Ux = nan at iteration 7" and len(history) == 1


def test_state_limit_is_configurable() -> None:
    text = ("Time = 4\nsurfaceFieldValue foamBridgeInlet write:\n"
            "    average(inlet) of foamBridgeMagSqrU = 3e+06\n")
    strict = LogParser("foamBridgeCells", "foamBridgeInlet", state_limit=2.5e6)
    strict.feed(text)
    assert strict.failed_at == 4 and strict.diverged == (
        "state term foamBridgeInlet = 3000000.0 (limit 2.5e+06) at iteration 4")
    default = _parser()
    default.feed(text)
    assert default.diverged is None and default.inlet_state == 3e6


#: The end of a simpleFoam v1912 run that the case's runTimeControl (satisfiedAction end) stopped, verbatim.
RUN_TIME_CONTROL_STOP = """Time = 327

smoothSolver:  Solving for Ux, Initial residual = 3.87419e-05, Final residual = 9.25146e-06, No Iterations 3
GAMG:  Solving for p, Initial residual = 0.000287965, Final residual = 2.35456e-05, No Iterations 4
ExecutionTime = 12.14 s  ClockTime = 14 s

runTimeControl stopWhenSettled output:
    average: settled averages:
        volAverage(k)Mean: 1.6761, delta: 0.000979387

    average: settled condition satisfied
    Stopping calculation
    Writing fields


End
"""


def test_a_run_time_control_stop_is_the_case_own_end() -> None:
    parser = LogParser("cells", "inlet")
    parser.feed(RUN_TIME_CONTROL_STOP)
    parser.finish()
    assert (parser.stopped_at, parser.stopped_by, parser.converged_at) == (327, "stopWhenSettled", None)
    unmet = LogParser("cells", "inlet")
    unmet.feed(RUN_TIME_CONTROL_STOP.replace("    Stopping calculation\n", "    Conditions not met\n"))
    assert unmet.stopped_at is None and unmet.error is None


def test_a_run_restarted_from_a_later_time_counts_its_iterations_from_there() -> None:
    parser = LogParser("cells", "inlet", start=100)
    parser.feed("Time = 101\n\nsmoothSolver:  Solving for Ux, Initial residual = 0.01, "
                "Final residual = 0.001, No Iterations 2\nExecutionTime = 0.1 s  ClockTime = 0 s\n\n"
                "SIMPLE solution converged in 101 iterations\n")
    assert (parser.completed, parser.converged_at, parser.history) == (1, 1, [{"Ux": 0.01}])
