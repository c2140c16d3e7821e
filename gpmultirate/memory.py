"""Refusing a fit that would not fit in memory, before it starts.

A fit holds a few matrices of the sizes its observation sets: the data
covariance and its derivatives (``M x M``, with ``M`` the slow samples after
the long-record reduction, at most the number of coefficients), the prior
covariance of the coefficients (``P x P`` per input, all inputs together for
the posterior), and the products of the regressor with them (``M x P``).
:func:`check_fit_memory` estimates the peak from these sizes and raises
:class:`MemoryLimitError` when it exceeds the memory available, so that an
impossible fit fails at once with the remedy, instead of being killed by the
operating system halfway.

The memory available is read from the operating system (``MemAvailable`` of
``/proc/meminfo``, else the physical memory); the environment variable
``GPMULTIRATE_MEMORY_LIMIT`` (in bytes) sets it explicitly.
"""

from __future__ import annotations

import os

from gpmultirate.exceptions import MemoryLimitError

__all__ = [
    "MemoryLimitError",
    "available_memory",
    "check_fit_memory",
    "fit_memory_estimate",
    "largest_fitting_order",
]

#: environment variable that sets the memory a fit may use, in bytes
LIMIT_VARIABLE = "GPMULTIRATE_MEMORY_LIMIT"
_BYTES = 8  # float64


def available_memory() -> int:
    """The memory a fit may use, in bytes.

    ``GPMULTIRATE_MEMORY_LIMIT`` when set, else the operating system's
    available memory (Linux ``MemAvailable``), else the physical memory.

    Examples
    --------
    >>> available_memory() > 0
    True
    """
    limit = os.environ.get(LIMIT_VARIABLE)
    if limit:
        try:
            value = int(float(limit))
        except ValueError:
            raise ValueError(
                f"{LIMIT_VARIABLE} must be a number of bytes; got {limit!r}"
            ) from None
        if value <= 0:
            raise ValueError(f"{LIMIT_VARIABLE} must be positive; got {limit!r}")
        return value
    try:
        with open("/proc/meminfo", encoding="ascii") as file:
            for line in file:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 2**63 - 1  # unknown: do not refuse


#: slow samples up to which the checks after a fit work with the full data covariance
#: (:data:`gpmultirate.misspecification.CHECKED_SAMPLES`)
CHECKED_SAMPLES = 2000


def fit_memory_estimate(n_outputs: int, n_coefficients: int, n_hyperparameters: int) -> int:
    """Estimated peak memory of a fit in bytes.

    ``M`` slow samples are reduced to at most ``n_coefficients`` (the
    long-record reduction), so the data-space matrices have side
    ``min(M, n_coefficients)``: the covariance, its Cholesky factor and
    inverse, and one derivative per hyperparameter; the posterior holds the
    ``P x P`` prior covariance and two ``M x P`` products; the reduction, the
    factor of ``[Phi y]`` built block by block; the checks after the fit, the
    full ``M x M`` covariance and its factor of a reduced record up to
    ``CHECKED_SAMPLES`` slow samples.  For a long record it covers
    the general posterior (eigendecomposition and QR); a prior with a
    tridiagonal precision (DC) needs less.

    Examples
    --------
    >>> fit_memory_estimate(200, 600, 4) / 1e6  # the paper's size, in MB
    11.2
    """
    m = min(int(n_outputs), int(n_coefficients))
    p = int(n_coefficients)
    data_space = (4 + int(n_hyperparameters)) * m * m
    posterior = 2 * p * p + 3 * m * p
    reduction = 3 * p * p if n_outputs > n_coefficients else 0
    # the checks after a tuned fit (misspecification, the disturbance check) factor
    # the full M x M data covariance up to CHECKED_SAMPLES slow samples: beyond the
    # data-space matrices where the record is reduced (M > P)
    checks = (2 * int(n_outputs) ** 2
              if int(n_coefficients) < int(n_outputs) <= CHECKED_SAMPLES else 0)
    return _BYTES * (data_space + posterior + reduction + checks)


def check_fit_memory(n_outputs: int, n_coefficients: int, n_hyperparameters: int,
                     n_inputs: int = 1) -> None:
    """Raise :class:`MemoryLimitError` when a fit of this size would not fit in memory.

    The message names the largest ``order`` (coefficients per input, of
    ``n_inputs``) whose fit would fit.

    Examples
    --------
    >>> check_fit_memory(200, 600, 4)  # the paper's size: fine
    >>> check_fit_memory(10, 10**6, 2)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    gpmultirate.exceptions.MemoryLimitError: the fit needs about 1.6e+04 GB ...
    """
    needed = fit_memory_estimate(n_outputs, n_coefficients, n_hyperparameters)
    available = available_memory()
    if needed <= available:
        return
    n_inputs = max(1, int(n_inputs))
    fits = largest_fitting_order(n_outputs, n_hyperparameters, available, n_inputs)
    hint = (f"use a smaller order, at most order={fits} here (or order=None, which chooses it "
            "from the data; the impulse response rarely needs more lags than it takes to "
            "decay)" if fits >= 1 else "use a smaller order (or order=None, which chooses it "
            "from the data)")
    raise MemoryLimitError(
        f"the fit needs about {needed / 1e9:.3g} GB (coefficients: {n_coefficients}, slow "
        f"samples: {n_outputs}) but {available / 1e9:.4g} GB are available: {hint}, a "
        "kernel with a fast path (TC, DC, SS, PK and sums of them) and more slow samples "
        "than coefficients, which reduce the data to the P x P long-record factor"
    )


def largest_fitting_order(n_outputs: int, n_hyperparameters: int, available: int,
                          n_inputs: int = 1) -> int:
    """The largest order (per input) whose fit :func:`fit_memory_estimate` puts within ``available``.

    0 when not even order 1 fits.

    Examples
    --------
    >>> order = largest_fitting_order(20000, 3, 2 * 10**9)
    >>> fit_memory_estimate(20000, order, 3) <= 2e9 < fit_memory_estimate(20000, order + 1, 3)
    True
    """
    low, high = 0, 1
    while fit_memory_estimate(n_outputs, high * n_inputs, n_hyperparameters) <= available:
        low, high = high, 2 * high
        if high > 2**40:
            return low
    while high - low > 1:
        middle = (low + high) // 2
        if fit_memory_estimate(n_outputs, middle * n_inputs, n_hyperparameters) <= available:
            low = middle
        else:
            high = middle
    return low
