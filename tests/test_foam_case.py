"""Case generation: inlet values, the 2h geometry, mesh resolution, the bridge's dictionaries; config."""

from __future__ import annotations

import stat
from pathlib import Path

import numpy as np
import pytest
from foam_marks import needs_openfoam
from foamlib import FoamFile

from foam_bridge import _base_case as base_case
from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge._config import (
    OBSERVATION_BOUND,
    STEP_HEIGHT_H,
    TEST_CONVERGENCE,
    FoamEnvConfig,
    failure_reward,
)
from foam_bridge._env import bounded_observation, observation_spec
from foam_bridge._errors import OpenFOAMNotFoundError
from foam_bridge._openfoam import find_openfoam
from foam_bridge.foamdict import expand

H = STEP_HEIGHT_H


def _points(case: Path) -> np.ndarray:
    return np.asarray(FoamFile(case / "constant" / "polyMesh" / "points")[None])


def test_inlet_turbulence_follows_the_papers_formula() -> None:
    k, omega = template.inlet_turbulence(50.0)
    assert k == pytest.approx(1.5 * (6.1e-4 * 50.0) ** 2, rel=1e-12)  # 1.3954e-3
    assert omega == pytest.approx(k / (0.009 * 1.56e-5), rel=1e-12)
    k_ref, _ = template.inlet_turbulence(44.2)
    assert k_ref == pytest.approx(1.09e-3, rel=1e-3)  # the tutorial's inlet k at U_ref


def test_mesh_parameters_scale_cell_counts_and_deepen_only_the_step() -> None:
    assert template.mesh_parameters(1.0, H) == {"yFloor": 0.0, **template.TUTORIAL_CELLS}
    coarse = template.mesh_parameters(0.01, H)
    assert all(coarse[name] == 1 for name in template.TUTORIAL_CELLS)  # at least one cell
    deep = template.mesh_parameters(0.5, 2 * H)
    assert deep["yFloor"] == pytest.approx(-1.0)
    assert deep["nyStep"] == 48 and deep["nyChannel"] == 32  # step blocks keep their cell size


@needs_openfoam
@pytest.mark.parametrize("mesh_scale, cells", [(0.25, 1264), (0.4, 3276), (1.0, 20540)])
def test_mesh_scale_changes_the_cell_count(tmp_path: Path, mesh_scale: float, cells: int) -> None:
    base_case.build_base_case(FoamEnvConfig(mesh_scale=mesh_scale), tmp_path / "base", find_openfoam())
    assert template.cell_count(tmp_path / "base") == cells


@needs_openfoam
def test_double_step_height_moves_only_the_floor_behind_the_step(tmp_path: Path) -> None:
    openfoam = find_openfoam()
    meshes = {}
    for name, height in (("h", H), ("2h", 2 * H)):
        cfg = FoamEnvConfig(mesh_scale=0.25, step_height=height)
        base_case.build_base_case(cfg, tmp_path / name, openfoam)
        meshes[name] = _points(tmp_path / name)
    single, double = meshes["h"], meshes["2h"]
    assert single[:, 1].min() == pytest.approx(0.0, abs=1e-12)
    assert double[:, 1].min() == pytest.approx(-H, abs=1e-12)  # floor 2h below the step's top
    for points in (single, double):  # inlet channel, top wall and domain length unchanged
        assert points[:, 1].max() == pytest.approx(9 * H)
        assert points[:, 0].min() == pytest.approx(-130 * H) and points[:, 0].max() == pytest.approx(50 * H)
        upstream = points[points[:, 0] < -1e-9]
        assert upstream[:, 1].min() == pytest.approx(H)  # the upstream floor is the step's top
    # the step face (x = 0) spans the full step height
    step_face = double[np.isclose(double[:, 0], 0.0)]
    assert step_face[:, 1].min() == pytest.approx(-H) and step_face[:, 1].max() == pytest.approx(9 * H)


