"""Tests of gpmultirate.datasets against the raw text files."""

from __future__ import annotations

import dataclasses
import fnmatch
import pathlib
import sys

import numpy as np
import pytest

from gpmultirate import datasets

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGED = ROOT / "gpmultirate" / "data" / "robot_arm.dat"
SHARED = pathlib.Path("/work/shared/data/daisy/robot_arm.dat")


def test_shape_and_finite():
    data = datasets.load_robot_arm()
    assert data.u.shape == (1024,)
    assert data.y.shape == (1024,)
    assert data.u.dtype == np.float64 and data.y.dtype == np.float64
    assert np.all(np.isfinite(data.u)) and np.all(np.isfinite(data.y))


def test_columns_match_packaged_file():
    table = np.loadtxt(PACKAGED)
    data = datasets.load_robot_arm()
    np.testing.assert_array_equal(data.u, table[:, 0])
    np.testing.assert_array_equal(data.y, table[:, 1])


@pytest.mark.skipif(not SHARED.exists(), reason="shared DaISy copy not available")
def test_values_equal_shared_source_file():
    table = np.loadtxt(SHARED)
    assert table.shape == (1024, 2)
    data = datasets.load_robot_arm()
    np.testing.assert_array_equal(data.u, table[:, 0])
    np.testing.assert_array_equal(data.y, table[:, 1])


@pytest.mark.skipif(not SHARED.exists(), reason="shared DaISy copy not available")
def test_packaged_file_is_an_unmodified_copy():
    assert PACKAGED.read_bytes() == SHARED.read_bytes()


def test_arrays_are_read_only():
    data = datasets.load_robot_arm()
    for x in (data.u, data.y):
        assert not x.flags.writeable
        with pytest.raises(ValueError):
            x[0] = 1.0


def test_every_call_returns_new_arrays():
    first, second = datasets.load_robot_arm(), datasets.load_robot_arm()
    assert not np.shares_memory(first.u, second.u)
    assert not np.shares_memory(first.y, second.y)
    assert not np.shares_memory(first.u, first.y)
    # a writable copy made by the user does not touch the next load
    u = first.u.copy()
    u[:] = 0.0
    np.testing.assert_array_equal(datasets.load_robot_arm().u, second.u)


def test_dataclass_is_frozen_with_metadata():
    data = datasets.load_robot_arm()
    with pytest.raises(dataclasses.FrozenInstanceError):
        data.u = np.zeros(1024)
    assert data.sample_time is None
    assert "DaISy" in data.citation and "96-009" in data.citation
    assert "De Moor" in data.citation and "KU Leuven" in data.citation
    assert "torque" in data.description and "acceleration" in data.description


@pytest.mark.skipif(sys.version_info < (3, 11), reason="tomllib needs Python 3.11")
def test_data_file_is_declared_as_package_data():
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["gpmultirate"]
    relative = PACKAGED.relative_to(ROOT / "gpmultirate").as_posix()
    assert any(fnmatch.fnmatch(relative, pattern) for pattern in patterns)
