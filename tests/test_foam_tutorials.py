"""OpenFOAM's own simpleFoam tutorials (Debian's openfoam-examples) as users' cases, real simpleFoam.

Each runs through FoamCaseEnv as written, to convergence with exact iteration accounting (the paper's
case, backwardFacingStep2D, is capped: it takes ~420 iterations of a 20,540-cell mesh to converge),
and what the episode ran with is read back from its files as OpenFOAM itself reads them
(``foamDictionary -expand``): the case's SIMPLE/SIMPLEC choice, its relaxation of the fields the agent
does not control, its inlet and turbulence boundary conditions and its function objects are kept.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from foam_marks import OPENFOAM

from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv
from foam_bridge._errors import CaseError
from foam_bridge._openfoam import find_openfoam
from foam_bridge.foamdict import expand

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
pytestmark = [*OPENFOAM, pytest.mark.skipif(not TUTORIALS.is_dir(), reason="openfoam-examples not installed")]


def _plain(value):
    """Nested dicts/lists with numpy arrays as lists, so that == compares them."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    return value.tolist() if isinstance(value, np.ndarray) else value


def _cfg(tmp_path: Path, case: str | Path, **overrides) -> FoamEnvConfig:
    source = case if isinstance(case, Path) else TUTORIALS / case
    return FoamEnvConfig(**{"case_dir": source, "interval": 50, "max_iterations": 1000,
                            "step_timeout_s": 120.0, "work_dir": tmp_path / "work", **overrides})


def _episode(env: FoamCaseEnv, action) -> tuple[list[float], dict]:
    rewards = []
    while True:
        _, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        if terminated or truncated:
            return rewards, info


def _as_openfoam_reads(env: FoamCaseEnv, relative: str, action) -> dict:
    """A dictionary of the episode case expanded by OpenFOAM, with the last action's factors in place
    of the relaxation FIFOs (which only a running solver's bridge can feed)."""
    copy = env.root / "readback"
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(env.case_dir, copy, symlinks=True, ignore=shutil.ignore_patterns("relaxation.*"))
    text = episode_case.relaxation_text(env.cfg, *action, flat=env.case_info.flat_relaxation)
    for boundary in episode_case.pause_boundaries(env.cfg):
        episode_case.relaxation_fifo(copy, boundary).write_bytes(text)
    return expand(env.openfoam, copy, relative)


def _check_accounting(env: FoamCaseEnv, rewards: list[float], info: dict, outcome: str) -> None:
    cfg = env.cfg
    assert info["outcome"] == outcome, info["cause"]
    total = info["iterations"]
    assert sum(rewards) == -total == info["episode"]["return"]
    assert rewards[:-1] == [-cfg.interval] * (len(rewards) - 1) and 0 < -rewards[-1] <= cfg.interval
    assert len(env.parser.history) == total  # every iteration the solver ran is counted, no more
    if outcome == "converged":
        assert env.parser.converged_at == total
        assert all(info["residuals"][name] < limit for name, limit in cfg.convergence.items()
                   if name in info["residuals"])


def _run_and_read_back(tmp_path: Path, name: str, action, outcome: str = "converged", **overrides):
    openfoam = find_openfoam()
    tutorial = {rel: _plain(expand(openfoam, TUTORIALS / name, rel)) for rel in ("0/U", "system/fvSolution")}
    with FoamCaseEnv(_cfg(tmp_path, name, **overrides)) as env:
        obs, info = env.reset(seed=0)
        rewards, final = _episode(env, action)
        _check_accounting(env, rewards, final, outcome)
        solution = _plain(_as_openfoam_reads(env, "system/fvSolution", action))
        control = expand(openfoam, env.case_dir, "system/controlDict")
        velocity = _plain(expand(openfoam, env.case_dir, "0/U"))
    # the inlet (and every other boundary condition of U) is the tutorial's own
    assert velocity["boundaryField"] == tutorial["0/U"]["boundaryField"]
    initial = (env.case_info.inlet_state + env.case_info.cells_state) / env.cfg.state_scale
    assert obs[0] == pytest.approx(initial)
    # SIMPLE is the case's own but for the criterion; the agent's factors merged into the case's own
    own_simple = {k: v for k, v in tutorial["system/fvSolution"]["SIMPLE"].items() if k != "residualControl"}
    assert solution["SIMPLE"] == {**own_simple, "residualControl": dict(env.cfg.convergence)}
    # the bridge's function objects go beside the case's own
    ours = {episode_case.CELLS_FUNCTION, episode_case.INLET_FUNCTION, episode_case.PAUSE_FUNCTION}
    assert ours <= set(control["functions"])
    return tutorial["system/fvSolution"]["relaxationFactors"], solution["relaxationFactors"], control, final


