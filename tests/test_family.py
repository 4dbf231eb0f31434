"""Case families (foam_bridge._family) from OpenFOAM's own simpleFoam tutorials and the built-in step,
on the real OpenFOAM: each variant's files hold the varied values as OpenFOAM reads them
(``foamDictionary``), the manifest says what was built, a seed gives the same family, every variant
runs simpleFoam, and a variation that cannot apply is refused before anything is written."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from foam_marks import OPENFOAM, needs_openfoam

from foam_bridge import Variation, build_family, sample_variations
from foam_bridge._family import MANIFEST, read_manifest
from foam_bridge._openfoam import find_openfoam
from foam_bridge._template import TEMPLATE_DIR
from jaxsimrl.cli.main import main

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")


def needs_tutorials(test):
    """Mark a test that runs OpenFOAM on its tutorials (skipped where either is missing)."""
    for mark in (*OPENFOAM, pytest.mark.skipif(not TUTORIALS.is_dir(), reason="openfoam-examples missing")):
        test = mark(test)
    return test


def _read(case: Path, relative: str, entry: str) -> str:
    """An entry of a case's file as OpenFOAM reads it (appended entries merged), e.g. ``uniform (1 0 0)``."""
    openfoam = find_openfoam()
    result = subprocess.run([openfoam.executable("foamDictionary"), "-case", str(case), "-precision", "17",
                             "-entry", entry, "-value", str(case / relative)], capture_output=True,
                            text=True, check=True, cwd=case, env=openfoam.environment(case))
    return result.stdout.strip()


def _numbers(text: str) -> list[float]:
    return [float(token) for token in text.replace("(", " ").replace(")", " ").split()
            if token not in ("uniform", "nonuniform")]


def _close(text: str, expected: list[float]) -> bool:
    return np.allclose(_numbers(text), expected, rtol=1e-9, atol=1e-12)


def _runs(case: Path, tmp_path: Path, iterations: int = 3, append: str = "") -> None:
    """simpleFoam runs ``iterations`` SIMPLE iterations of a copy of ``case`` (``append`` added to its
    fvSolution) without an error."""
    openfoam = find_openfoam()
    run = tmp_path / f"run-{case.name}"
    shutil.copytree(case, run)
    with open(run / "system" / "fvSolution", "a") as out:
        out.write(append)
    subprocess.run([openfoam.executable("foamDictionary"), "-entry", "endTime", "-set", str(iterations),
                    str(run / "system" / "controlDict")], capture_output=True, check=True, cwd=run,
                   env=openfoam.environment(run))
    result = subprocess.run([openfoam.executable("simpleFoam"), "-case", str(run)], capture_output=True,
                            text=True, env=openfoam.environment(run), timeout=120, check=False, cwd=run)
    log = result.stdout + result.stderr
    assert result.returncode == 0 and "FOAM FATAL" not in log, log[-2000:]
    assert f"\nTime = {iterations}\n" in log and "\nEnd\n" in log, log[-2000:]


def _family(tmp_path: Path, base: Path, *variations: Variation, append: str = "") -> tuple[Path, list]:
    dest = tmp_path / "family"
    cases = build_family(base, dest, [*variations, Variation()])  # the neutral one: the base as it is
    for case in cases:
        _runs(case.path, tmp_path, append=append)
    return dest, cases


def test_sampling_is_seeded_and_each_variation_has_its_own_stream():
    ranges = {"speed": (0.5, 1.5), "mesh": (0.5, 1.0)}
    first = sample_variations(ranges, 4, seed=7)
    assert first == sample_variations(ranges, 4, seed=7) and first != sample_variations(ranges, 4, seed=8)
    assert all(0.5 <= v.speed <= 1.5 and 0.5 <= v.mesh <= 1 for v in first)
    assert all(v.angle == 0 and v.viscosity == v.initial == 1 for v in first)
    with_angle = sample_variations({**ranges, "angle": (-5, 5)}, 4, seed=7)
    assert [v.speed for v in with_angle] == [v.speed for v in first]  # adding a range moves nothing else
    with pytest.raises(ValueError, match="unknown variation"):
        sample_variations({"sped": (1, 2)}, 2, 0)
    with pytest.raises(ValueError, match="low 2 > high 1"):
        sample_variations({"speed": (2, 1)}, 2, 0)


def test_a_variation_is_checked_when_made():
    assert Variation(speed=2, viscosity=4).reynolds_ratio == 0.5
    for bad in ({"speed": 0}, {"mesh": -1}, {"initial": -0.5}, {"angle": 120}, {"viscosity": math.nan}):
        with pytest.raises(ValueError, match=f"variation {next(iter(bad))}="):
            Variation(**bad)


