"""Issue 56's fresh sets' candidates (experiments/settle/fresh-set, then fresh-set-2 and fresh-set-3 as
each earlier one was spent): every builder writes a case with its user's settings; the candidates hold
what their set needs (plain SIMPLE and SIMPLEC, the turbulence models mixed, meshes large enough for the
long cases, function objects on most); no candidate is a case of an earlier set; two builds of a case
are the same files; blockMesh and checkMesh pass and the function objects are well formed for v1912."""

from __future__ import annotations

import filecmp
import importlib.util
import re
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import NamedTuple

import pytest
from foam_marks import HAVE_OPENFOAM

from foam_bridge import find_openfoam

ROOT = Path(__file__).resolve().parent.parent
#: The development cases of issue 56 and every other case of heldout-v2 and -v3: no candidate is one.
EARLIER = ("controller/heldout-v2/cases.py", "controller/heldout-v3/cases.py")


class Needs(NamedTuple):
    """What a fresh set's candidates hold: at least ``simple`` plain SIMPLE and as many SIMPLEC, at least
    ``functions`` with function objects, every mesh's cells within ``cells``, at least ``large[1]`` meshes
    of ``large[0]`` cells or more; no case of the sets in ``earlier`` (under experiments/); ``twice``: the
    cases built twice and compared."""

    earlier: tuple[str, ...]
    simple: int
    functions: int
    cells: tuple[int, int]
    large: tuple[int, int]
    twice: tuple[str, ...]


SETS = {
    "fresh-set": Needs(EARLIER, 7, 11, (1, 30000), (12000, 6),
                       ("squareNearWall", "porousHedge", "annulusWideRKE", "squareBankInline")),
    "fresh-set-2": Needs((*EARLIER, "settle/fresh-set/cases.py"), 8, 14, (4000, 13000), (11000, 5),
                         ("squareTandemSST", "cylinderTandemRKE", "windbreakSST")),
    "fresh-set-3": Needs((*EARLIER, "settle/fresh-set/cases.py", "settle/fresh-set-2/cases.py"), 9, 14,
                         (4000, 11000), (9000, 5), ("cylinderPairSST", "squaresCloseKE", "stepWideSST")),
}


@pytest.fixture(scope="module", params=list(SETS))
def fresh_set(request) -> str:
    return request.param


@pytest.fixture(scope="module")
def needs(fresh_set) -> Needs:
    return SETS[fresh_set]


@pytest.fixture(scope="module")
def cases(fresh_set):
    name = f"settle_{fresh_set.replace('-', '_')}_cases"
    path = ROOT / "experiments" / "settle" / fresh_set / "cases.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.modules.pop(name, None)


@pytest.fixture(scope="module")
def written(cases, tmp_path_factory):
    """Every case's dictionaries and fields, written without meshing (heldout-v2's run made a no-op)."""
    root = tmp_path_factory.mktemp("written")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(cases.V2, "run", lambda *args: None)
        for name, builder in cases.CASES.items():
            builder(root / name)
    return root


def entry(text: str, key: str) -> str:
    found = re.search(rf"^\s*{key}\s+([^;]+);", text, re.M)
    assert found, key
    return found.group(1).strip()


def settings(case: Path) -> dict[str, str]:
    solution = (case / "system" / "fvSolution").read_text()
    control = (case / "system" / "controlDict").read_text()
    turbulence = (case / "constant" / "turbulenceProperties").read_text()
    model = "laminar" if "simulationType laminar" in turbulence else entry(turbulence, "RASModel")
    return {"consistent": entry(solution, "consistent"), "model": model, "endTime": entry(control, "endTime"),
            "writeInterval": entry(control, "writeInterval"), "deltaT": entry(control, "deltaT"),
            "functions": "\nfunctions\n{" in control}


def test_every_builder_is_described_and_new(cases, needs):
    assert 18 <= len(cases.CASES) <= 20
    assert set(cases.CASES) == set(cases.DESCRIPTIONS)
    earlier = "\n".join((ROOT / "experiments" / path).read_text() for path in needs.earlier)
    for name, builder in cases.CASES.items():
        doc = " ".join(builder.__doc__.split())
        assert doc.startswith(cases.DESCRIPTIONS[name][1] + "."), name  # opens with its kind
        for said in ("Re ", "endTime 3000", "Why:", "cells"):
            assert said in doc, (name, said)
        assert f"def {name}(" not in earlier, name  # not the name of a case of an earlier set


def test_the_candidates_hold_what_the_set_needs(cases, needs, written):
    found = {name: settings(written / name) for name in cases.CASES}
    algorithms = Counter(entry["consistent"] for entry in found.values())
    assert min(algorithms["no"], algorithms["yes"]) >= needs.simple, algorithms  # plain SIMPLE, SIMPLEC
    models = Counter(entry["model"] for entry in found.values())
    assert {"kEpsilon", "realizableKE", "kOmegaSST"} <= set(models) and models["laminar"] <= 2, models
    assert sum(entry["functions"] for entry in found.values()) >= needs.functions
    for name, entry_ in found.items():  # a user's budget and output
        assert entry_["endTime"] == "3000" and entry_["deltaT"] == "1", name
        assert entry_["writeInterval"] in ("500", "1000"), name
    # every case's own criterion is on, and no runTimeControl: the reference run removes only the criterion
    for name in cases.CASES:
        assert "residualControl" in (written / name / "system" / "fvSolution").read_text(), name
        assert "runTimeControl" not in (written / name / "system" / "controlDict").read_text(), name