@pytest.mark.slow  # a whole tutorial run
def test_pitz_daily_converges_with_its_own_simplec_and_relaxation(tmp_path: Path) -> None:
    own, used, control, final = _run_and_read_back(tmp_path, "pitzDaily", (0.9, 0.9))
    assert used["equations"] == {**own["equations"], "U": 0.9} and own["equations"]['".*"'] == 0.9
    assert used["fields"] == {"p": 0.9}
    assert "streamlines" in control["functions"]  # its #includeFunc
    assert final["inlet_velocity"] == 10.0  # the tutorial's inlet speed, reported


@pytest.mark.slow  # a whole tutorial run
def test_air_foil_2d_converges_with_plain_simple_and_its_own_factors(tmp_path: Path) -> None:
    own, used, _, final = _run_and_read_back(tmp_path, "airFoil2D", (0.7, 0.3))
    assert own == {"fields": {"p": 0.3}, "equations": {"U": 0.7, "nuTilda": 0.7}}
    assert used == own  # the agent's (0.7, 0.3) happen to be the tutorial's: nothing else changed
    assert np.isnan(final["inlet_velocity"])  # a freestream inlet has no value to report


@pytest.mark.slow  # a whole tutorial run
def test_t3a_converges_and_keeps_its_transition_model_factors(tmp_path: Path) -> None:
    own, used, control, _ = _run_and_read_back(tmp_path, "T3A", (0.9, 0.9))
    assert used["equations"] == {'".*"': 0.9, "U": 0.9} and own["equations"] == {'".*"': 0.9}
    assert {"wallShearStress", "kGraph"} <= set(control["functions"])


@pytest.mark.slow  # whole tutorial runs
def test_air_foil_2d_convergence_checked_at_its_own_and_at_a_higher_relaxation(tmp_path: Path) -> None:
    """The convergence check (confirm_alpha_u) on a case of plain SIMPLE with Spalart-Allmaras (no k or
    omega) that writes ascii fields, at its own factors (0.7, 0.3)."""

    def run(confirm: float | None, name: str) -> tuple[list[float], dict]:
        with FoamCaseEnv(_cfg(tmp_path / name, "airFoil2D", confirm_alpha_u=confirm)) as env:
            env.reset(seed=0)
            return _episode(env, (0.7, 0.3))

    _, plain = run(None, "plain")
    _, own = run(0.7, "own")
    (check,) = own["episode"]["confirmations"]  # at its own alpha_u: the solver's K stands
    assert (own["outcome"], own["iterations"]) == ("converged", plain["iterations"]) and check["passed"]
    assert set(check["residuals"]) == {"U", "p"}
    assert check["residuals"]["U"] == pytest.approx(check["solver_residuals"]["U"], rel=0.1)
    rewards, higher = run(0.9, "higher")  # at 0.9 its U residual reads ~3x higher: the run goes on
    first, *later = higher["episode"]["confirmations"]
    assert first["iteration"] == plain["iterations"] and not first["passed"]
    assert first["residuals"]["U"] > 2 * first["solver_residuals"]["U"]
    assert higher["outcome"] == "converged" and later and later[-1]["passed"]
    assert higher["iterations"] == later[-1]["iteration"] > plain["iterations"]
    assert higher["iterations"] % 50 == 0 and sum(rewards) == -higher["iterations"]


