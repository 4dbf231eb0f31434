"""The case generator (foam_bridge._generator, issue 47) on the real OpenFOAM, on coarse meshes: every kind
meshes (checkMesh says OK), is a one-cell-thick 2-D case with the four patches, and converges; a seed gives
the same specs and files; the resolution changes the cells only; no kind is a reserved held-out kind; a
case whose own run does not converge is rejected and recorded, and a second call goes on from the manifest;
the CLI; ``train-foam --family`` finds exactly the accepted cases."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
from foam_marks import OPENFOAM
from foamlib import FoamFile

import foam_bridge._generator as generator
from foam_bridge import GEOMETRY_KINDS, CaseSpec, generate_cases, read_generated, sample_specs, write_case
from foam_bridge._generator_specs import KIND_DESCRIPTIONS
from foam_bridge._openfoam import find_openfoam
from foam_bridge._template import cell_count, run_application
from jaxsimrl.apps.foam.cli.train_family import family_case_dirs
from jaxsimrl.cli.main import main

pytestmark = OPENFOAM

ROOT = Path(__file__).resolve().parent.parent
RESERVED = ROOT / "experiments" / "controller" / "heldout-v2" / "reserved_kinds.json"
#: Words that name a reserved kind's geometry (reserved_kinds.json's "what"): no generated kind may use them.
RESERVED_WORDS = ("cylinder", "tube", "jet", "impinging", "cavity", "recess", "annul", "concentric", "rotat",
                  "room", "box", "porous", "darcy")
#: Settings that converge any drawn geometry quickly: the geometry under test, not a user's choice.
EASY = {"algorithm": "SIMPLEC", "factors": (("U", 0.9), ("p", 1.0), ("turbulence", 0.8)),
        "criterion": (("p", 1e-3), ("U", 1e-3), ("turbulence", 1e-3)), "end_time": 2000}


def _spec(kind: str, seed: int = 0, **changes) -> CaseSpec:
    return dataclasses.replace(sample_specs(1, seed, kinds=(kind,))[0], **changes)


def _boundary(case: Path) -> dict[str, dict]:
    return dict(FoamFile(case / "constant" / "polyMesh" / "boundary")[None])


def _points(case: Path) -> np.ndarray:
    text = (case / "constant" / "polyMesh" / "points").read_text()
    body = text[text.index("(", text.index("}")):]
    return np.array([[float(v) for v in row.split()] for row in re.findall(r"\(([^()]+)\)", body)])


@pytest.mark.parametrize("kind", GEOMETRY_KINDS)
def test_every_kind_is_a_valid_2d_case_that_converges(kind, tmp_path):
    openfoam = find_openfoam()
    case = write_case(_spec(kind, **EASY), tmp_path / kind, resolution=0.4, openfoam=openfoam)
    assert not case.with_name(f"{kind}.partial").exists()
    run_application(openfoam, "checkMesh", case)
    assert "Mesh OK" in (case / "log.checkMesh").read_text()
    patches = _boundary(case)
    assert {name: entry["type"] for name, entry in patches.items()} == \
        {"inlet": "patch", "outlet": "patch", "walls": "wall", "frontAndBack": "empty"}
    cells = cell_count(case)
    assert 400 < cells < 3000 and patches["frontAndBack"]["nFaces"] == 2 * cells  # one cell thick
    assert len(np.unique(_points(case)[:, 2])) == 2
    own = generator.run_own(case, openfoam, tmp_path / "own")
    assert own.converged and own.exit_code == 0 and 0 < own.iterations < 2000, own
    assert (case / "log.simpleFoam").is_file() and not (tmp_path / "own").exists()
    assert sorted(p.name for p in case.iterdir() if p.name[0].isdigit()) == ["0"]  # the fields stay out


def _files(case: Path) -> dict[str, bytes]:
    return {str(p.relative_to(case)): p.read_bytes() for p in sorted(case.rglob("*"))
            if p.is_file() and not p.name.startswith("log.")}


def test_a_seed_gives_the_same_specs_and_files(tmp_path):
    specs = sample_specs(6, 3)
    assert specs == sample_specs(6, 3) and sample_specs(9, 3)[:6] == specs  # more cases keep the first ones
    assert sample_specs(6, 4) != specs
    assert [spec.kind for spec in specs] == list(GEOMETRY_KINDS)
    assert [spec.name for spec in specs] == [f"{kind}-{k}" for k, kind in enumerate(GEOMETRY_KINDS)]
    assert all(CaseSpec.from_json(json.loads(json.dumps(spec.to_json()))) == spec for spec in specs)
    for spec in (specs[2], specs[5]):  # curved edges: a bump and a bend
        first = write_case(spec, tmp_path / "a" / spec.name, resolution=0.3)
        again = write_case(sample_specs(6, 3)[specs.index(spec)], tmp_path / "b" / spec.name, resolution=0.3)
        assert _files(first) == _files(again)


def test_the_drawn_settings_are_users_settings():
    specs = sample_specs(60, 0)
    for spec in specs:
        factors, criterion = dict(spec.factors), dict(spec.criterion)
        assert 1e4 <= spec.reynolds <= 2e5 and spec.model in ("kEpsilon", "realizableKE", "kOmegaSST")
        assert 2000 <= spec.end_time <= 4000 and criterion["U"] in (1e-3, 1e-4)
        assert criterion["turbulence"] == criterion["U"]
        assert criterion["p"] in (criterion["U"], 10 * criterion["U"])
        if spec.algorithm == "SIMPLEC":
            assert factors["p"] == 1 and 0.8 <= factors["U"] <= 0.95 and 0.7 <= factors["turbulence"] <= 0.95
        else:
            assert 0.5 <= factors["U"] <= 0.9 and 0.2 <= factors["p"] <= 0.5
    assert 20 <= sum(spec.algorithm == "SIMPLE" for spec in specs) <= 40
    with pytest.raises(ValueError, match="unknown geometry kind"):
        sample_specs(2, 0, kinds=("cylinder",))


@pytest.mark.parametrize("kind", ["step", "bend"])
def test_the_resolution_changes_the_cells_only(kind, tmp_path):
    spec = _spec(kind, seed=1)
    coarse = write_case(spec, tmp_path / "coarse", resolution=0.5)
    fine = write_case(spec, tmp_path / "fine", resolution=1.0)
    assert 3.0 < cell_count(fine) / cell_count(coarse) < 5.0
    boxes = [np.array([pts.min(axis=0), pts.max(axis=0)]) for pts in (_points(coarse), _points(fine))]
    # the same extent; a curved wall's extreme lies between mesh points, so within 0.5 % of the size
    np.testing.assert_allclose(boxes[0], boxes[1], rtol=0, atol=5e-3 * np.ptp(boxes[1][:, :2]))
    assert np.ptp(boxes[1][:, :2]) > 0.1
    for name in ("system/fvSolution", "system/controlDict", "system/fvSchemes", "0/U", "0/k", "constant/"
                 "turbulenceProperties"):
        assert (coarse / name).read_text() == (fine / name).read_text(), name


def _reserved_description(text: str) -> list[str]:
    return [word for word in RESERVED_WORDS if word in text.lower()]


def test_no_kind_is_a_reserved_held_out_kind():
    reserved = json.loads(RESERVED.read_text())["reserved"]
    names = {entry["kind"] for entry in reserved}
    assert names == {"bluff-body", "tube-bank", "impinging-jet", "wall-cavity", "annulus", "ventilated-room",
                     "porous-obstacle"}
    assert not names & set(GEOMETRY_KINDS)
    assert set(KIND_DESCRIPTIONS) == set(GEOMETRY_KINDS)
    for kind, description in KIND_DESCRIPTIONS.items():
        assert not _reserved_description(f"{kind} {description}"), kind
    for entry in reserved:  # the check itself can fail: each reserved description trips it
        assert _reserved_description(entry["what"]), entry
    assert all(float(dict(spec.geometry)["angle"]) <= 180 for spec in sample_specs(60, 0, kinds=("bend",)))


def test_a_case_that_does_not_converge_is_rejected_and_a_second_call_goes_on(tmp_path, monkeypatch):
    drawn, runs = generator.draw_spec, []

    def draw(seed, index, kinds, *rest):  # case 0 gets 5 iterations: its own run cannot converge
        spec = dataclasses.replace(drawn(seed, index, kinds, *rest), **EASY)
        return dataclasses.replace(spec, end_time=5) if index == 0 else spec

    def counted(case, *args):
        runs.append(case.name)
        return own_run(case, *args)

    own_run = generator.run_own
    monkeypatch.setattr(generator, "draw_spec", draw)
    monkeypatch.setattr(generator, "run_own", counted)
    dest = tmp_path / "gen"
    seen = []
    cases = generate_cases(dest, 2, 7, kinds=("contraction", "rib"), resolution=0.4, progress=seen.append)
    assert [case.name for case in cases] == ["rib-1", "contraction-2"] and runs == ["contraction-0", "rib-1",
                                                                                    "contraction-2"]
    assert [getattr(item, "reason", None) is not None for item in seen] == [True, False, False]
    manifest = read_generated(dest)
    assert [entry["name"] for entry in manifest["rejected"]] == ["contraction-0"]
    assert "not converged within endTime (5 iterations)" in manifest["rejected"][0]["reason"]
    for entry, case in zip(manifest["cases"], cases, strict=True):
        assert entry["converged"] and entry["iterations"] == case.iterations > 5 and entry["cpu_s"] >= 0
        assert entry["cells"] == cell_count(dest / entry["name"]) and entry["spec"] == case.spec.to_json()
    assert family_case_dirs([dest]) == [dest / "contraction-2", dest / "rib-1"]  # nor the manifest nor -0
    (dest / ".generating" / "rib-3.partial" / "system").mkdir(parents=True)  # an interrupted call's leftover
    (dest / ".generating" / "rib-3.partial" / "system" / "controlDict").write_text("")
    runs.clear()
    more = [case.name for case in generate_cases(dest, 3, 7, kinds=("contraction", "rib"), resolution=0.4)]
    assert more[:2] == ["rib-1", "contraction-2"] and runs[-1] == more[2]  # the made ones are not run again
    assert runs[0] == "rib-3" and not {"contraction-0", "rib-1", "contraction-2"} & set(runs)
    assert not (dest / ".generating").exists()
    assert len(read_generated(dest)["cases"]) == 3 and len(family_case_dirs([dest])) == 3
    with pytest.raises(ValueError, match="seed 7 \\(now 8\\)"):
        generate_cases(dest, 3, 8, kinds=("contraction", "rib"), resolution=0.4)


def test_keep_unconverged_keeps_a_case_that_runs_its_endtime_and_says_so(tmp_path, monkeypatch):
    """Issue 56: the cases whose criterion is never met are the ones the stop on the answer is for."""
    drawn = generator.draw_spec

    def draw(seed, index, kinds, *rest):  # 5 iterations: its own run cannot converge
        return dataclasses.replace(drawn(seed, index, kinds, *rest), **{**EASY, "end_time": 5})

    monkeypatch.setattr(generator, "draw_spec", draw)
    dest = tmp_path / "gen"
    (case,) = generate_cases(dest, 1, 7, kinds=("contraction",), resolution=0.4, keep_unconverged=True)
    manifest = read_generated(dest)
    assert case.name == "contraction-0" and case.converged is False and case.iterations == 5
    assert manifest["keep_unconverged"] and not manifest["rejected"]
    assert manifest["cases"][0]["converged"] is False and (dest / "contraction-0" / "system").is_dir()
    with pytest.raises(ValueError, match="keep_unconverged True \\(now False\\)"):
        generate_cases(dest, 1, 7, kinds=("contraction",), resolution=0.4)


def _exit_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as stop:
        return int(stop.code or 0)


def test_the_cli_refuses_bad_input_in_one_line(tmp_path, capsys, monkeypatch):
    dest = str(tmp_path / "gen")
    for flags in (["-n", "0"], ["-n", "2", "--kinds", "cylinder"], ["-n", "2", "--resolution", "0"],
                  ["-n", "2", "--workers", "0"], ["-n", "2", "--seed", "-1"]):
        assert _exit_code(["generate-cases", dest, *flags]) == 2, flags
        assert capsys.readouterr().err.count("\n") == 1, flags
    monkeypatch.setenv("PATH", str(tmp_path))  # no OpenFOAM on it
    assert _exit_code(["generate-cases", dest, "-n", "1"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "simpleFoam" in error
    assert not Path(dest).exists()


def test_the_cli_generates_cases_on_two_workers(tmp_path, capsys):
    dest = tmp_path / "gen"
    code = main(["generate-cases", str(dest), "-n", "2", "--seed", "0", "--kinds", "step", "diffuser",
                 "--resolution", "0.4", "--workers", "2"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    line = r"^\[1/2\] \w+-\d+: SIMPLEC?, \w+, Re [\d.e+]+, [\d,]+ cells, own \d+ its [\d.]+ s$"
    assert re.search(line, printed, re.MULTILINE), printed
    assert "[2/2]" in printed, printed
    assert re.search(r"^accepted 2, rejected \d+.*CPU s", printed, re.MULTILINE), printed
    manifest = read_generated(dest)
    assert len(manifest["cases"]) == 2 and manifest["seed"] == 0 and manifest["resolution"] == 0.4
    assert family_case_dirs([dest]) == sorted(dest / entry["name"] for entry in manifest["cases"])