def test_function_objects_are_what_a_user_writes(cases, written):
    kinds = Counter()
    for name in cases.CASES:
        control = (written / name / "system" / "controlDict").read_text()
        for kind in re.findall(r"^\s*type\s+(\w+);", control, re.M):
            kinds[kind] += 1
        if "forces" in control or "forceCoeffs" in control:
            assert "rho             rhoInf;" in control and "CofR" in control, name
        for block in re.findall(r"type\s+\w+;.*?\n\s*}", control, re.S):  # every one writes each iteration
            assert "writeControl    timeStep;" in block and "writeInterval   1;" in block, name
    assert kinds["forces"] + kinds["forceCoeffs"] >= 4 and kinds["probes"] >= 4
    assert kinds["surfaceFieldValue"] >= 4 and kinds["volFieldValue"] >= 1, kinds


@pytest.mark.openfoam
@pytest.mark.skipif(not HAVE_OPENFOAM, reason="simpleFoam not on PATH")
@pytest.mark.parametrize(("fresh_set", "name"), [(set_, name) for set_, needs in SETS.items()
                                                  for name in needs.twice], indirect=["fresh_set"])
def test_a_case_builds_the_same_twice_and_meshes(cases, name, tmp_path):
    for build in ("a", "b"):
        cases.CASES[name](tmp_path / build / name)
    compare = filecmp.dircmp(tmp_path / "a" / name, tmp_path / "b" / name, ignore=["log.blockMesh"])
    assert not compare.diff_files and not compare.left_only and not compare.right_only
    for sub in ("system", "constant", "0", "constant/polyMesh"):
        assert not filecmp.dircmp(tmp_path / "a" / name / sub, tmp_path / "b" / name / sub).diff_files, sub
    assert "End" in (tmp_path / "a" / name / "log.blockMesh").read_text()
    case = tmp_path / "a" / name
    assert _foam(case, "foamDictionary", "system/controlDict", "-entry", "functions", "-keywords",
                 log=False).split()


def _foam(case: Path, *command: str, ok: bool = True, log: bool = True) -> str:
    """``command``'s output (with its errors when ``log``), asserting its exit status."""
    # OpenFOAM's own environment (WM_PROJECT_DIR, PWD: else it warns on stdout that it is not cwd), as
    # the bridge runs it: a shell without WM_PROJECT_DIR (CI's) cannot run foamDictionary otherwise
    done = subprocess.run(command, cwd=case, env=find_openfoam().environment(case), capture_output=True,
                          text=True, check=False)
    assert (done.returncode == 0) == ok, (case.name, command, done.stdout[-2000:], done.stderr[-2000:])
    return done.stdout + done.stderr if log else done.stdout


def _only(case: Path, keep: list[str], named: list[str]) -> None:
    """The controlDict's functions cut down to ``keep``."""
    for other in named:
        if other not in keep:
            _foam(case, "foamDictionary", "system/controlDict", "-entry", f"functions/{other}", "-remove")


@pytest.mark.slow  # every case built, meshed, checked and post-processed once: 10-60 s a set
@pytest.mark.openfoam
@pytest.mark.skipif(not HAVE_OPENFOAM or not shutil.which("postProcess"), reason="OpenFOAM not on PATH")
def test_every_case_meshes_and_its_function_objects_find_their_patches_and_points(cases, needs, tmp_path):
    """checkMesh passes on every mesh; probes and surface and volume averages run on the initial fields
    (postProcess, no solver): every probe inside the mesh, every patch found. forces and forceCoeffs need
    the solver's turbulence model for the viscous stress, so postProcess stops there, after reading the
    dictionary and its patches (a patch it cannot find is a warning before that stop)."""
    large = 0
    for name, builder in cases.CASES.items():
        case = tmp_path / name
        builder(case)
        report = _foam(case, "checkMesh")
        assert "Mesh OK." in report, name
        cells = int(re.search(r"^\s*cells:\s+(\d+)", report, re.M).group(1))
        assert needs.cells[0] <= cells <= needs.cells[1], name
        assert f"{cells:,} cells" in " ".join(builder.__doc__.split()), name  # as its docstring says
        large += cells >= needs.large[0]
        control = case / "system" / "controlDict"
        original = control.read_text()
        if "functions" not in original:
            continue
        named = _foam(case, "foamDictionary", "system/controlDict", "-entry", "functions",
                      "-keywords", log=False).split()
        types = dict(re.findall(r"^    (\w+)\n    \{\n\s+type\s+(\w+);", original, re.M))
        assert set(types) == set(named), name
        forces = [fo for fo in named if types[fo] in ("forces", "forceCoeffs")]  # by type: two bodies, two
        others = [fo for fo in named if fo not in forces]
        if others:
            _only(case, others, named)
            log = _foam(case, "postProcess", "-time", "0", "-fields", "(U p k)")
            assert "Did not find location" not in log and "FATAL" not in log, name
            assert "Cannot find any patch" not in log, name
            for fo in others:
                assert list((case / "postProcessing" / fo).rglob("*")), (name, fo)
            control.write_text(original)
        if forces:
            _only(case, forces, named)
            log = _foam(case, "postProcess", "-time", "0", "-fields", "(U p k)", ok=False)
            assert "No valid model for viscous stress calculation" in log, (name, log[-1500:])
            assert "Cannot find any patch" not in log, name  # a wrong patch is only a warning
            control.write_text(original)
    assert large >= needs.large[1]
