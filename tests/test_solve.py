"""``jaxsimrl solve``: a user's case converged by a controller, handed back as a normal OpenFOAM case.

Real simpleFoam on small cases: OpenFOAM's pitzDaily tutorial (its own mesh and settings) and the
built-in step template copied as a user's case at mesh_scale 0.4. Every wait is bounded.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from foam_marks import OPENFOAM
from foamlib import FoamFile
from slow_case import STOP_LIMIT_S, iterations_in, seconds_until, slow_pitz_daily, wait_until

from foam_bridge import _template as template
from foam_bridge import foamdict
from foam_bridge._config import FoamEnvConfig
from foam_bridge._logparse import LogParser
from foam_bridge._openfoam import BRIDGE_MARK, find_openfoam
from jaxsimrl import load_policy
from jaxsimrl.apps.foam.solve import DEFAULT_CONTROLLER, Controller, SolveReport, solve_case
from jaxsimrl.apps.foam.solve.agreement import compare_results, summary_line, tolerances
from jaxsimrl.apps.foam.solve.controller import policy_env_config
from jaxsimrl.apps.foam.solve.criterion import parse_residual, resolve
from jaxsimrl.apps.foam.solve.own import OwnProcess
from jaxsimrl.apps.foam.solve.settings import CaseSettings, nudged_factors, solve_config
from jaxsimrl.apps.foam.solve.watchdog import Watchdog

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
#: What the shipped controller says of itself (jaxsimrl/apps/foam/controllers/default/provenance.json).
SHIPPED = json.loads((DEFAULT_CONTROLLER / "provenance.json").read_text())
PYTHON = sys.executable
pytestmark = OPENFOAM
FOAM_ENV = {**os.environ, "WM_PROJECT_DIR": os.environ.get("WM_PROJECT_DIR", "/usr/share/openfoam")}


def _tree_hash(root: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        digest.update(str(path.relative_to(root)).encode())
        if path.is_file():
            digest.update(path.read_bytes())
    return digest.hexdigest()


def _coarse_step(dest: Path) -> Path:
    """The built-in step as a user's case: mesh_scale 0.4, SIMPLEC, own factors, the training criterion."""
    shutil.copytree(template.TEMPLATE_DIR, dest)
    with FoamFile(dest / "system" / "meshParameters") as params:
        params.update(template.mesh_parameters(0.4, 0.0127))
    solution = dest / "system" / "fvSolution"
    text = solution.read_text().replace("p               1e-4;", "p               5e-2;")
    text = text.replace("U               1e-6;", "U               1e-3;").replace(" 1e-5;", " 1e-3;")
    solution.write_text(text + '\nrelaxationFactors { fields { p 0.8; } equations { U 0.9; ".*" 0.8; } }\n')
    return dest


def _pitz_daily(tmp_path: Path) -> Path:
    if not (TUTORIALS / "pitzDaily").is_dir():
        pytest.skip("openfoam-examples not installed")
    return Path(shutil.copytree(TUTORIALS / "pitzDaily", tmp_path / "pitzDaily"))


