"""Measured input/output records shipped with the package.

The records are sampled at a single (fast) rate, so the fast-rate output is
known: keep every ``factor``-th output sample to make a slow-rate
measurement, identify from it, and validate against the samples that were
left out.  The files live in ``gpmultirate/data`` and are read with
:mod:`importlib.resources`, so they are found in any installation.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from importlib import resources

import numpy as np

__all__ = ["Dataset", "load_cd_player_arm", "load_robot_arm", "robot_arm_csv"]

_DAISY_CITATION = (
    'De Moor B.L.R. (ed.), "DaISy: Database for the Identification of Systems", '
    "Department of Electrical Engineering, ESAT/STADIUS, KU Leuven, Belgium, "
    "https://homes.esat.kuleuven.be/~smc/daisy/. "
)


@dataclass(frozen=True)
class Dataset:
    """A measured input/output record.

    A single-input single-output record has 1-D ``u`` and ``y``; with several
    inputs or outputs they are 2-D and each column is one channel, in the
    layout :meth:`FIRGaussianProcess.fit <gpmultirate.FIRGaussianProcess.fit>`
    takes for ``u`` (an estimator models one output, ``y[:, j]``, at a time).

    Attributes
    ----------
    u : ndarray of shape (N,) or (N, n_inputs)
        Input, read-only; column ``k`` is input ``k``.
    y : ndarray of shape (N,) or (N, n_outputs)
        Output at the same rate as ``u``, read-only; column ``j`` is output ``j``.
    description : str
        What was measured, in the source's words.
    citation : str
        How to cite the source of the data.
    sample_time : float or None, default=None
        Sample time in seconds; ``None`` when the source does not give it
        (frequencies are then in cycles per sample).

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.datasets import Dataset
    >>> data = Dataset(u=np.zeros(3), y=np.ones(3), description="test", citation="none")
    >>> data.sample_time is None
    True
    """

    u: np.ndarray
    y: np.ndarray
    description: str
    citation: str
    sample_time: float | None = None


def _read_columns(filename: str, n_columns: int) -> np.ndarray:
    """Read a whitespace-separated text file of ``gpmultirate/data``."""
    text = resources.files("gpmultirate").joinpath("data", filename).read_text(encoding="ascii")
    table = np.loadtxt(io.StringIO(text), ndmin=2)
    if table.shape[1] != n_columns or not np.all(np.isfinite(table)):
        raise ValueError(
            f"{filename} must hold {n_columns} finite columns; got shape {table.shape}"
        )
    return table


def _read_only(x: np.ndarray) -> np.ndarray:
    x = np.ascontiguousarray(x, dtype=float).copy()
    x.setflags(write=False)
    return x


def load_robot_arm() -> Dataset:
    """Flexible robot arm (DaISy data set 96-009), 1024 samples.

    The arm is installed on an electrical motor; the input ``u`` is the
    measured reaction torque of the structure on the ground and the output
    ``y`` the acceleration of the flexible arm.  The excitation is a periodic
    sine sweep that covers about the lowest 40 % of the frequency band.  The
    source does not give the sample time, so ``sample_time`` is ``None``.

    The record starts in the middle of the experiment: the arm is not at rest
    at the first sample, and outputs early in the record depend on inputs
    that were not recorded.  When an FIR model of order ``P`` is validated on
    this record, compare only outputs at index ``P - 1`` and later, which see
    recorded inputs only.

    Returns
    -------
    Dataset
        ``u`` and ``y`` of shape ``(1024,)``, read-only; every call returns
        new arrays.

    Examples
    --------
    >>> from gpmultirate.datasets import load_robot_arm
    >>> data = load_robot_arm()
    >>> data.u.shape, data.y.shape, data.sample_time
    ((1024,), (1024,), None)
    >>> data.u.flags.writeable
    False

    Make a slow-rate measurement by keeping every third output sample:

    >>> y_slow = data.y[::3]
    >>> y_slow.shape
    (342,)
    """
    table = _read_columns("robot_arm.dat", 2)
    return Dataset(
        u=_read_only(table[:, 0]),
        y=_read_only(table[:, 1]),
        description=(
            "Flexible robot arm installed on an electrical motor. Input u: reaction torque "
            "of the structure on the ground; output y: acceleration of the flexible arm. "
            "Periodic sine-sweep excitation, 1024 samples, sample time not given by the "
            "source. The record starts mid-experiment (the arm is not at rest)."
        ),
        citation=_DAISY_CITATION + 'Data set 96-009, "Data of a flexible robot arm".',
        sample_time=None,
    )


def load_cd_player_arm() -> Dataset:
    """CD-player arm (DaISy data set 96-007), 2048 samples, 2 inputs and 2 outputs.

    The mechanical arm of a CD player, which positions the read head over
    the track: a lightly damped mechanical system.  The inputs ``u[:, 0]``
    and ``u[:, 1]`` are the forces of the two mechanical actuators, the
    outputs ``y[:, 0]`` and ``y[:, 1]`` the tracking accuracy of the arm.
    The source does not give the sample time, so ``sample_time`` is
    ``None``.

    Each output depends mainly on the input of the same index, but not only
    on it: identify each output from both inputs (``u`` as it is).  The
    signals do not have zero mean; subtract the means of the estimation
    data before fitting an FIR model, which has no offset term.  As for
    :func:`load_robot_arm`, the record starts in the middle of the
    experiment, so the inputs before the first sample are unknown: fit with
    ``initial_conditions="discard"`` or compare only outputs at index
    ``P - 1`` and later.

    Returns
    -------
    Dataset
        ``u`` and ``y`` of shape ``(2048, 2)``, read-only; every call returns
        new arrays.

    Examples
    --------
    >>> from gpmultirate.datasets import load_cd_player_arm
    >>> data = load_cd_player_arm()
    >>> data.u.shape, data.y.shape, data.sample_time
    ((2048, 2), (2048, 2), None)
    >>> data.y.flags.writeable
    False

    A slow-rate measurement of the second output, every third sample, to be
    explained by both inputs:

    >>> y_slow = data.y[::3, 1]
    >>> y_slow.shape
    (683,)
    """
    table = _read_columns("CD_player_arm.dat", 4)
    return Dataset(
        u=_read_only(table[:, :2]),
        y=_read_only(table[:, 2:]),
        description=(
            "Arm of a CD player, a lightly damped mechanical system with 2 inputs and "
            "2 outputs. Inputs u[:, 0], u[:, 1]: forces of the two mechanical actuators; "
            "outputs y[:, 0], y[:, 1]: tracking accuracy of the arm. 2048 samples, sample "
            "time not given by the source. The record starts mid-experiment (the arm is "
            "not at rest)."
        ),
        citation=_DAISY_CITATION + 'Data set 96-007, "CD-player arm".',
        sample_time=None,
    )


def robot_arm_csv() -> str:
    """Path of ``robot_arm_multirate.csv``: the robot arm as a slow-rate measurement.

    The file holds the record of :func:`load_robot_arm` in the layout of
    ``gpmultirate fit``: a header ``u,y_slow``, one row per fast sample, the
    input ``u`` in every row and the output in every third row (rows 0, 3,
    6, ...), empty elsewhere.  ``gpmultirate fit --example robot-arm`` fits
    it; from a shell its path is
    ``python -c "import gpmultirate.datasets as d; print(d.robot_arm_csv())"``.

    Returns
    -------
    str
        The path of the file in the installed package.

    Examples
    --------
    >>> from gpmultirate.datasets import robot_arm_csv
    >>> with open(robot_arm_csv()) as stream:
    ...     [next(stream).strip() for _ in range(3)]
    ['u,y_slow', '2.2183165e-01,-1.7703630e-01', '3.9027807e-02,']
    """
    return str(resources.files("gpmultirate").joinpath("data", "robot_arm_multirate.csv"))