@pytest.mark.slow  # a whole tutorial run
def test_backward_facing_step_2d_runs_capped_with_its_include_funcs(tmp_path: Path) -> None:
    # the paper's case (20,540 cells, six function objects of its own): two steps of 25 iterations,
    # then the cap, to keep the test short
    own, used, control, _ = _run_and_read_back(tmp_path, "backwardFacingStep2D", (0.95, 0.95), "truncated",
                                               interval=25, max_iterations=50)
    assert used["equations"] == {"U": 0.95, '".*"': 0.8} and own["equations"]["U"] == 0.9
    own_functions = {"stressComponents", "pressureCoefficient", "sample", "sampleCp", "wallShearStress"}
    assert own_functions <= set(control["functions"])


def _air_foil_with_directives(tmp_path: Path) -> Path:
    """airFoil2D with #include, $var, a regex key and an #includeFunc added by a 'user'."""
    case = tmp_path / "airFoilUser"
    shutil.copytree(TUTORIALS / "airFoil2D", case)
    (case / "system" / "relaxationSettings").write_text("turbulenceFactor 0.7;\npressureFactor 0.3;\n")
    solution = case / "system" / "fvSolution"
    text = solution.read_text()
    start = text.index("relaxationFactors")
    solution.write_text(text[:start] + '#include "relaxationSettings"\nrelaxationFactors\n{\n'
                        '    fields { p $pressureFactor; }\n'
                        '    equations { U 0.7; "(nuTilda|k)" $turbulenceFactor; }\n}\n')
    control = case / "system" / "controlDict"
    control.write_text(control.read_text() + "\nfunctions\n{\n    #includeFunc residuals\n}\n")
    return case


@pytest.mark.slow  # a whole tutorial run
def test_a_case_with_include_var_and_regex_keys_runs_as_written(tmp_path: Path) -> None:
    case = _air_foil_with_directives(tmp_path)
    before = {p: p.read_bytes() for p in case.rglob("*") if p.is_file()}
    with FoamCaseEnv(_cfg(tmp_path, case, max_iterations=300)) as env:
        env.reset(seed=0)
        rewards, final = _episode(env, (0.7, 0.3))
        _check_accounting(env, rewards, final, "converged")
        factors = _as_openfoam_reads(env, "system/fvSolution", (0.7, 0.3))["relaxationFactors"]
        functions = expand(env.openfoam, env.case_dir, "system/controlDict")["functions"]
    assert factors == {"fields": {"p": 0.3}, "equations": {"U": 0.7, '"(nuTilda|k)"': 0.7}}
    assert "residuals" in functions and episode_case.PAUSE_FUNCTION in functions
    assert {p: p.read_bytes() for p in case.rglob("*") if p.is_file()} == before  # never modified


def test_setting_a_user_case_inlet_is_opt_in_and_uses_its_viscosity(tmp_path: Path) -> None:
    openfoam = find_openfoam()
    cfg = _cfg(tmp_path, "pitzDaily", inlet_velocity=15.0, inlet_turbulence=(0.05, 10.0))
    with FoamCaseEnv(cfg) as env:
        obs, info = env.reset(seed=0)
        velocity = expand(openfoam, env.case_dir, "0/U")["boundaryField"]
        k = expand(openfoam, env.case_dir, "0/k")
        omega = expand(openfoam, env.case_dir, "0/omega")
    np.testing.assert_allclose(velocity["inlet"]["value"], [15.0, 0.0, 0.0])
    assert velocity["outlet"] == {"type": "zeroGradient"} and info["inlet_velocity"] == 15.0
    expected_k = 1.5 * (0.05 * 15.0) ** 2
    assert k["boundaryField"]["inlet"]["value"] == pytest.approx(expected_k, rel=1e-12)
    assert omega["boundaryField"]["inlet"]["value"] == pytest.approx(expected_k / (10.0 * 1e-5), rel=1e-12)
    assert k["internalField"] == 0.375  # only the inlet changes in a user's case
    assert obs[0] == pytest.approx(15.0**2 / cfg.state_scale)


