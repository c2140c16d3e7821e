"""Tests of gpmultirate.datasets against the raw text files."""

from __future__ import annotations

import dataclasses
import fnmatch
import hashlib
import pathlib
import sys

import numpy as np
import pytest

from gpmultirate import datasets

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGED = ROOT / "gpmultirate" / "data" / "robot_arm.dat"
SHARED = pathlib.Path("/work/shared/data/daisy/robot_arm.dat")
CD_PACKAGED = ROOT / "gpmultirate" / "data" / "CD_player_arm.dat"
CD_SHARED = pathlib.Path("/work/shared/data/daisy/CD_player_arm.dat")


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
    for path in (PACKAGED, CD_PACKAGED):
        relative = path.relative_to(ROOT / "gpmultirate").as_posix()
        assert any(fnmatch.fnmatch(relative, pattern) for pattern in patterns)


# ------------------------------------------------------------- CD-player arm
def test_cd_player_arm_shape_and_finite():
    data = datasets.load_cd_player_arm()
    assert data.u.shape == (2048, 2)
    assert data.y.shape == (2048, 2)
    assert data.u.dtype == np.float64 and data.y.dtype == np.float64
    assert np.all(np.isfinite(data.u)) and np.all(np.isfinite(data.y))
    # columns are channels: each output follows mainly the input of its index
    # (with opposite sign), which a transposed or shuffled table would not
    corr = np.corrcoef(np.column_stack([data.u, data.y]).T)
    assert corr[0, 2] < -0.9 and corr[1, 3] < -0.9
    assert abs(corr[0, 3]) < 0.3 and abs(corr[1, 2]) < 0.3


def test_cd_player_arm_columns_match_packaged_file():
    table = np.loadtxt(CD_PACKAGED)
    data = datasets.load_cd_player_arm()
    np.testing.assert_array_equal(data.u, table[:, :2])
    np.testing.assert_array_equal(data.y, table[:, 2:])


@pytest.mark.skipif(not CD_SHARED.exists(), reason="shared DaISy copy not available")
def test_cd_player_arm_values_equal_shared_source_file():
    table = np.loadtxt(CD_SHARED)
    assert table.shape == (2048, 4)
    data = datasets.load_cd_player_arm()
    np.testing.assert_array_equal(data.u, table[:, :2])
    np.testing.assert_array_equal(data.y, table[:, 2:])


@pytest.mark.skipif(not CD_SHARED.exists(), reason="shared DaISy copy not available")
def test_cd_player_arm_packaged_file_is_an_unmodified_copy():
    assert CD_PACKAGED.read_bytes() == CD_SHARED.read_bytes()


# SHA-256 of the DaISy files as distributed (robot_arm.dat, CD_player_arm.dat),
# so the packaged copies are checked where the source files are not at hand
SOURCE_SHA256 = {
    PACKAGED: "7577818296239b7a47d1db59abac7ae03fe106f246e0a001152fcc0a733d83c7",
    CD_PACKAGED: "a2ef4bf51c3102487a0690c7a68d97f3b1966cd07319580011a97fc0af904eaa",
}


@pytest.mark.parametrize("path", list(SOURCE_SHA256), ids=lambda path: path.name)
def test_packaged_files_hash_as_the_daisy_sources(path):
    assert hashlib.sha256(path.read_bytes()).hexdigest() == SOURCE_SHA256[path]


def test_cd_player_arm_arrays_are_read_only_and_new():
    first, second = datasets.load_cd_player_arm(), datasets.load_cd_player_arm()
    for x in (first.u, first.y):
        assert not x.flags.writeable
        with pytest.raises(ValueError):
            x[0, 0] = 1.0
        with pytest.raises(ValueError):
            x[:, 1] = 1.0
    assert not np.shares_memory(first.u, second.u)
    assert not np.shares_memory(first.y, second.y)
    assert not np.shares_memory(first.u, first.y)
    # contiguous copies, not views of one table
    assert first.u.flags.c_contiguous and first.y.flags.c_contiguous
    u = first.u.copy()
    u[:] = 0.0
    np.testing.assert_array_equal(datasets.load_cd_player_arm().u, second.u)


def test_cd_player_arm_metadata():
    data = datasets.load_cd_player_arm()
    with pytest.raises(dataclasses.FrozenInstanceError):
        data.y = np.zeros((2048, 2))
    assert data.sample_time is None
    assert "DaISy" in data.citation and "96-007" in data.citation
    assert "De Moor" in data.citation and "KU Leuven" in data.citation
    assert "CD player" in data.description and "actuators" in data.description


def test_cd_player_arm_fits_both_inputs_of_one_output():
    # the layout the estimators take: u as it is, one output column at a time
    import gpmultirate as gm

    data = datasets.load_cd_player_arm()
    u = data.u[:300] - data.u[:300].mean(axis=0)
    y_slow = data.y[:300:3, 1]
    model = gm.LeastSquaresFIR(factor=3, order=10).fit(u, y_slow - y_slow.mean())
    assert model.coef_.shape == (2, 10)
