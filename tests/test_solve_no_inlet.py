"""A case without an inlet (a lid-driven cavity) is a case too: ``solve`` runs it with a no-training rule,
and the shipped controller, which observes the flow relative to the inlet's, hands it to the case's own
settings instead of refusing it. The cavity is OpenFOAM's own (pisoFoam/RAS/cavity's mesh and fields),
made a steady laminar simpleFoam case (Re 100) with a tight criterion, so that it takes ~70 iterations."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from foam_marks import needs_openfoam

from foam_bridge._base_case import declared_patches
from foam_bridge._config import FoamEnvConfig
from foam_bridge._openfoam import find_openfoam
from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.controller import DEFAULT_CONTROLLER
from jaxsimrl.apps.foam.solve.settings import inlet_of

CAVITY = Path("/usr/share/doc/openfoam-examples/examples/incompressible/pisoFoam/RAS/cavity")
HEADER = "FoamFile {{ version 2.0; format ascii; class dictionary; object {}; }}\n"
FILES = {
    "system/controlDict": "application simpleFoam; startFrom latestTime; startTime 0; stopAt endTime; "
                          "endTime 1000; deltaT 1; writeControl timeStep; writeInterval 1000; purgeWrite 0; "
                          "writeFormat ascii; writePrecision 8; timeFormat general; timePrecision 6; "
                          "runTimeModifiable true; functions {}",
    "system/fvSchemes": "ddtSchemes { default steadyState; } gradSchemes { default Gauss linear; } "
                        "divSchemes { default none; div(phi,U) bounded Gauss linearUpwind grad(U); "
                        "div((nuEff*dev2(T(grad(U))))) Gauss linear; } laplacianSchemes { default Gauss "
                        "linear corrected; } interpolationSchemes { default linear; } snGradSchemes { "
                        "default corrected; }",
    "system/fvSolution": "solvers { p { solver GAMG; tolerance 1e-7; relTol 0.1; smoother GaussSeidel; } "
                         "U { solver smoothSolver; smoother GaussSeidel; tolerance 1e-8; relTol 0.1; } } "
                         "SIMPLE { nNonOrthogonalCorrectors 0; consistent yes; pRefCell 0; pRefValue 0; "
                         "residualControl { p 1e-5; U 1e-5; } } "
                         "relaxationFactors { equations { U 0.9; \".*\" 0.9; } }",
    "constant/turbulenceProperties": "simulationType laminar;",
    "constant/transportProperties": "transportModel Newtonian; nu [0 2 -1 0 0 0 0] 0.001;",
}


def _cavity(dest: Path) -> Path:
    if not CAVITY.is_dir():
        pytest.skip("openfoam-examples not installed")
    shutil.copytree(CAVITY, dest)
    for name in ("k", "epsilon", "nuTilda", "omega", "nut"):  # laminar: U and p alone
        (dest / "0" / name).unlink(missing_ok=True)
    for relative, body in FILES.items():
        (dest / relative).write_text(HEADER.format(Path(relative).name) + body + "\n")
    return dest


def test_a_config_without_an_inlet_cannot_set_the_inlet_speed() -> None:
    assert FoamEnvConfig(case_dir=Path("c"), inlet_patch=None).validate().inlet_patch is None
    with pytest.raises(ValueError, match="inlet_patch"):
        FoamEnvConfig(case_dir=Path("c"), inlet_patch=None, inlet_velocity=10.0).validate()
    with pytest.raises(ValueError, match="inlet_patch"):
        FoamEnvConfig(inlet_patch=None).validate()  # the built-in case sets its inlet's speed


@needs_openfoam
def test_the_inlet_is_the_case_s_own_or_none_and_a_named_one_must_exist(tmp_path: Path) -> None:
    openfoam = find_openfoam()
    cavity = _cavity(tmp_path / "cavity")
    assert declared_patches(cavity, openfoam) == ["movingWall", "fixedWalls", "frontAndBack"]
    assert inlet_of(cavity, None, openfoam) is None
    assert inlet_of(cavity, "movingWall", openfoam) == "movingWall"
    with pytest.raises(ValueError, match=r"--inlet-patch lid: .* no patch named 'lid' \(its patches: moving"):
        inlet_of(cavity, "lid", openfoam)
    with pytest.raises(ValueError, match="--inlet-patch lid"):  # solve says so before anything runs
        solve_case(cavity, tmp_path / "out", rule="residual-rule", inlet_patch="lid")
    assert not (tmp_path / "out").exists()


@needs_openfoam
@pytest.mark.parametrize("controller", ["learned", "residual-rule"])
def test_a_cavity_is_solved_by_a_rule_and_handed_to_its_own_settings_by_the_controller(
        tmp_path: Path, controller: str) -> None:
    cavity = _cavity(tmp_path / "cavity")
    out = tmp_path / "out"
    shipped = DEFAULT_CONTROLLER if controller == "learned" else None
    report = solve_case(cavity, out, policy=shipped, rule=None if shipped else controller, step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    assert report.converged and data["status"] == "complete"
    assert (out / data["result"]["time_directory"] / "U").is_file()
    if controller == "learned":
        assert data["result"]["fields_from"] == "the case's own settings (the controller does not apply)"
        reasons = " ".join(event["reason"] for event in data["fallback"])
        assert "no patch named 'inlet'" in reasons and "--inlet-patch" in reasons
    else:
        assert data["result"]["fields_from"] == "the controller"
        assert len(data["steps"]) >= 2 and all(step["source"] == "controller" for step in data["steps"])