@pytest.mark.parametrize("name, overrides, message", [
    ("airFoil2D", {"inlet_velocity": 30.0},
     "0/U: boundaryField/inlet is type 'freestreamVelocity'; setting the inlet needs a fixedValue inlet"),
    ("pitzDaily", {"inlet_patch": "entry"}, "0/U: no boundaryField entry for the inlet patch 'entry'"),
    ("bump2D", {}, "system/blockMeshDict: entry 'edges' uses #codeStream/#calc, which OpenFOAM v1912 refuses "
                   "to compile when run as root"),
])
def test_a_case_the_bridge_cannot_drive_fails_at_creation_in_one_line(tmp_path, name, overrides, message):
    if name == "bump2D" and os.geteuid() != 0:
        pytest.skip("OpenFOAM compiles #codeStream for a normal user")
    with pytest.raises(CaseError) as error:
        FoamCaseEnv(_cfg(tmp_path, name, **overrides))
    text = str(error.value)
    assert "\n" not in text and text.startswith(str(TUTORIALS / name)) and message in text
    assert not (tmp_path / "work" / "env_0").exists()


def test_a_user_case_inlet_for_one_episode_needs_a_fixed_value_inlet(tmp_path: Path) -> None:
    with FoamCaseEnv(_cfg(tmp_path, "airFoil2D")) as env:
        with pytest.raises(CaseError, match="freestreamVelocity"):
            env.reset(options={"inlet_velocity": 30.0})
        obs, info = env.reset(seed=0)  # the case's own inlet still works
        assert np.isnan(info["inlet_velocity"]) and obs[0] > 0


@pytest.mark.slow  # a whole tutorial run
def test_a_case_under_a_path_with_spaces_runs_and_a_work_dir_with_spaces_is_refused(tmp_path: Path) -> None:
    """OpenFOAM itself cannot run a case whose path has a space; the bridge only copies the user's case,
    so the case may live anywhere, and a work_dir it cannot use is refused up front."""
    source = tmp_path / "my cases" / "pitzDaily"
    shutil.copytree(TUTORIALS / "pitzDaily", source)
    with FoamCaseEnv(_cfg(tmp_path, source, max_iterations=100)) as env:
        env.reset()
        _, _, _, _, info = env.step((0.9, 0.9))
    assert info["outcome"] in ("running", "truncated") and info["iterations"] == 50
    with pytest.raises(ValueError, match="contains whitespace") as raised:
        FoamCaseEnv(_cfg(tmp_path, "pitzDaily", work_dir=tmp_path / "work dir"))
    assert len(str(raised.value).splitlines()) == 1 and not (tmp_path / "work dir").exists()


@pytest.mark.slow  # three tutorial runs
def test_the_final_field_of_a_tutorial_reads_alike_in_ascii_binary_and_compressed(tmp_path):
    from foamlib import FoamFile

    from foam_bridge._fields import final_field

    with FoamCaseEnv(_cfg(tmp_path, "pitzDaily", max_iterations=100, keep_cases=True)) as env:
        env.reset(seed=0)
        _, info = _episode(env, (0.9, 0.9))
        assert (info["outcome"], info["iterations"]) == ("truncated", 100)
        written = final_field(env.case_dir, "U")
        episode = env.case_dir
        # the same fields rewritten by OpenFOAM's foamFormatConvert, in a clean copy of the tutorial
        converted = {}
        for write_format, compression, name in (("binary", "off", "U"), ("ascii", "on", "U.gz")):
            copy = tmp_path / f"{write_format}_{compression}"
            shutil.copytree(TUTORIALS / "pitzDaily", copy)
            for part in ("100", "constant"):
                shutil.copytree(episode / part, copy / part, dirs_exist_ok=True)
            control = FoamFile(copy / "system" / "controlDict")
            control["writeFormat"], control["writeCompression"] = write_format, compression
            template.run_application(env.openfoam, "foamFormatConvert", copy)
            assert sorted(f.name for f in (copy / "100").glob("U*")) == [name]
            converted[name] = final_field(copy, "U")
    assert written is not None and written[0] == 100.0 and written[1].shape == (12225, 3)
    for time, values in converted.values():
        assert time == 100.0
        np.testing.assert_allclose(values, written[1], rtol=1e-12, atol=0)  # the same, to the last ulp