def _marked_processes(under: Path) -> list[int]:
    """Live processes carrying the bridge's mark for a case under ``under``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            environ = (entry / "environ").read_bytes().split(b"\0")
            state = (entry / "stat").read_text().split()[2]
        except OSError:
            continue
        prefix = BRIDGE_MARK.encode() + b"="
        mark = next((item[len(prefix):] for item in environ if item.startswith(prefix)), None)
        if mark is not None and state != "Z" and str(under) in mark.decode(errors="replace"):
            found.append(int(entry.name))
    return found


def _check_normal_case(out: Path, time_name: str) -> None:
    """No bridge machinery; foamDictionary answers at once; simpleFoam restarts from the fields."""
    assert not list(out.rglob("foamBridge")) and not list(out.rglob("relaxation.*"))
    assert not any(path.is_fifo() or path.is_symlink() for path in out.rglob("*"))
    entry = subprocess.run(["foamDictionary", "-entry", "relaxationFactors", "system/fvSolution"], cwd=out,
                           env=FOAM_ENV, capture_output=True, text=True, timeout=20, check=True)
    assert "relaxationFactors" in entry.stdout
    restart = out.parent / "restart"
    shutil.copytree(out, restart, ignore=shutil.ignore_patterns("compare", "solve.*"))
    subprocess.run(["foamDictionary", "-entry", "startFrom", "-set", "latestTime", "system/controlDict"],
                   cwd=restart, env=FOAM_ENV, capture_output=True, timeout=20, check=True)
    log = subprocess.run(["simpleFoam"], cwd=restart, env=FOAM_ENV, capture_output=True, text=True,
                         timeout=120)
    assert log.returncode == 0, log.stdout[-2000:]
    assert f"Time = {int(time_name) + 1}\n" in log.stdout  # it went on from the converged fields
    assert "SIMPLE solution converged" in log.stdout


def _without_residual_control(case: Path) -> Path:
    """``case`` with its SIMPLE residualControl block removed (pitzDaily's holds no nested braces)."""
    solution = case / "system" / "fvSolution"
    text = solution.read_text()
    start = text.index("    residualControl")
    solution.write_text(text[:start] + text[text.index("}", start) + 1:])
    return case


#: A criterion of the case's own: stop once the mean k over the cells settles (runTimeControl, its
#: satisfiedAction end); on pitzDaily with its own settings it stops at iteration ~414.
STOP_WHEN_SETTLED = """
cellsK
{
    type volFieldValue; libs (fieldFunctionObjects); fields (k); operation volAverage; regionType all;
    writeControl timeStep; writeInterval 1; writeFields false; log false;
}
stopWhenSettled
{
    type runTimeControl; libs (utilityFunctionObjects); satisfiedAction end;
    conditions
    {
        settled
        {
            type average; functionObject cellsK; fields (volAverage(k)); tolerance 2e-4; window 50;
            windowType exact;
        }
    }
}
"""


def _settling_pitz_daily(tmp_path: Path) -> Path:
    """pitzDaily without residualControl, ended by a runTimeControl once its mean k settles."""
    case = _without_residual_control(_pitz_daily(tmp_path))
    (case / "system" / "stopWhenSettled").write_text(STOP_WHEN_SETTLED)
    control = case / "system" / "controlDict"
    control.write_text(control.read_text().replace("#includeFunc streamlines", '#include "stopWhenSettled"'))
    return case


def _last_time(log: str) -> int:
    return int([line for line in log.splitlines() if line.startswith("Time = ")][-1].split()[-1])


def test_residual_is_a_threshold_or_named_fields() -> None:
    assert parse_residual("1e-4") == 1e-4
    assert parse_residual("p=1e-3,U=1e-4") == {"p": 1e-3, "U": 1e-4}
    for bad in ("0", "-1", "nan", "p=", "p=1e-3,p=1e-4", "=1e-3", "p=x"):
        with pytest.raises(ValueError, match="--residual"):
            parse_residual(bad)
    assert resolve(1e-4, ["U", "p", "k"], Path("c")) == {"U": 1e-4, "p": 1e-4, "k": 1e-4}
    with pytest.raises(ValueError, match="q, which case c does not solve"):
        resolve("q=1e-3", ["U", "p"], Path("c"))


@pytest.mark.slow  # whole pitzDaily solves
def test_a_case_without_residual_control_is_solved_with_residual(tmp_path: Path) -> None:
    case = _without_residual_control(_pitz_daily(tmp_path))
    process = _cli(str(case), "--out", str(tmp_path / "refused"), cwd=tmp_path)
    _, err = process.communicate(timeout=180)
    assert process.returncode == 2 and err.count("\n") == 1 and "--residual" in err
    process = _cli(str(case), "--out", str(tmp_path / "unknown"), "--residual", "U=1e-3,omega=1e-3",
                   cwd=tmp_path)
    _, err = process.communicate(timeout=180)
    assert process.returncode == 2 and err.count("\n") == 1 and "omega, which case" in err
    assert not (tmp_path / "refused").exists() and not (tmp_path / "unknown").exists()
    out = tmp_path / "out"  # pitzDaily's own thresholds, given on the command line
    process = _cli(str(case), "--out", str(out), "--residual", "p=1e-2,U=1e-3,k=1e-3,epsilon=1e-3",
                   "--compare", "--controller", "learned", cwd=tmp_path)
    printed, err = process.communicate(timeout=600)
    assert process.returncode == 0, err
    # the CLI ends without the interpreter's teardown (jaxsimrl.cli.main.entry): nothing printed is lost
    assert printed.splitlines()[-1] == f"wrote {out} (the case, log.simpleFoam, solve.json, solve.png)"
    assert (out / "solve.png").read_bytes()[:4] == b"\x89PNG"
    criterion = {"p": 1e-2, "U": 1e-3, "k": 1e-3, "epsilon": 1e-3}
    assert f"criterion {criterion} (--residual)" in printed.splitlines()[0]
    data = json.loads((out / "solve.json").read_text())
    assert data["settings"]["criterion"] == criterion and data["settings"]["criterion_from"] == "--residual"
    assert data["result"]["converged"] and data["result"]["converged_by"] == "--residual, confirmed"
    own = data["compare"]["own"]  # the same criterion, or the runs are not comparable
    assert own["converged"] and own["converged_by"] == "--residual"
    for where in (out, out / "compare" / "own"):  # as OpenFOAM reads them
        solution = foamdict.expand(find_openfoam(), where, "system/fvSolution")
        assert solution["SIMPLE"]["residualControl"] == criterion
    _check_normal_case(out, data["result"]["time_directory"])  # its restart stops at once, converged


@pytest.mark.slow  # whole pitzDaily solves
def test_a_run_time_control_stop_is_converged_by_the_case_criterion(tmp_path: Path) -> None:
    case = _settling_pitz_daily(tmp_path)
    out = tmp_path / "out"
    report = solve_case(case, out, policy=DEFAULT_CONTROLLER, compare=True, step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    result, own = data["result"], data["compare"]["own"]
    assert report.converged and result["outcome"] == "converged" and not data["fallback"]
    assert data["settings"]["criterion"] == {} and "runTimeControl" in data["settings"]["criterion_from"]
    assert result["converged_by"] == "the case's function object stopWhenSettled (runTimeControl)"
    assert not data["confirmations"]  # no residual criterion to confirm
    log = (out / "log.simpleFoam").read_text()  # the controlled run stopped where its function object said
    assert "    Stopping calculation" in log and _last_time(log) == result["iterations"]
    assert result["time_directory"] == str(result["iterations"])
    assert (out / result["time_directory"] / "U").is_file()
    own_log = (out / "compare" / "own" / "log.simpleFoam").read_text()  # the plain simpleFoam run
    assert own["converged"] and "    Stopping calculation" in own_log
    assert own["iterations"] == _last_time(own_log)
    assert own["iterations"] < 2000  # it stopped there, not at its endTime


def _partly_run_pitz_daily(tmp_path: Path) -> tuple[Path, str]:
    """pitzDaily run for 100 iterations by plain simpleFoam (so it has 0/ and 100/; its endTime back at
    2000), and that run's log."""
    case = _pitz_daily(tmp_path)
    control = case / "system" / "controlDict"
    own = control.read_text()
    control.write_text(own.replace("endTime         2000;", "endTime         100;"))
    subprocess.run(["blockMesh"], cwd=case, env=FOAM_ENV, capture_output=True, timeout=60, check=True)
    log = subprocess.run(["simpleFoam"], cwd=case, env=FOAM_ENV, capture_output=True, text=True, timeout=300,
                         check=True).stdout
    control.write_text(own)
    assert (case / "100" / "U").is_file()
    return case, log


def _parsed(log: str) -> LogParser:
    parser = LogParser("", "")
    parser.feed(log)
    parser.finish()
    return parser


def _first_time(log: str) -> int:
    return int(next(line for line in log.splitlines() if line.startswith("Time = ")).split()[-1])


@pytest.mark.slow  # whole pitzDaily solves
def test_a_case_with_a_later_time_goes_on_from_it(tmp_path: Path) -> None:
    case, first = _partly_run_pitz_daily(tmp_path)
    out = tmp_path / "out"
    report = solve_case(case, out, policy=DEFAULT_CONTROLLER, compare=True, step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    result, own = data["result"], data["compare"]["own"]
    assert report.converged and data["settings"]["started_from"] == "time 100 (latest)"
    assert "started from time 100 (latest)" in report.summary()
    assert data["settings"]["max_iterations"] == 1900  # endTime 2000 minus the start
    log = (out / "log.simpleFoam").read_text()
    assert _first_time(log) == 101 and result["time_directory"] == str(100 + result["iterations"])
    assert _last_time(log) == 100 + result["iterations"]
    # it went on: its first residuals are those where the first run stopped, not those of a start from 0
    before, after = _parsed(first).history, _parsed(log).history
    assert before[0]["Ux"] == 1.0 and after[0]["Ux"] < 10 * before[-1]["Ux"] < 0.1
    assert (out / "100" / "U").is_file() and (out / result["time_directory"] / "U").is_file()
    own_log = (out / "compare" / "own" / "log.simpleFoam").read_text()  # the own run goes on from 100 too
    assert own["converged"] and _first_time(own_log) == 101 and _last_time(own_log) == 100 + own["iterations"]
    _check_normal_case(out, result["time_directory"])


@pytest.mark.slow  # a pitzDaily run
def test_from_time_picks_the_start_and_an_unknown_one_is_refused(tmp_path: Path) -> None:
    case, first = _partly_run_pitz_daily(tmp_path)
    process = _cli(str(case), "--out", str(tmp_path / "bad"), "--from-time", "50", cwd=tmp_path)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 2 and err.count("\n") == 1 and "no time directory 50" in err
    control = case / "system" / "controlDict"
    own = control.read_text()
    control.write_text(own.replace("endTime         2000;", "endTime         100;"))  # no budget left
    process = _cli(str(case), "--out", str(tmp_path / "bad"), cwd=tmp_path)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 2 and err.count("\n") == 1 and "--max-iterations" in err
    control.write_text(own)
    assert not (tmp_path / "bad").exists()
    out = tmp_path / "out"
    report = solve_case(case, out, from_time=0, step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    assert report.converged and data["settings"]["started_from"] == "time 0 (--from-time)"
    log = (out / "log.simpleFoam").read_text()  # it re-started: the first iteration of the first run
    assert _first_time(log) == 1 and _parsed(log).history[0]["Ux"] == _parsed(first).history[0]["Ux"] == 1.0
    assert data["settings"]["max_iterations"] == 2000 and not (out / "100").exists()
    assert data["result"]["time_directory"] == str(data["result"]["iterations"])


def test_watchdog_fires_on_growth_and_on_stall_only() -> None:
    healthy = Watchdog({"U": 1e-3, "p": 1e-2})
    for level in (1e-1, 3e-2, 1e-2, 4e-3, 2e-3):
        assert healthy.check({"U": level, "p": level}) is None
    growing = Watchdog({"U": 1e-3})
    assert growing.check({"U": 1e-2}) is None and growing.check({"U": 2e-1}).startswith("residuals grew")
    stalled = Watchdog({"U": 1e-3})
    reasons = [stalled.check({"U": 1e-2 * (1 + 0.01 * i)}) for i in range(4)]
    assert reasons[:3] == [None] * 3 and reasons[3].startswith("residuals stalled")
    assert stalled.check({"U": 1e-9}) is None  # it fires once


#: Function objects a user might add to pitzDaily, for solve --compare's agreement to compare.
PITZ_DAILY_FUNCTIONS = """
    #includeFunc fieldMinMax(U,p)
    #includeFunc patchAverage(name=inlet,p)
    probes { type probes; libs (sampling); fields (p U); probeLocations ((0.01 0 0) (0.1 0.01 0)); }
    forces { type forces; libs (forces); patches (lowerWall); rho rhoInf; rhoInf 1; CofR (0 0 0); }
"""


@pytest.fixture(scope="module")
def pitz_daily_solved(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str, SolveReport]:
    """(case, out, the case's tree hash before, report) of one ``solve --compare`` of pitzDaily by the
    shipped learned controller (a run other than the own one), with PITZ_DAILY_FUNCTIONS added to its own
    streamlines."""
    case = _pitz_daily(tmp_path_factory.mktemp("solved"))
    control = case / "system" / "controlDict"
    control.write_text(control.read_text().replace("#includeFunc streamlines\n",
                                                   "#includeFunc streamlines\n" + PITZ_DAILY_FUNCTIONS))
    before = _tree_hash(case)
    out = case.parent / "out"
    report = solve_case(case, out, policy=DEFAULT_CONTROLLER, compare=True, step_timeout_s=120)
    return case, out, before, report


@pytest.mark.slow  # pitz_daily_solved: solve --compare of pitzDaily
def test_solve_pitz_daily_gives_a_normal_converged_case(pitz_daily_solved) -> None:
    case, out, before, report = pitz_daily_solved
    assert _tree_hash(case) == before  # the user's case is never modified
    data = json.loads((out / "solve.json").read_text())
    assert data["status"] == "complete" and report.converged and data["result"]["converged"]
    result = data["result"]
    assert result["fields_from"] == "the controller" and result["time_directory"] == str(result["iterations"])
    assert data["confirmations"][-1]["passed"]
    assert data["controller"]["default"] and data["controller"]["recorded"] == SHIPPED
    criterion = set(data["settings"]["criterion"])
    assert set(data["residuals"]["controlled"]) == criterion == {"U", "p", "k", "epsilon"}
    assert len(data["residuals"]["controlled"]["U"]) == result["iterations"]
    assert data["steps"] and all(len(step["action"]) == len(SHIPPED["actions"]) for step in data["steps"])
    assert (out / "solve.png").read_bytes()[:4] == b"\x89PNG"
    own = data["compare"]["own"]
    assert own["converged"]
    assert math.isclose(own["ratio_iterations"], result["iterations"] / own["iterations"])
    assert (out / result["time_directory"] / "U").is_file() and (out / "log.simpleFoam").is_file()
    _check_normal_case(out, result["time_directory"])


@pytest.mark.slow  # pitz_daily_solved
def test_solve_compare_says_the_result_agrees_with_own(pitz_daily_solved) -> None:
    _, out, _, report = pitz_daily_solved
    agreement = json.loads((out / "solve.json").read_text())["compare"]["own"]["agreement"]
    assert agreement == report.data["compare"]["own"]["agreement"]
    criterion = report.data["settings"]["criterion"]
    assert agreement["agree"] is True
    assert list(agreement["tolerance"].values()) == list(tolerances(criterion))
    assert set(agreement["fields"]) == {"U", "p", "k", "epsilon"} and not agreement["notes"]
    assert all(0 < entry["value"] <= entry["tolerance"] for entry in agreement["fields"].values())
    objects = agreement["function_objects"]  # forces, moments, probes, min/max, inlet pressure
    assert {name.split(" ")[0] for name in objects} == {
        "forces/force.dat", "forces/moment.dat", "probes/p", "probes/U", "fieldMinMax(U,p)/fieldMinMax.dat",
        "patchAverage(name=inlet,p)/surfaceFieldValue.dat"}
    assert all(entry["ok"] for entry in objects.values())
    assert "    results agree with own: fields max rel. L2 " in report.summary()


@pytest.mark.slow  # pitz_daily_solved
def test_solve_compare_measures_the_spread_of_two_legitimate_runs(pitz_daily_solved) -> None:
    _, out, _, report = pitz_daily_solved
    own = json.loads((out / "solve.json").read_text())["compare"]["own"]
    spread = own["spread"]  # the own run against one at alpha_u 0.95 (pitzDaily's own 0.9, SIMPLEC: up)
    assert spread["measured"] and spread["nudge"] == "alpha_u 0.95" and spread["factors"][0] == 0.95
    assert spread["iterations"] > 0 and spread["iterations"] != own["iterations"]  # another run indeed
    assert (out / "compare" / "spread" / "log.simpleFoam").is_file()
    assert set(spread["fields"]) == {"U", "p", "k", "epsilon"}
    assert all(value > 0 for value in spread["fields"].values())  # converged runs stop apart
    for name, entry in own["agreement"]["fields"].items():  # the verdict allows the larger of the two
        assert entry["spread"] == spread["fields"][name]
        assert entry["allowed"] == max(entry["tolerance"], entry["spread"])
    assert "the criterion " in report.summary().split("results agree with own")[1]


def test_the_spread_run_nudges_alpha_u_the_way_the_algorithm_tolerates() -> None:
    def nudged(u: float | None, variant: str) -> tuple[tuple[float, float, float], str]:
        return nudged_factors(CaseSettings((u, 0.3, 0.7), False, 1000, variant))

    assert nudged(0.9, "SIMPLEC") == ((0.95, 0.3, 0.7), "alpha_u 0.95")  # SIMPLEC: up, never below own
    assert nudged(0.95, "SIMPLEC")[0][0] == 0.9  # at the top already: down
    assert nudged(0.7, "SIMPLE") == ((0.65, 0.3, 0.7), "alpha_u 0.65")  # plain SIMPLE: down
    assert nudged(None, "SIMPLE")[0][0] == 0.95  # U not relaxed (1): down


@pytest.mark.slow  # pitz_daily_solved and another run
def test_an_own_run_converged_to_a_looser_criterion_is_flagged(pitz_daily_solved, tmp_path: Path) -> None:
    case, out, _, report = pitz_daily_solved
    loose = Path(shutil.copytree(case, tmp_path / "loose"))  # the criterion 10x looser: it stops early
    solution = loose / "system" / "fvSolution"
    solution.write_text(solution.read_text().replace("1e-2;", "1e-1;").replace("1e-3;", "1e-2;"))
    process = OwnProcess(loose, tmp_path / "early", "early", 120.0, None, False)  # spawned: JAX is loaded
    try:
        early = process.result(150.0)
    finally:
        process.stop()
    assert early.converged and early.iterations < report.data["compare"]["own"]["iterations"]
    agreement = compare_results(out, Path(early.case), ["U", "p", "k", "epsilon"],
                                report.data["settings"]["criterion"], (True, True), "early")
    assert agreement["agree"] is False and agreement["fields"]["p"]["ok"] is False
    line = summary_line("early", agreement)
    assert line.startswith("results DIFFER from early: ") and "fields max rel. L2 " in line
    field_tolerance = tolerances(report.data["settings"]["criterion"])[0]
    assert line.split("fields max rel. L2 ")[1].split(";")[0].endswith(f" (p) > tol {field_tolerance:.0e}")


def test_the_controlled_run_starts_from_the_check_build(tmp_path: Path) -> None:
    case = _coarse_step(tmp_path / "step")
    work = tmp_path / "work"
    cfg, checked = solve_config(case, policy_env_config(None), work, 300, 0.9, None, 120.0)
    assert checked.directory == work / "checked"
    assert (checked.directory / "constant" / "polyMesh" / "boundary").is_file()
    assert checked.info.solved_fields and cfg.convergence == {"U": 1e-3, "p": 5e-2, "k": 1e-3, "omega": 1e-3}
    (checked.directory / "built-by-the-check").write_text("")  # not in the user's case: a rebuild loses it
    env = checked(cfg, work, 0)
    try:
        assert (env.base / "built-by-the-check").is_file() and env.case_info == checked.info
        obs, info = env.reset(seed=0)
        assert obs.shape == tuple(env.observation_space_spec.shape) and info["iterations"] == 0
    finally:
        env.close()


@pytest.mark.slow  # a whole solve and its rerun
def test_a_bad_controller_is_rescued_by_the_case_own_settings(tmp_path: Path) -> None:
    case = _coarse_step(tmp_path / "step")

    out = tmp_path / "out"  # actions the env rejects: the first step fails
    report = solve_case(case, out, policy=Controller(_Constant(math.nan, math.nan), {}), step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    assert data["status"] == "complete" and report.converged
    assert data["result"]["fields_from"].startswith("the case's own settings")
    assert [event["kind"] for event in data["fallback"]] == ["rerun"]
    assert (out / data["result"]["time_directory"] / "U").is_file()
    assert not _marked_processes(tmp_path)


class _Constant:
    """A controller forced to act the same factors whatever it sees (a bad one, for the fallbacks)."""

    env_params, action_dim = FoamEnvConfig(), 2

    def __init__(self, *factors: float) -> None:
        self.factors = np.asarray(factors)

    def act(self, obs, state=None, deterministic=True):
        return self.factors, state


def test_solve_a_coarse_step_case_with_a_loaded_policy(tmp_path: Path) -> None:
    case = _coarse_step(tmp_path / "step")
    before = _tree_hash(case)
    out = tmp_path / "out"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        policy = load_policy(DEFAULT_CONTROLLER)  # the policy API's object, as a user holds it
        report = solve_case(case, out, policy=policy, compare_constant=(0.9, 0.8), step_timeout_s=120)
    assert not [w for w in caught if "fork" in str(w.message)]  # the solver never forks this JAX process
    assert _tree_hash(case) == before and report.converged
    data = json.loads((out / "solve.json").read_text())
    assert data["result"]["fields_from"] == "the controller" and not data["fallback"]
    assert data["controller"]["checkpoint"] == SHIPPED["checkpoint"] and not data["controller"]["default"]
    constant = data["compare"]["constant"]
    assert constant["converged"] and (out / "compare" / "constant" / "log.simpleFoam").is_file()
    assert isinstance(constant["agreement"]["agree"], bool) and "with constant" in report.summary()
    assert "constant factors" in (out / "compare" / "constant" / "system" / "fvSolution").read_text()
    assert "constant factors" not in (out / "system" / "fvSolution").read_text()
    assert (out / "constant" / "polyMesh" / "boundary").is_file()  # meshed by the bridge, kept as a real mesh
    _check_normal_case(out, data["result"]["time_directory"])


@pytest.mark.slow  # a whole solve
def test_a_stalling_controller_hands_the_live_run_to_the_case_own_factors(tmp_path: Path) -> None:
    case = _coarse_step(tmp_path / "step")
    out = tmp_path / "out"
    report = solve_case(case, out, policy=Controller(_Constant(0.2, 0.2), {}), step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    (event,) = data["fallback"]
    assert event["kind"] == "watchdog" and "stalled" in event["reason"] and report.converged
    after = [step for step in data["steps"] if step["from_iteration"] >= event["at_iteration"]]
    assert after and all(step["action"] == [0.9, 0.8] for step in after)  # the case's own (U 0.9, p 0.8)
    assert data["result"]["fields_from"].startswith("the controller, then the case's own factors")


class _ConstantEvery25(_Constant):
    """The stalling controller, stepping every 25 iterations as issue 47's recurrent policy does."""

    env_params = FoamEnvConfig(interval=25)


@pytest.mark.slow  # a whole solve
def test_a_learned_controller_s_stall_window_is_300_iterations_whatever_its_step(tmp_path: Path) -> None:
    """The stall window is calibrated on steps of 100 iterations; counted in the controller's own steps of
    25 it was 75 iterations and handed runs back on plateaus the own run passes through."""
    case = _coarse_step(tmp_path / "step")
    out = tmp_path / "out"
    solve_case(case, out, policy=Controller(_ConstantEvery25(0.2, 0.2), {}), step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    (event,) = data["fallback"]
    assert event["kind"] == "watchdog" and "stalled" in event["reason"] and "12 steps" in event["reason"]
    assert event["at_iteration"] >= 300 and data["settings"]["interval"] == 25


@pytest.mark.slow  # a whole solve
def test_a_plain_simple_case_runs_with_its_own_settings(tmp_path: Path) -> None:
    case = _coarse_step(tmp_path / "step")  # the shipped controller learned SIMPLEC factors
    solution = case / "system" / "fvSolution"
    solution.write_text(solution.read_text().replace("consistent      yes;", "consistent      no;"))
    control = case / "system" / "controlDict"
    control.write_text(control.read_text().replace("endTime         2000;", "endTime         300;"))
    out = tmp_path / "out"
    report = solve_case(case, out, policy=DEFAULT_CONTROLLER, compare=True,  # the own run is the comparison's
                        step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    assert [event["kind"] for event in data["fallback"]] == ["not applicable"]
    agreement = data["compare"]["own"]["agreement"]  # out holds the own run's result, not converged in 300
    reason = "the own run (the controller's result is its) did not converge"
    assert agreement == {"agree": None, "same_run": True, "reason": reason}
    assert f"    no agreement figure with own: {reason}" in report.summary().splitlines()
    assert "SIMPLEC" in data["fallback"][0]["reason"] and not data["steps"]
    assert data["result"]["fields_from"] == "the case's own settings (the controller does not apply)"
    assert data["result"]["iterations"] == report.iterations <= 300
    assert (out / data["result"]["time_directory"] / "U").is_file()


def _cli(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([PYTHON, "-m", "jaxsimrl", "solve", *args], cwd=cwd, env=FOAM_ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow  # CLI subprocesses that load JAX
def test_a_case_it_cannot_drive_is_one_line_and_exit_2(tmp_path: Path) -> None:
    case = _coarse_step(tmp_path / "step")
    solution = case / "system" / "fvSolution"
    solution.write_text(solution.read_text().replace("residualControl", "noControl"))
    process = _cli(str(case), "--out", str(tmp_path / "out"), cwd=tmp_path)
    _, err = process.communicate(timeout=180)
    assert process.returncode == 2 and err.count("\n") == 1 and "residualControl" in err
    assert "--residual" in err
    assert not (tmp_path / "out").exists()  # nothing claimed, nothing left
    (case / "processor0").mkdir()
    process = _cli(str(case), "--out", str(tmp_path / "out2"), cwd=tmp_path)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 2 and err.count("\n") == 1 and "decomposed" in err


@pytest.mark.slow  # slow_case: steps over a minute
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_solve_leaves_no_solver_within_5_s_mid_step_and_says_so(tmp_path: Path,
                                                                          sig: signal.Signals) -> None:
    """On a case whose step lasts over a minute (tests/slow_case.py): Ctrl-C, SIGTERM (a batch scheduler,
    docker stop) and kill -9 of solve, sent while the controlled run and the own run are both mid-step,
    leave no solver after 5 s. A solver that ran on to the end of its step would fail this."""
    case = slow_pitz_daily(tmp_path / "slow")
    out = tmp_path / "out"
    process = _cli(str(case), "--out", str(out), "--compare", "--controller", "learned", cwd=tmp_path)
    controlled = out / ".solve-work" / "env_0" / "episode" / "log.simpleFoam"
    own = out / "compare" / "own" / "log.simpleFoam"

    def both_mid_step() -> bool:
        return min(iterations_in(controlled), iterations_in(own)) >= 3 or process.poll() is not None

    try:
        wait_until(both_mid_step, 240, "both solvers to be 3 iterations into their first step")
        assert process.poll() is None, process.communicate()
        assert iterations_in(controlled) < 90  # the step has a minute to go
        process.send_signal(sig)
        took = seconds_until(lambda: not _marked_processes(tmp_path), 30.0)
        _, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert took < STOP_LIMIT_S, f"a solver ran on for {took:.1f} s after {sig.name}"
    assert process.returncode == {signal.SIGINT: 130, signal.SIGTERM: 143}.get(sig, -signal.SIGKILL)
    status = json.loads((out / "solve.json").read_text())
    if sig == signal.SIGKILL:
        assert status["status"] == "incomplete"
    else:
        assert status["status"] == "interrupted" and "every solver it started was stopped" in status["holds"]
        assert err.strip().splitlines()[-1] == ("jaxsimrl solve: interrupted" if sig == signal.SIGINT else
                                                "jaxsimrl solve: terminated (SIGTERM)")