@needs_tutorials
def test_pitz_daily_speed_viscosity_and_a_coarser_mesh(tmp_path):
    dest, (case, neutral) = _family(tmp_path, TUTORIALS / "pitzDaily",
                                    Variation(speed=1.5, viscosity=2, mesh=0.5))
    path = case.path
    assert _close(_read(path, "0/U", "boundaryField/inlet/value"), [15, 0, 0])
    assert _close(_read(path, "0/k", "boundaryField/inlet/value"), [0.375 * 1.5**2])
    assert _close(_read(path, "0/epsilon", "boundaryField/inlet/value"), [14.855 * 1.5**3])
    assert _close(_read(path, "0/omega", "boundaryField/inlet/value"), [440.15 * 1.5])
    assert _close(_read(path, "0/nuTilda", "internalField"), [0])  # no inlet value to scale: 0 stays 0
    assert _close(_read(path, "constant/transportProperties", "nu"), [2e-5])
    assert case.cells == 3093 and neutral.cells == 12225  # 18x30 -> 9x15 ... per block
    manifest = read_manifest(dest)
    assert [entry["name"] for entry in manifest["cases"]] == ["pitzDaily-0", "pitzDaily-1"]
    entry = manifest["cases"][0]
    assert entry["variation"] == {"speed": 1.5, "angle": 0.0, "viscosity": 2, "mesh": 0.5, "initial": 1.0}
    assert entry["reynolds_ratio"] == 0.75 and entry["algorithm"] == "SIMPLEC"
    assert entry["inlet_patches"] == ["inlet"] and entry["inlet_velocity"] == [15.0, 0.0, 0.0]
    assert entry["cells"] == 3093 and entry["base"] == str(TUTORIALS / "pitzDaily")
    assert not list(dest.glob(".*"))  # no partial case or scratch copy left


@needs_tutorials
def test_pitz_daily_expt_inlet_scales_its_mapped_inlet_data(tmp_path):
    _, (case, _) = _family(tmp_path, TUTORIALS / "pitzDailyExptInlet", Variation(speed=0.5))
    data = TUTORIALS / "pitzDailyExptInlet" / "constant" / "boundaryData" / "inlet" / "0"
    for name, power in (("U", 1), ("k", 2), ("epsilon", 3)):
        base = _numbers(_mapped_list(data / name))
        assert np.allclose(_numbers(_mapped_list(case.path / "constant/boundaryData/inlet/0" / name)),
                           np.asarray(base) * 0.5**power)
    assert case.algorithm == "SIMPLE" and case.inlet_patches == ("inlet",) and case.inlet_velocity is None


def _mapped_list(path: Path) -> str:
    """The list of a boundaryData file, its count and comment lines left out."""
    lines = [line for line in path.read_text().splitlines() if not line.lstrip().startswith("//")]
    return " ".join(lines[1:])


@needs_tutorials
def test_air_foil_speed_angle_and_refined_mesh(tmp_path):
    _, (case, neutral) = _family(tmp_path, TUTORIALS / "airFoil2D", Variation(speed=1.5, angle=5, mesh=2))
    angle = math.radians(math.degrees(math.atan2(3.62, 25.75)) + 5)
    speed = 1.5 * math.hypot(25.75, 3.62)
    expected = [speed * math.cos(angle), speed * math.sin(angle), 0]
    for patch in ("inlet", "outlet"):  # both freestream patches
        assert _close(_read(case.path, "0/U", f"boundaryField/{patch}/freestreamValue"), expected)
        assert _close(_read(case.path, "0/nuTilda", f"boundaryField/{patch}/freestreamValue"), [0.21])
    assert _close(_read(case.path, "0/U", "internalField"), expected)
    assert case.cells == 4 * neutral.cells == 42880 and case.inlet_patches == ("inlet", "outlet")
    assert np.allclose(case.inlet_velocity, expected)


@needs_tutorials
def test_backward_facing_step_from_rest_on_a_coarse_mesh(tmp_path):
    _, (case, neutral) = _family(tmp_path, TUTORIALS / "backwardFacingStep2D",
                                 Variation(speed=0.5, mesh=0.5, initial=0))
    assert _close(_read(case.path, "0/U", "boundaryField/inlet/value"), [22.1, 0, 0])
    assert _close(_read(case.path, "0/U", "internalField"), [0, 0, 0])
    assert _close(_read(case.path, "0/omega", "boundaryField/inlet/value"), [181728 * 0.5])
    assert _close(_read(case.path, "0/k", "boundaryField/inlet/value"), [1.09e-3 * 0.25])
    assert neutral.cells == 20540 and 0.2 < case.cells / neutral.cells < 0.3


