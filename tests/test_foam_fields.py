"""foam_bridge._fields: the final field of a case and the relative L2 distance between two fields."""

from __future__ import annotations

import numpy as np
import pytest
from foamlib import FoamFieldFile

from foam_bridge._fields import final_field, relative_l2, time_directories


def _write_u(case, time, value):
    directory = case / time
    directory.mkdir(parents=True)
    field = FoamFieldFile(directory / "U")
    field.dimensions = [0, 1, -1, 0, 0, 0, 0]
    field.internal_field = value
    field.boundary_field = {}


def test_final_field_is_the_latest_written_time_after_the_first(tmp_path):
    case = tmp_path / "case"
    _write_u(case, "0", np.zeros((4, 3)))
    (case / "constant").mkdir()
    assert final_field(case) is None  # only the initial time: the run wrote nothing
    _write_u(case, "100", np.ones((4, 3)))
    _write_u(case, "630", np.arange(12.0).reshape(4, 3))
    assert [t for t, _ in time_directories(case)] == [0.0, 100.0, 630.0]
    time, values = final_field(case)
    assert time == 630.0 and values.shape == (4, 3)
    np.testing.assert_array_equal(values, np.arange(12.0).reshape(4, 3))


def test_a_uniform_or_missing_final_field_is_none(tmp_path):
    case = tmp_path / "case"
    _write_u(case, "0", np.zeros((4, 3)))
    _write_u(case, "50", [1.0, 0.0, 0.0])  # uniform: not a solution to compare cell by cell
    assert final_field(case) is None
    (case / "90").mkdir()  # a later time without U
    assert final_field(case) is None


def test_relative_l2():
    reference = np.array([[3.0, 0.0, 0.0], [0.0, 4.0, 0.0]])
    assert relative_l2(reference, reference) == 0.0
    assert relative_l2(reference * 1.1, reference) == pytest.approx(0.1)
    assert relative_l2(np.zeros((3, 3)), reference) is None  # another mesh
    assert relative_l2(None, reference) is None and relative_l2(reference, np.zeros((2, 3))) is None
