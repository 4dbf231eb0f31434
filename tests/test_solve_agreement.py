"""jaxsimrl.apps.foam.solve.agreement on small hand-written cases: fields (ascii, binary, uniform, missing)
and function-object tables as OpenFOAM v1912 writes them. No OpenFOAM needed; the real runs are in
tests/test_solve.py."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from foamlib import FoamFieldFile

from jaxsimrl.apps.foam.solve.agreement import (
    compare_results,
    final_rows,
    measure_spread,
    relative_difference,
    spread_line,
    summary_line,
    time_series,
    tolerances,
)

CRITERION = {"U": 1e-3, "p": 1e-2, "k": 1e-3}
TOL, OBJECT_TOL = tolerances(CRITERION)
CELLS = 40
HEADER = "FoamFile\n{{\n    version 2.0;\n    format ascii;\n    class {cls};\n    object {name};\n}}\n"


def _write_field(directory: Path, name: str, values: np.ndarray | float, binary: bool = False) -> None:
    """A volScalarField (a volVectorField for U) file; a single value (a 3-vector for U) is written as a
    uniform field."""
    vector = name == "U"
    values = np.asarray(values, dtype=float)
    entry = _vector if vector else _scalar
    if values.ndim == (1 if vector else 0):
        internal = f"uniform {entry(values)}"
    else:
        kind = "vector" if vector else "scalar"
        internal = f"nonuniform List<{kind}> {len(values)}\n(\n" + "\n".join(map(entry, values)) + "\n)"
    directory.mkdir(parents=True, exist_ok=True)
    cls = "volVectorField" if vector else "volScalarField"
    (directory / name).write_text(HEADER.format(cls=cls, name=name) + "dimensions [0 1 -1 0 0 0 0];\n"
                                  f"internalField {internal};\nboundaryField\n{{\n}}\n")
    if binary:  # foamlib rewrites it as OpenFOAM's binary format
        file = FoamFieldFile(directory / name)
        file.format = "binary"
        file.internal_field = values


def _scalar(value: float) -> str:
    return repr(float(value))


def _vector(row: np.ndarray) -> str:
    return f"({' '.join(map(_scalar, row))})"


def _fields(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"U": rng.normal(10.0, 1.0, (CELLS, 3)), "p": rng.normal(0.0, 5.0, CELLS),
            "k": rng.uniform(0.1, 0.5, CELLS)}


def _case(root: Path, time: str, fields: dict[str, np.ndarray | float], binary: bool = False) -> Path:
    """A case holding 0/ and one later time directory with ``fields``."""
    (root / "0").mkdir(parents=True)
    for name, values in fields.items():
        _write_field(root / time, name, values, binary)
    return root


def _agreement(ours: Path, theirs: Path, fields: tuple[str, ...] = ("U", "p", "k")) -> dict:
    return compare_results(ours, theirs, list(fields), CRITERION, (True, True))


def test_the_same_fields_agree_and_a_changed_field_is_flagged(tmp_path: Path) -> None:
    fields = _fields()
    ours = _case(tmp_path / "ours", "200", fields)
    same = _case(tmp_path / "same", "282", fields)
    agreement = _agreement(ours, same)
    assert agreement["agree"] and all(entry["value"] == 0.0 for entry in agreement["fields"].values())
    assert summary_line("own", agreement).startswith("results agree with own: fields max rel. L2 0.0e+00")

    changed = dict(fields, k=fields["k"] * (1 + 3 * TOL))  # k off by 3 tolerances, U and p the same
    agreement = _agreement(ours, _case(tmp_path / "changed", "282", changed))
    assert not agreement["agree"]
    assert agreement["fields"]["k"]["ok"] is False and math.isclose(agreement["fields"]["k"]["value"],
                                                                    3 * TOL / (1 + 3 * TOL))
    assert agreement["fields"]["U"]["ok"] and agreement["fields"]["p"]["ok"]
    line = summary_line("own", agreement)
    assert line.startswith("results DIFFER from own: k ") and "U " not in line.split(";")[0]


def test_binary_and_ascii_fields_compare_as_the_same_numbers(tmp_path: Path) -> None:
    fields = _fields()
    ours = _case(tmp_path / "ascii", "200", fields)
    theirs = _case(tmp_path / "binary", "282", fields, binary=True)
    assert FoamFieldFile(theirs / "282" / "U").format == "binary"
    agreement = _agreement(ours, theirs)
    assert agreement["agree"] and {entry["value"] for entry in agreement["fields"].values()} == {0.0}


def test_the_same_run_says_so(tmp_path: Path) -> None:
    case = _case(tmp_path / "own", "313", _fields())
    agreement = compare_results(case, case, ["U", "p", "k"], CRITERION, (True, True), same_run=True)
    assert agreement["same_run"] and agreement["agree"]
    assert summary_line("own", agreement).startswith("results agree with own (the same run: the controller's "
                                                     "result is this run's): fields max rel. L2 0.0e+00 (U)")


def test_a_uniform_field_is_compared_cell_by_cell(tmp_path: Path) -> None:
    fields = _fields()
    ours = _case(tmp_path / "ours", "200", dict(fields, k=np.full(CELLS, 0.25), U=np.tile([1.0, 2.0, 0.0],
                                                                                         (CELLS, 1))))
    theirs = _case(tmp_path / "theirs", "282", dict(fields, k=0.25, U=np.array([1.0, 2.0, 0.0])))
    agreement = _agreement(ours, theirs)
    assert agreement["fields"]["k"]["value"] == 0.0 and agreement["fields"]["U"]["value"] == 0.0


def test_a_missing_field_is_not_compared_and_not_agreement(tmp_path: Path) -> None:
    fields = _fields()
    ours = _case(tmp_path / "ours", "200", fields)
    theirs = _case(tmp_path / "theirs", "282", {name: fields[name] for name in ("U", "p")})
    agreement = _agreement(ours, theirs)
    assert agreement["fields"]["k"] == {"value": None, "tolerance": TOL, "ok": None,
                                        "note": "missing or unreadable in the own run"}
    assert agreement["fields"]["U"]["ok"] and not agreement["agree"]
    assert any(note.startswith("field k: missing") for note in agreement["notes"])
    assert "k not compared" in summary_line("own", agreement)


def test_runs_that_did_not_both_converge_get_no_figure(tmp_path: Path) -> None:
    agreement = compare_results(tmp_path, tmp_path, ["U"], CRITERION, (True, False), "constant")
    assert agreement == {"agree": None, "same_run": False, "reason": "the constant run did not converge"}
    assert summary_line("constant", agreement) == ("no agreement figure with constant: the constant run did "
                                                   "not converge")


FORCE = """# Force
# CofR        : (0.000000e+00 0.000000e+00 0.000000e+00)
#
# Time        \t(total_x total_y total_z)\t(pressure_x pressure_y pressure_z)
1             \t(-1.0e-02 -8.0e-02 2.0e-21)\t(-1.1e-02 -8.0e-02 -7.0e-22)
{time}        \t(-4.0e-05 -5.0e-03 {z})\t(-8.0e-05 -5.0e-03 -1.0e-22)
"""
MINMAX = """# Field minima and maxima
# Time        \tfield         \tmin           \tlocation(min) \tmax           \tlocation(max)
{time}        \tmag(U)        \t0.0\t(-1.9e-02 2.5e-02 0.0)\t{umax}\t(-1.1e-02 1.4e-02 0.0)
{time}        \tp             \t-5.5\t(6.3e-03 -2.6e-03 0.0)\t20.4\t({x} -2.4e-02 0.0)
"""
PROBES = """# Probe 0 (0.01 0 0)
# Probe 1 (0.1 0.01 0)
#       Probe             0             1
#        Time
            1             (2.1 -3.5 0)             (4.7 -0.39 0)
           {time}             (6.5 -2.2 0)             (6.5 -0.26 0)
