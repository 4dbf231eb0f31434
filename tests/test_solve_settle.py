"""``solve --settle``: the case's own run stopped once its answer has settled (foam_bridge's answer monitor),
on the coarse step with the real simpleFoam, against the plain run of the same case to its budget."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from foam_marks import OPENFOAM
from test_solve import _coarse_step

from foam_bridge import read_internal_field, relative_l2, time_directories
from jaxsimrl.apps.foam.solve import SolveReport, solve_case

pytestmark = OPENFOAM
TOLERANCE = 1e-3
#: A criterion the coarse step never meets: only its answer can end the run before its budget (2000).
NEVER = "1e-12"
PROBES = """
functions
{
    wakeProbe
    {
        type probes; libs (sampling); fields (U p); writeControl timeStep; writeInterval 1;
        probeLocations ((0.1 0.0 0.0005) (0.2 0.0 0.0005));
    }
}
"""


def _field(case: Path, time: str, name: str) -> object:
    found = read_internal_field(case / time / name)
    assert found is not None, f"{case / time / name} unreadable"
    return found[0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """The coarse step with a probe: solved with --settle and with --settle off (its whole budget)."""
    root = tmp_path_factory.mktemp("settle")
    case = _coarse_step(root / "step")
    control = case / "system" / "controlDict"
    control.write_text(control.read_text() + PROBES)
    solve_case(case, root / "settled", residual=NEVER, settle=TOLERANCE, step_timeout_s=120)
    solve_case(case, root / "plain", residual=NEVER, settle=None, step_timeout_s=120)
    return case, root / "settled", root / "plain"


@pytest.mark.slow  # two coarse-step solves, one to its budget (~1 min)
def test_a_settled_answer_stops_the_run_early_within_the_tolerance_of_the_plain_run(runs) -> None:
    _, settled, plain = runs
    data, base = (json.loads((out / "solve.json").read_text()) for out in (settled, plain))
    result = data["result"]
    assert base["result"]["outcome"] == "not converged" and base["result"]["iterations"] == 2000
    assert result["outcome"] == "settled" and not result["converged"]
    assert result["iterations"] < 0.5 * base["result"]["iterations"]
    errors = result["iterative_error"]
    assert {"U", "p", "k", "omega"} <= set(errors) and max(errors.values()) <= TOLERANCE
    assert any(name.startswith("wakeProbe/") for name in errors)  # the case's own probe is monitored
    # the answer at the stop is within the tolerance of where the plain run ends (2000 iterations)
    stop, end = str(result["iterations"]), "2000"
    for name in ("U", "p", "k", "omega"):
        assert relative_l2(_field(settled, stop, name), _field(plain, end, name)) <= TOLERANCE, name
    assert set(result["residuals_not_met"]) == {"U", "p", "k", "omega"}


@pytest.mark.slow
def test_the_stopped_case_is_a_normal_case_in_its_own_format(runs) -> None:
    case, settled, _ = runs
    data = json.loads((settled / "solve.json").read_text())
    times = [path.name for _, path in time_directories(settled)]
    assert times == ["0", str(data["result"]["iterations"])]  # no sample left behind
    latest = settled / times[-1]
    assert b"format      ascii" in (latest / "U").read_bytes()[:1000]  # the case writes ascii
    assert (latest / "phi").is_file()
    assert (settled / "system" / "controlDict").read_text() == (case / "system" / "controlDict").read_text()
    assert not (settled / "system" / "jaxsimrlSettle").exists()


@pytest.mark.slow
def test_settle_off_is_the_plain_run_and_the_summary_says_how_precise(runs) -> None:
    _, settled, plain = runs
    base = json.loads((plain / "solve.json").read_text())
    assert "iterative_error" not in base["result"] and "answer" not in base
    summary = SolveReport(json.loads((settled / "solve.json").read_text())).summary()
    assert "settled" in summary and "iterative error (estimated, relative)" in summary
    assert "never met the criterion" in summary


@pytest.mark.parametrize("value", ["0", "-1e-3", "abc", "2"])
def test_a_bad_settle_tolerance_is_one_line_and_exit_2(tmp_path: Path, value: str) -> None:
    done = subprocess.run([sys.executable, "-m", "jaxsimrl", "solve", str(tmp_path), "--settle", value],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and "--settle" in done.stderr


@pytest.mark.slow  # one coarse-step solve of 300 iterations
def test_max_iterations_bounds_the_default_run(tmp_path: Path) -> None:
    """--max-iterations is the default run's budget too (it ran to the case's own endTime before)."""
    case = _coarse_step(tmp_path / "step")
    report = solve_case(case, tmp_path / "out", residual=NEVER, settle=None, max_iterations=300,
                        step_timeout_s=120)
    assert report.iterations == 300 and report.data["result"]["outcome"] == "not converged"
    assert (tmp_path / "out" / "300" / "U").is_file()