@needs_openfoam
def test_episode_case_dictionaries_as_openfoam_reads_them(tmp_path: Path) -> None:
    cfg = FoamEnvConfig(mesh_scale=0.25, interval=50, max_iterations=300, convergence=dict(TEST_CONVERGENCE))
    openfoam = find_openfoam()
    info = base_case.build_base_case(cfg, tmp_path / "base", openfoam)
    episode = tmp_path / "episode"
    episode_case.write_episode_case(tmp_path / "base", episode, cfg, 50.0, info)
    k, omega = template.inlet_turbulence(50.0)
    velocity = expand(openfoam, episode, "0/U")["boundaryField"]["inlet"]["value"]
    np.testing.assert_allclose(velocity, [50.0, 0.0, 0.0])
    for name, value in (("k", k), ("omega", omega)):
        field = expand(openfoam, episode, f"0/{name}")
        assert field["boundaryField"]["inlet"]["value"] == pytest.approx(value, rel=1e-12)
        assert field["internalField"] == pytest.approx(value, rel=1e-12)
    assert episode_case.initial_state(info, 50.0) == pytest.approx((2500.0, 1e-16))

    control = expand(openfoam, episode, "system/controlDict")
    assert (control["endTime"], control["writeFormat"], control["runTimeModifiable"]) == (300, "binary", True)
    assert control["OptimisationSwitches"]["fileModificationSkew"] == 0
    functions = control["functions"]
    assert functions[episode_case.INLET_FUNCTION]["name"] == "inlet"
    pauses = [entry[0] for entry in functions[episode_case.PAUSE_FUNCTION]["timeVsFile"]]
    assert pauses == [50, 100, 150, 200, 250]
    assert episode_case.pause_boundaries(cfg) == [0, *pauses]

    for boundary in episode_case.pause_boundaries(cfg):
        assert stat.S_ISFIFO(episode_case.relaxation_fifo(episode, boundary).stat().st_mode)
    episode_case.make_uninterrupted(episode, cfg, 0.7, 0.3)  # FIFO 0 -> a file: readable without a solver
    solution = expand(openfoam, episode, "system/fvSolution")
    assert solution["relaxationFactors"] == {"fields": {"p": 0.3},
                                             "equations": {"U": 0.7, "k": 0.8, "omega": 0.8}}
    assert episode_case.PAUSE_FUNCTION not in expand(openfoam, episode, "system/controlDict")["functions"]
    assert solution["SIMPLE"]["consistent"] is True  # the built-in case's default: SIMPLEC
    assert solution["SIMPLE"]["residualControl"] == dict(TEST_CONVERGENCE)  # the template's own is gone
    assert solution["SIMPLE"]["nNonOrthogonalCorrectors"] == 0  # the rest of SIMPLE is the case's
    assert "foamBridgeCaseSIMPLE" not in solution
    assert (episode / "constant" / "polyMesh").is_symlink()


@pytest.mark.parametrize("relax_k_omega, expected", [(None, 0.8), ("alpha_u", 0.7), (0.6, 0.6)])
def test_relaxation_text_of_the_builtin_case(relax_k_omega, expected) -> None:
    cfg = FoamEnvConfig(relax_k_omega=relax_k_omega)
    factors = FoamFile.loads(episode_case.relaxation_text(cfg, 0.7, 0.3))
    assert factors["relaxationFactors"] == {"fields": {"p": 0.3}, "equations": {"U": 0.7, "k": expected,
                                                                                "omega": expected}}


def test_relaxation_text_of_a_user_case_names_only_what_the_agent_controls() -> None:
    own = FoamEnvConfig(case_dir="case")  # None: the case's own k/omega factors stay in force
    factors = FoamFile.loads(episode_case.relaxation_text(own, 0.7, 0.3))["relaxationFactors"]
    assert factors == {"fields": {"p": 0.3}, "equations": {"U": 0.7}}
    flat = FoamFile.loads(episode_case.relaxation_text(own, 0.7, 0.3, flat=True))["relaxationFactors"]
    assert flat == {"p": 0.3, "U": 0.7}