"""
COEFFICIENTS = "# Force coefficients\n# Time\tCd\tCs\tCl\n{time}\t{cd}\t{cs}\t-1.0e-04\n"
RESIDUALS = "# Solver information\n# Time  \tp_solver\tp_initial\n{time}\tGAMG\t{residual}\n"


def _post(case: Path, time: str, start: str = "0", z: str = "-8.3e-23", umax: str = "11.25",
          x: str = "2.0e-01", cd: str = "8.2e-07", cs: str = "1.6e-24") -> Path:
    """A case's postProcessing/ with forces, force coefficients, fieldMinMax, probes, solverInfo and a
    VTK file."""
    post = case / "postProcessing"
    files = {f"forces/{start}/force.dat": FORCE.format(time=time, z=z),
             f"fieldMinMax/{start}/fieldMinMax.dat": MINMAX.format(time=time, umax=umax, x=x),
             f"probes/{start}/U": PROBES.format(time=time),
             f"coefficients/{start}/coefficient.dat": COEFFICIENTS.format(time=time, cd=cd, cs=cs),
             f"residuals/{start}/solverInfo.dat": RESIDUALS.format(time=time, residual=float(time) * 1e-6),
             f"sets/streamlines/{time}/track0_U.vtk": "# vtk DataFile Version 2.0\nsets\nASCII\n"}
    for name, text in files.items():
        (post / name).parent.mkdir(parents=True, exist_ok=True)
        (post / name).write_text(text)
    return case


def test_function_object_final_rows_are_read_as_openfoam_writes_them(tmp_path: Path) -> None:
    case = _post(tmp_path / "case", "200")
    assert set(time_series(case)) == {"forces/force.dat", "fieldMinMax/fieldMinMax.dat", "probes/U",
                                      "coefficients/coefficient.dat",
                                      "sets/streamlines/track0_U.vtk"}  # solverInfo: not a result
    assert final_rows(case / "postProcessing/forces/0/force.dat") == {"": {
        "total": (-4e-05, -5e-03, -8.3e-23), "pressure": (-8e-05, -5e-03, -1e-22)}}
    minmax = final_rows(case / "postProcessing/fieldMinMax/0/fieldMinMax.dat")  # no locations: discrete
    assert minmax == {"mag(U)": {"min": (0.0,), "max": (11.25,)}, "p": {"min": (-5.5,), "max": (20.4,)}}
    assert final_rows(case / "postProcessing/probes/0/U") == {"": {"0": (6.5, -2.2, 0.0),
                                                                  "1": (6.5, -0.26, 0.0)}}
    assert final_rows(case / "postProcessing/coefficients/0/coefficient.dat") == {"": {
        "Cd": (8.2e-07,), "Cs": (1.6e-24,), "Cl": (-1e-04,)}}
    assert final_rows(case / "postProcessing/sets/streamlines/200/track0_U.vtk") is None


def test_function_objects_agree_flag_and_skip(tmp_path: Path) -> None:
    fields = _fields()
    ours = _post(_case(tmp_path / "ours", "200", fields), "200", z="3.0e-21", x="1.9e-01", cd="8.45e-07",
                 cs="3.0e-24")
    theirs = _post(_case(tmp_path / "theirs", "282", fields), "282")
    agreement = _agreement(ours, theirs)
    objects = agreement["function_objects"]
    assert objects["forces/force.dat total"]["value"] < 1e-15  # a vector: its z round-off is nothing
    # a side-force coefficient of 1e-24 is round-off: measured against 1e-3 of the row's largest value
    assert objects["coefficients/coefficient.dat Cs"]["value"] < 1e-15
    assert objects["coefficients/coefficient.dat Cd"]["value"] == pytest.approx(0.25 / 8.2)  # against itself
    assert objects["fieldMinMax/fieldMinMax.dat [p] max"]["value"] == 0.0  # its location moved: not compared
    assert len(objects) == 2 + 3 + 4 + 2 and agreement["agree"] and not agreement["notes"]
    assert summary_line("own", agreement) == (
        f"results agree with own: fields max rel. L2 0.0e+00 (U) <= tol {TOL:.0e}; function objects max "
        f"3.0e-02 (coefficients/coefficient.dat Cd) <= tol {OBJECT_TOL:.0e}")

    umax = 11.25 / (1 - 2 * OBJECT_TOL)  # ours is 2 tolerances below it
    theirs_off = _post(_case(tmp_path / "off", "282", fields), "282", umax=repr(umax), start="100")
    (theirs_off / "postProcessing/forces/100/force.dat").write_text(FORCE.format(time=282, z=0.0).replace(
        "(pressure_x pressure_y pressure_z)", "(viscous_x viscous_y viscous_z)"))
    _post(theirs_off, "100", start="0")  # an earlier start time: the restart's (start 100) files win
    agreement = _agreement(ours, theirs_off)
    assert not agreement["agree"] and agreement["notes"] == [
        "forces/force.dat: different rows or columns in the two runs, not compared"]
    entry = agreement["function_objects"]["fieldMinMax/fieldMinMax.dat [mag(U)] max"]
    assert entry["ok"] is False and math.isclose(entry["value"], 2 * OBJECT_TOL)
    assert f"fieldMinMax/fieldMinMax.dat [mag(U)] max {2 * OBJECT_TOL:.1e}" in summary_line("own", agreement)


@pytest.mark.parametrize(("value", "reference", "scale", "expected"), [
    (1.1, 1.0, 0.0, 0.1), (0.0, 0.0, 0.0, 0.0), (1e-20, 0.0, 1e-3, 1e-17), (1.0, 0.0, 0.0, math.inf),
    (math.nan, math.nan, 0.0, 0.0), (math.nan, 1.0, 0.0, math.inf)])
def test_relative_difference(value: float, reference: float, scale: float, expected: float) -> None:
    assert relative_difference(value, reference, scale) == pytest.approx(expected)


def test_no_figure_without_a_residual_criterion(tmp_path):
    """A case whose own function objects ended both runs has no residualControl threshold: no tolerance
    can be derived, and the comparison says why instead of failing the solve."""
    agreement = compare_results(tmp_path, tmp_path, ["U"], {}, (True, True))
    assert agreement["agree"] is None and "no residual criterion" in agreement["reason"]
    assert summary_line("own", agreement).startswith("no agreement figure with own")


def test_a_difference_within_the_measured_spread_agrees(tmp_path: Path) -> None:
    fields = _fields()
    own = _case(tmp_path / "own", "282", fields)
    nudged = _case(tmp_path / "nudged", "250", dict(fields, k=fields["k"] * (1 + 4 * TOL)))
    ours = _case(tmp_path / "ours", "200", dict(fields, k=fields["k"] * (1 + 2 * TOL)))
    spread = measure_spread(own, nudged, ["U", "p", "k"], CRITERION, (True, True), "alpha_u 0.95")
    assert spread["measured"] and not spread["settled"]  # k: 4 tolerances apart, U and p equal
    assert spread["fields"]["U"] == 0.0 and spread["fields"]["k"] > 3 * TOL
    assert not _agreement(ours, own)["agree"]  # the tolerance alone flags k ...
    agreement = compare_results(ours, own, ["U", "p", "k"], CRITERION, (True, True), spread=spread)
    k = agreement["fields"]["k"]  # ... within what two legitimate runs differ by, it agrees
    assert agreement["agree"] and k["ok"] and k["allowed"] == k["spread"] == spread["fields"]["k"] > TOL
    assert agreement["fields"]["U"]["allowed"] == TOL  # no spread in U: the tolerance holds
    far = _case(tmp_path / "far", "200", dict(fields, k=fields["k"] * (1 + 8 * TOL)))
    assert not compare_results(far, own, ["U", "p", "k"], CRITERION, (True, True), spread=spread)["agree"]


def test_the_spread_line_says_whether_the_criterion_fixes_the_answer(tmp_path: Path) -> None:
    fields = _fields()
    own = _case(tmp_path / "own", "282", fields)
    close = _case(tmp_path / "close", "250", dict(fields, k=fields["k"] * (1 + TOL / 2)))
    settled = measure_spread(own, close, ["U", "p", "k"], CRITERION, (True, True), "alpha_u 0.95")
    assert settled["settled"]
    assert spread_line(settled, CRITERION).startswith("the criterion fixes the answer: the own run and")
    far = _case(tmp_path / "far", "250", dict(fields, p=fields["p"] * 1.12))  # 12 % apart in p
    loose = measure_spread(own, far, ["U", "p", "k"], CRITERION, (True, True), "alpha_u 0.95")
    line = spread_line(loose, CRITERION)
    assert not loose["settled"] and "leaves the answer uncertain" in line and "end p 12 % apart" in line
    assert "about 1e-04 (--residual)" in line  # 1e-2 x 1 % / 12 %, down to a decade
    unconverged = measure_spread(own, far, ["U"], CRITERION, (True, False), "alpha_u 0.95")
    assert not unconverged["measured"] and "did not converge" in spread_line(unconverged, CRITERION)
