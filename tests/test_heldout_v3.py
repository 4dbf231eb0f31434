"""heldout-v3's builders (experiments/controller/heldout-v3, issue 47's fresh held-out set): every case is of
a kind heldout-v2 reserves, so no training case can be of its kind; two builds of a case are the same files
and blockMesh meshes it (the O-grid cylinder, the porous zone, the rotating annulus)."""

from __future__ import annotations

import filecmp
import importlib
import json
import sys
from pathlib import Path

import pytest
from foam_marks import HAVE_OPENFOAM

ROOT = Path(__file__).resolve().parent.parent
HERE = ROOT / "experiments" / "controller" / "heldout-v3"


@pytest.fixture(scope="module")
def cases():
    sys.path.insert(0, str(HERE))
    try:
        sys.modules.pop("cases", None)
        yield importlib.import_module("cases")
    finally:
        sys.path.remove(str(HERE))
        sys.modules.pop("cases", None)


def test_every_case_is_of_a_reserved_kind(cases):
    reserved = json.loads((ROOT / "experiments" / "controller" / "heldout-v2" / "reserved_kinds.json")
                          .read_text())["reserved"]
    kinds = {kind for _, kind, _ in cases.DESCRIPTIONS.values()}
    assert kinds == {entry["kind"] for entry in reserved}  # all seven, and nothing else
    assert set(cases.CASES) == set(cases.DESCRIPTIONS)
    for name, builder in cases.CASES.items():  # each docstring opens with its kind
        assert builder.__doc__.startswith(cases.DESCRIPTIONS[name][1] + "."), name


@pytest.mark.openfoam
@pytest.mark.skipif(not HAVE_OPENFOAM, reason="simpleFoam not on PATH")
@pytest.mark.parametrize("name", ["cylinderSlow", "porousDense", "couetteSlow"])
def test_a_case_builds_the_same_twice_and_meshes(cases, name, tmp_path):
    for build in ("a", "b"):
        cases.CASES[name](tmp_path / build / name)
    compare = filecmp.dircmp(tmp_path / "a" / name, tmp_path / "b" / name, ignore=["log.blockMesh"])
    assert not compare.diff_files and not compare.left_only and not compare.right_only
    for sub in ("system", "constant", "0", "constant/polyMesh"):
        assert not filecmp.dircmp(tmp_path / "a" / name / sub, tmp_path / "b" / name / sub).diff_files, sub
    assert (tmp_path / "a" / name / "constant" / "polyMesh" / "owner").is_file()
    assert "End" in (tmp_path / "a" / name / "log.blockMesh").read_text()