def test_missing_openfoam_is_a_one_line_error_saying_how_to_install(tmp_path: Path) -> None:
    with pytest.raises(OpenFOAMNotFoundError, match="apt-get install -y openfoam") as error:
        find_openfoam(path=str(tmp_path / "empty"))
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("overrides, field", [
    ({"mesh_scale": 0.0}, "mesh_scale"), ({"interval": 0}, "interval"),
    ({"max_iterations": 50}, "max_iterations"), ({"simple_variant": "PISO"}, "simple_variant"),
    ({"relax_k_omega": "omega"}, "relax_k_omega"), ({"inlet_turbulence": (0.01, -1.0)}, "inlet_turbulence"),
    ({"action_low": (0.5, 0.2), "action_high": (0.4, 0.95)}, "action_low"),
    ({"inlet_velocity": (65.0, 35.0)}, "inlet_velocity"), ({"convergence": {}}, "convergence"),
    ({"inlet_patch": ""}, "inlet_patch"), ({"relax_k_omega": 1.5}, "relax_k_omega"),
    ({"state_divergence_ratio": 0.0}, "state_divergence_ratio"),
    ({"state_divergence_ratio": float("inf")}, "state_divergence_ratio"),
    ({"state_interval": 0}, "state_interval"), ({"interval": 25, "state_interval": 10}, "state_interval"),
    ({"confirm_alpha_t": 0.8}, "confirm_alpha_t"),
])
def test_bad_config_is_a_one_line_value_error_naming_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(ValueError, match=f"FoamEnvConfig.{field}") as error:
        FoamEnvConfig(**overrides).validate()
    assert "\n" not in str(error.value)


def test_failure_reward_is_the_rest_of_the_cap_or_the_configured_penalty() -> None:
    assert failure_reward(FoamEnvConfig(max_iterations=4000), 1269) == -2731.0
    assert failure_reward(FoamEnvConfig(max_iterations=4000), 4000) == 0.0
    assert failure_reward(FoamEnvConfig(max_iterations=4000, failure_penalty=-2000.0), 1269) == -2000.0


def test_observation_is_always_finite_float32_inside_the_documented_box() -> None:
    raw = np.array([np.inf, -np.inf, np.nan, 1e40, -1e40, 3.5, -2.0])
    obs = bounded_observation(raw)
    assert obs.dtype == np.float32 and np.all(np.isfinite(obs))
    b = OBSERVATION_BOUND
    np.testing.assert_array_equal(obs, np.array([b, -b, b, b, -b, 3.5, -2.0], dtype=np.float32))
    spec = observation_spec(FoamEnvConfig(residual_features=1))
    assert spec.shape == (5,) and spec.low[0] == 0.0
    assert np.all(spec.low[1:] == -b) and np.all(spec.high == b) and np.all(np.isfinite(spec.high))


def test_a_start_time_keeps_that_directory_and_moves_the_run_and_its_pauses(tmp_path: Path) -> None:
    source = tmp_path / "case"
    for name in ("0", "50", "100", "system"):
        (source / name).mkdir(parents=True)
    (source / "100" / "U").write_text("")
    template.copy_case(source, tmp_path / "copy", start_time=100)
    assert sorted(path.name for path in (tmp_path / "copy").iterdir()) == ["0", "100", "system"]
    with pytest.raises(ValueError, match="start_time"):
        FoamEnvConfig(start_time=100).validate()  # the built-in case has only 0
    cfg = FoamEnvConfig(case_dir=source, start_time=100, max_iterations=300, interval=100).validate()
    (source / "system" / "controlDict").write_text("")
    (source / "system" / episode_case.BRIDGE_DIR).mkdir()
    episode_case.write_control(source, cfg, pause=True)
    control = FoamFile(source / "system" / episode_case.CONTROL_INCLUDE)
    assert (control["startTime"], control["endTime"]) == (100, 400)
    pause = control["functions"][episode_case.PAUSE_FUNCTION]["timeVsFile"]
    assert [row[0] for row in pause] == [200, 300]  # after iterations 100 and 200 of the run