@needs_tutorials
def test_t3a_speed_and_initial_field(tmp_path):
    _, (case, _) = _family(tmp_path, TUTORIALS / "T3A", Variation(speed=1.5, initial=0.5))
    assert _close(_read(case.path, "0/U", "boundaryField/inlet/value"), [8.1, 0, 0])
    assert _close(_read(case.path, "0/U", "internalField"), [5.4 * 1.5 * 0.5, 0, 0])
    assert _close(_read(case.path, "0/k", "boundaryField/inlet/value"), [0.047633 * 2.25])
    assert _close(_read(case.path, "0/omega", "boundaryField/inlet/value"), [264.63 * 1.5])
    assert _close(_read(case.path, "0/k", "boundaryField/plate/value"), [0])  # a wall is no inlet
    assert _close(_read(case.path, "0/ReThetat", "boundaryField/inlet/value"), [160.99])  # intensity only
    assert case.algorithm == "SIMPLEC"


@needs_openfoam
def test_the_built_in_step_template_is_a_base_like_any_other(tmp_path):
    """Its blockMeshDict takes the cell counts from system/meshParameters ($nx): the expansion the
    family scales has them resolved, so the template needs nothing of its own. Like the template, its
    variants leave the relaxation factors to the env (fvSolution has none: plain SIMPLEC at factor 1
    divides by zero); run by hand, they take the tutorial's."""
    _, (case, neutral) = _family(tmp_path, TEMPLATE_DIR, Variation(speed=0.5, mesh=0.3),
                                 append="relaxationFactors { equations { U 0.9; \".*\" 0.8; } }\n")
    assert case.name == "backward_facing_step-0" and neutral.cells == 20540
    assert _close(_read(case.path, "0/U", "boundaryField/inlet/value"), [22.1, 0, 0])
    assert _close(_read(case.path, "0/k", "boundaryField/inlet/value"), [1.09e-3 * 0.25])
    assert 0.07 < case.cells / neutral.cells < 0.11


@needs_tutorials
def test_a_seed_gives_the_same_family(tmp_path):
    ranges = {"speed": (0.7, 1.3), "viscosity": (0.8, 1.25), "mesh": (0.3, 0.5)}
    manifests = []
    for name in ("one", "two"):
        build_family(TUTORIALS / "pitzDaily", tmp_path / name, sample_variations(ranges, 3, seed=3))
        manifests.append((tmp_path / name / MANIFEST).read_text())
        assert (tmp_path / name / "pitzDaily-2" / "0" / "U").read_text() == \
            (tmp_path / "one" / "pitzDaily-2" / "0" / "U").read_text()
    assert manifests[0] == manifests[1] and len(json.loads(manifests[0])["cases"]) == 3


@needs_tutorials
@pytest.mark.parametrize(("case", "variation", "reason"), [
    ("pitzDaily", Variation(angle=5), r"case pitzDaily: the angle of attack applies to external flows.*"
                                      r"inlet \(fixedValue\)"),
    ("pitzDailyExptInlet", Variation(angle=-3), r"inlet \(timeVaryingMappedFixedValue\)"),
    ("pitzDaily", Variation(initial=0.5), r"case pitzDaily: 0/U starts from rest"),
    ("airFoil2D", Variation(mesh=1.5), r"case airFoil2D ships a finished mesh .* not 1.5"),
])
def test_a_variation_that_cannot_apply_is_refused_before_anything_is_written(tmp_path, case, variation,
                                                                             reason):
    dest = tmp_path / "family"
    with pytest.raises(ValueError, match=reason) as refused:
        build_family(TUTORIALS / case, dest, [Variation(speed=1.1), variation])
    assert "\n" not in str(refused.value)
    assert not dest.exists()


@needs_tutorials
def test_the_cli_builds_a_family_of_several_bases(tmp_path, capsys):
    out = tmp_path / "fam"
    bases = [str(TUTORIALS / "pitzDaily"), str(TUTORIALS / "T3A")]
    code = main(["family", *bases, "--out", str(out), "--variants", "2", "--seed", "1",
                 "--speed", "0.8", "1.2", "--mesh", "0.25", "0.4"])
    printed = capsys.readouterr().out
    assert code == 0 and printed.count("built ") == 4, printed
    assert [entry["name"] for entry in read_manifest(out)["cases"]] == \
        ["pitzDaily-0", "pitzDaily-1", "T3A-0", "T3A-1"]
    code = main(["family", bases[0], "--out", str(tmp_path / "bad"), "--variants", "2", "--angle", "1", "2"])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and "angle of attack" in error
    for flags in (["--speed", "2", "1"], ["--variants", "0"], ["--mesh", "0", "1"], ["--angle", "x", "1"]):
        assert _exit_code(["family", bases[0], "--out", str(tmp_path / "bad"), *flags]) == 2
        assert capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "bad").exists()


def _exit_code(argv: list[str]) -> int:
    """main's exit code, whether the parser (SystemExit) or the command refused the input."""
    try:
        return main(argv)
    except SystemExit as stop:
        return int(stop.code or 0)
