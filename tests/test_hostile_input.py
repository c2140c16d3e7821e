"""Hostile input: every public entry point rejects bad arguments cleanly.

Each test draws a public call with exactly one bad argument: a wrong type
(string, None, dict, object, complex number, bool for an int, a scikit-learn
estimator for a kernel), a wrong shape (2-D, 3-D, empty, scalar), a wrong
length (``y_slow`` not of ``len(range(offset, N, factor))`` samples), NaN or
inf, a bad ``factor``/``order``/``offset`` (0, negative, float, ``order > N``,
``offset >= factor``), bad lags (negative, NaN), a bad credible level (0, 1,
above 1, negative, NaN), a bad ``sample_time``, or a kernel of the wrong kind
or with an out-of-range hyperparameter such as ``DC(alpha=1.5)``.

The call must raise :class:`ValueError` or :class:`TypeError` (subclasses
included: ``IdentifiabilityError``, ``ModelFileError``, scikit-learn's
``NotFittedError``) whose message names the bad argument.  Every strategy of
bad values is tagged with the argument it replaces (the ``names`` of a
:class:`Slot`); the test checks that one of these names occurs in the message
as a whole identifier.  For a kernel hyperparameter out of range the
hyperparameter's name (``alpha``) or ``kernel`` is accepted; for a corrupted
model file the exception must be ``ModelFileError`` and the message must say
which part of the file (``file``, ``header`` or ``kernel``) is bad; for an
unfitted model, ``NotFittedError`` naming ``fit``.  Any other exception, no
exception, or a ``RuntimeWarning`` (an error under the project's pytest
settings; numpy's ``ComplexWarning``, which signals a silently discarded
imaginary part, is one) fails.

Not treated as invalid: an empty list of lags (the answer is empty, as for
scikit-learn's kernels), ``factor > len(u)`` (one slow sample), and a path
that does not exist or is a directory (``load_model`` documents
``FileNotFoundError``; the operating system's errors are the right answer).
Small integers and booleans are never drawn as paths: ``open`` takes them as
file descriptors of this process (see
``test_save_model_rejects_a_file_descriptor_as_path``).

Examples per run (derandomized, no example database: every run draws the
same inputs; each test asserts that it ran at least its budget, and
``test_generated_tests_checked_at_least_1000_examples``, last in the module,
asserts that the examples the tests counted while running add up to at least
1000):

=================================================  ========
test                                               examples
=================================================  ========
test_fit_rejects_bad_arguments                          300
test_gaussian_process_methods_reject_bad_arguments      250
test_least_squares_rejects_bad_arguments                150
test_operator_rejects_bad_arguments                     150
test_observed_kernel_rejects_bad_arguments              120
test_lag_kernels_reject_bad_arguments                   200
test_goodness_of_fit_rejects_bad_arguments               80
test_persistence_rejects_bad_paths_and_objects          150
test_simulation_rejects_bad_arguments                   300
=================================================  ========
total                                                  1700
=================================================  ========

Deterministic tests complete the picture: a file descriptor is not a path
for ``save_model``; ``load_model`` of a missing file raises the documented
``FileNotFoundError``; the forged model files used above carry a valid
checksum (so that they test the loader's checks behind it); and
``test_minimal_reproducer_is_rejected`` holds, one test each, the smallest
input of every distinct defect the generated tests found, so that each
defect reads as its own failure and stays fixed.

Sizes are tiny (at most 12 fast samples for the estimators): drawing and
checking the 1700 examples takes about 10-20 s; shrinking failing examples
takes longer.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import re
import warnings
from dataclasses import dataclass, field
from functools import cache, partial
from typing import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from sklearn.exceptions import NotFittedError
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import Kernel
from sklearn.linear_model import LinearRegression
from threadpoolctl import threadpool_limits

from gpmultirate import (
    DownsampledConvolution,
    FIRGaussianProcess,
    LeastSquaresFIR,
    ModelFileError,
    ObservedKernel,
    fit_percent,
    goodness_of_fit,
    load_model,
    save_model,
)
from gpmultirate import simulation as sim
from gpmultirate.kernels import DC, PK, SS, TC
from gpmultirate.observations.experiment import is_record_list

ACCEPTED = (ValueError, TypeError)
BUDGET = {
    "fit": 300,
    "gp_methods": 250,
    "least_squares": 150,
    "operator": 150,
    "observed_kernel": 120,
    "lag_kernels": 200,
    "goodness_of_fit": 80,
    "persistence": 150,
    "simulation": 300,
}
#: Examples each generated test actually checked in this session, by BUDGET key.
RAN: dict[str, int] = {}
MIN_TOTAL_EXAMPLES = 1000
NAN, INF = float("nan"), float("inf")
VALID = object()  # "keep the valid argument"


@pytest.fixture(scope="module", autouse=True)
def single_threaded_blas():
    # The matrices here are tiny; threaded BLAS only adds contention (20x
    # slower tuning on two cores), so keep one thread while this module runs.
    with threadpool_limits(limits=1):
        yield


# ------------------------------------------------------------- checking
@dataclass(frozen=True)
class Case:
    """One call with one bad argument, and what its error must say."""

    label: str
    call: Callable[[], object]
    names: tuple[str, ...]
    expected: tuple[type, ...] = ACCEPTED

    def __repr__(self) -> str:
        return self.label


@dataclass(frozen=True)
class Slot:
    """An argument of an entry point, the strategy of bad values for it, its name(s)."""

    template: str
    call: Callable[[object], object]
    values: st.SearchStrategy
    names: tuple[str, ...]
    expected: tuple[type, ...] = field(default=ACCEPTED)


def show(value) -> str:
    """A one-line repr; kernels show all their parameters, bounds included."""
    if isinstance(value, Kernel):
        params = value.get_params(deep=False)
        return f"{type(value).__name__}({', '.join(f'{k}={show(v)}' for k, v in params.items())})"
    return " ".join(repr(value).split())


def slot_cases(*slots: Slot) -> st.SearchStrategy:
    def cases_for(slot):
        return slot.values.map(
            lambda value: Case(
                slot.template.format(show(value)),
                partial(slot.call, value),
                slot.names,
                slot.expected,
            )
        )

    return st.sampled_from(slots).flatmap(cases_for)


def names_argument(message: str, name: str) -> bool:
    """True when ``name`` occurs in ``message`` as a whole identifier."""
    return re.search(rf"(?<![\w.]){re.escape(name)}(?!\w)", message) is not None


def assert_rejected(case: Case) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. ConvergenceWarning of a tuned fit
        warnings.simplefilter("error", RuntimeWarning)
        try:
            case.call()
        except case.expected as exc:
            message = str(exc)
            assert any(names_argument(message, name) for name in case.names), (
                f"{case.label}: the {type(exc).__name__} message does not name "
                f"{' or '.join(case.names)}: {message!r}"
            )
            return
        except Exception as exc:  # noqa: BLE001 - any other exception is the failure
            raise AssertionError(
                f"{case.label}: raised {type(exc).__name__} ({exc}) instead of "
                f"{' or '.join(t.__name__ for t in case.expected)} naming "
                f"{' or '.join(case.names)}"
            ) from exc
    raise AssertionError(f"{case.label}: the invalid input was accepted")


def run_hostile(cases: st.SearchStrategy, key: str) -> int:
    """Check ``BUDGET[key]`` generated cases; record in ``RAN[key]`` and return how many ran."""
    budget = BUDGET[key]
    ran = 0

    @settings(
        max_examples=budget,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(cases)
    def check(case):
        nonlocal ran
        ran += 1
        assert_rejected(case)

    check()
    RAN[key] = ran
    assert ran >= budget
    return ran


# -------------------------------------------------------- bad values
class Opaque:
    """An object of no use to the library."""

    def __repr__(self) -> str:
        return "Opaque()"


JUNK = (
    "abc",
    "",
    b"\x00bytes",
    {},
    {"a": 1},
    Opaque(),
    1 + 2j,
    ["a", "b"],
    [[1.0, 2.0], [3.0]],
    LinearRegression(),
    {1.0, 2.0},
    print,
)
junk = st.sampled_from(JUNK)
junk_or_none = st.sampled_from((None,) + JUNK)
non_finite = st.sampled_from([NAN, INF, -INF])
# complex numbers, also with a zero imaginary part (still not real numbers)
complex_numbers = st.one_of(
    st.complex_numbers(min_magnitude=0.1, max_magnitude=10, allow_nan=False).filter(
        lambda z: z.imag != 0),
    st.sampled_from([0.5 + 0j, np.complex128(0.5), 2 + 0j]),
)


def with_none(strategy, none_is_bad: bool):
    return strategy | st.none() if none_is_bad else strategy


def bad_ints(low: int, high: int | None = None, *, none_is_bad: bool = True):
    """Anything but an int in ``low..high``: out of range, floats, bools, junk."""
    options = [
        st.integers(max_value=low - 1),
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(-3, 5).map(float),
        st.integers(1, 5).map(np.float64),
        st.booleans(),
        complex_numbers,
        st.sampled_from(["1", "2", np.array([2]), [2]]),
        junk,
    ]
    if high is not None:
        options.insert(1, st.integers(min_value=high + 1))
    return with_none(st.one_of(options), none_is_bad)


def bad_positive(*, none_is_bad: bool = True):
    """Anything but a finite positive real number."""
    return with_none(
        st.one_of(
            st.floats(max_value=0.0),
            non_finite,
            st.booleans(),
            complex_numbers,
            st.sampled_from(["1.0", np.array([1.0]), [1.0]]),
            junk,
        ),
        none_is_bad,
    )


def bad_levels():
    return st.one_of(
        st.floats(max_value=0.0),
        st.floats(min_value=1.0),
        non_finite,
        st.booleans(),
        complex_numbers,
        st.sampled_from(["0.9", np.array([0.9])]),
        junk_or_none,
    )


def bad_seeds(*, sklearn: bool, none_is_bad: bool = False):
    """Random states neither None, an int seed, nor a numpy generator."""
    options = [
        st.integers(max_value=-1),
        st.floats(allow_nan=True, allow_infinity=True),
        complex_numbers,
        st.sampled_from(["0", "abc", {}, Opaque(), [0.5]]),
    ]
    if sklearn:  # numpy's legacy RandomState takes 32-bit seeds only
        options.append(st.integers(min_value=2**32))
    return with_none(st.one_of(options), none_is_bad)


def finite_vectors(n: int):
    return hnp.arrays(float, n, elements=st.floats(-10, 10))


@st.composite
def vectors_with_non_finite(draw, n: int):
    x = draw(finite_vectors(n))
    x[draw(st.integers(0, n - 1))] = draw(non_finite)
    return x


@st.composite
def complex_vectors(draw, n: int):
    real = draw(finite_vectors(n))
    imag = draw(hnp.arrays(float, n, elements=st.floats(0.5, 2.0)))
    as_list = draw(st.booleans())
    z = real + 1j * imag
    return z.tolist() if as_list else z


def bad_signals(n: int, *, none_is_bad: bool = True):
    """Anything but a finite real vector of ``n`` samples (wrong lengths excluded)."""
    return with_none(
        st.one_of(
            junk,
            st.floats(allow_nan=True, allow_infinity=True),  # scalars
            st.sampled_from([np.empty(0), [], np.empty((0, 3))]),
            hnp.arrays(float, st.tuples(st.integers(2, 4), st.integers(2, 4)),
                       elements=st.floats(-1, 1)),
            hnp.arrays(float, (2, 2, 2), elements=st.floats(-1, 1)),
            vectors_with_non_finite(n),
            complex_vectors(n),
            st.just(["x"] * n),
        ),
        none_is_bad,
    )


def bad_fit_inputs(n: int):
    """Bad ``u`` for ``fit``: as :func:`bad_signals`, but a 2-D real array is several
    inputs (valid), so only arrays of three or more dimensions stay bad shapes."""
    return with_none(
        st.one_of(
            junk,
            st.floats(allow_nan=True, allow_infinity=True),  # scalars
            st.sampled_from([np.empty(0), [], np.empty((0, 3))]),
            hnp.arrays(float, (2, 2, 2), elements=st.floats(-1, 1)),
            vectors_with_non_finite(n),
            complex_vectors(n),
            st.just(["x"] * n),
        ),
        True,
    )


@st.composite
def vectors_with_infinity(draw, n: int):
    x = draw(finite_vectors(n))
    x[draw(st.integers(0, n - 1))] = draw(st.sampled_from([np.inf, -np.inf]))
    return x


def bad_slow_outputs(n: int):
    """Bad ``y_slow`` for ``fit``: NaN marks a missing sample (valid), inf does not,
    and neither does a record without any finite sample."""
    return with_none(
        st.one_of(
            junk,
            st.floats(allow_nan=True, allow_infinity=True),  # scalars
            st.sampled_from([np.empty(0), [], np.empty((0, 3)), np.full(n, np.nan)]),
            hnp.arrays(float, st.tuples(st.integers(2, 4), st.integers(2, 4)),
                       elements=st.floats(-1, 1)),
            hnp.arrays(float, (2, 2, 2), elements=st.floats(-1, 1)),
            vectors_with_infinity(n),
            complex_vectors(n),
            st.just(["x"] * n),
        ),
        True,
    )


def wrong_lengths(n: int):
    """Finite real vectors whose length is not ``n``."""
    return st.integers(1, n + 4).filter(lambda k: k != n).flatmap(finite_vectors)


def constant_signals(n: int):
    """Constant vectors, also of values whose computed mean is not exactly the value.

    (``np.full(7, 0.1).mean() != 0.1``: the spread is 1e-33, not 0.)
    """
    return st.one_of(st.floats(-5, 5), st.sampled_from([0.1, 0.7, 2.2])).map(
        lambda c: np.full(n, c))


@st.composite
def vectors_with_negative(draw, n: int):
    x = draw(hnp.arrays(float, n, elements=st.floats(0, 10)))
    x[draw(st.integers(0, n - 1))] = draw(st.floats(max_value=-1e-300))
    return x


def bad_lags(*, none_is_bad: bool):
    return with_none(
        st.one_of(
            st.integers(1, 4).flatmap(vectors_with_negative),
            st.integers(1, 4).flatmap(vectors_with_non_finite),
            st.integers(1, 4).flatmap(vectors_with_negative).map(lambda x: x[:, None]),
            hnp.arrays(float, st.tuples(st.integers(1, 3), st.integers(2, 3)),
                       elements=st.floats(0, 5)),
            hnp.arrays(float, (2, 1, 1), elements=st.floats(0, 5)),
            st.floats(0, 5),
            st.integers(1, 4).flatmap(complex_vectors),
            junk,
        ),
        none_is_bad,
    )


def bad_frequencies():
    """Frequency grids in Hz that are not finite, non-negative and non-empty vectors."""
    return st.one_of(
        st.integers(1, 4).flatmap(vectors_with_negative),
        bad_signals(3, none_is_bad=False),
    )


# ------------------------------------------------------- bad kernels
@dataclass(frozen=True)
class Bad:
    """A bad value with the argument names its error must mention.

    The repr never calls the value's own repr (scikit-learn's repr of
    ``ConstantKernel(-1.0)`` takes a square root and warns).
    """

    value: object
    names: tuple[str, ...]

    def __repr__(self) -> str:
        return show(self.value)


HYPERPARAMETERS = {
    TC: {"alpha": (0.0, 1.0)},
    DC: {"alpha": (0.0, 1.0), "beta": (-1.0, 1.0)},
    SS: {"alpha": (0.0, 1.0)},
    PK: {"alpha": (0.0, 1.0), "omega": (0.0, 2 * math.pi), "sigma1": (0.0, INF),
         "sigma2": (0.0, INF)},
}


@st.composite
def kernels_with_bad_hyperparameter(draw):
    """A lag kernel (maybe scaled or summed) with one value outside its range."""
    kind = draw(st.sampled_from(sorted(HYPERPARAMETERS, key=lambda k: k.__name__)))
    name = draw(st.sampled_from(sorted(HYPERPARAMETERS[kind])))
    low, high = HYPERPARAMETERS[kind][name]
    out_of_range = [st.floats(max_value=low), non_finite, st.booleans(), complex_numbers,
                    st.sampled_from(["0.5", None, np.array([0.5, 0.6]), {}, Opaque()])]
    if math.isfinite(high):
        out_of_range.append(st.floats(min_value=high, exclude_min=True))
    kernel = kind(**{name: draw(st.one_of(out_of_range))})
    wrap = draw(st.sampled_from(["bare", "scaled", "sum"]))
    if wrap == "scaled":
        kernel = C(2.0) * kernel
    elif wrap == "sum":
        kernel = C(1.0) * DC(0.8, 0.6) + kernel
    return Bad(kernel, (name, "kernel"))


NOT_KERNELS = ("DC", LinearRegression(), {}, Opaque(), DC, 1.0, np.eye(3), [DC(), TC()])
# A negative, NaN or infinite prior variance; only the estimator is asked to
# refuse these (scikit-learn's ConstantKernel itself takes any value).
BAD_AMPLITUDES = tuple(
    Bad(C(value) * kind(), ("constant_value", "kernel"))
    for value, kind in ((-1.0, DC), (NAN, DC), (INF, TC))
)


def bad_kernels(*, amplitudes: bool = True):
    options = [
        st.sampled_from(NOT_KERNELS).map(lambda k: Bad(k, ("kernel",))),
        kernels_with_bad_hyperparameter(),
    ]
    if amplitudes:
        options.append(st.sampled_from(BAD_AMPLITUDES))
    return st.one_of(options)


BAD_BOUNDS = ("abc", (-1.0, 2.0), (0.0, 1.0), (2.0, 1.0), (NAN, 1.0), (1e-3,), 5.0, {})
# DC's beta is a correlation: (0, 1) is valid for it, the bounds must lie in (-1, 1]
BAD_CORRELATION_BOUNDS = ("abc", (-1.0, 0.5), (-2.0, 0.5), (0.5, 1.5), (0.6, 0.5), (NAN, 0.5),
                          (1e-3,), 5.0, {})


@st.composite
def kernels_with_bad_bounds(draw):
    """Kernels whose tuning bounds are malformed (only used when tuning)."""
    kernel, choices = draw(st.sampled_from([
        (lambda b: TC(alpha_bounds=b), BAD_BOUNDS),
        (lambda b: C(1.0) * DC(beta_bounds=b), BAD_CORRELATION_BOUNDS),
        (lambda b: C(1.0, constant_value_bounds=b) * SS(), BAD_BOUNDS),
        (lambda b: PK(omega_bounds=b), BAD_BOUNDS),
    ]))
    kernel = kernel(draw(st.sampled_from(choices)))
    return Bad(kernel, ("bounds", "alpha_bounds", "beta_bounds", "omega_bounds",
                        "constant_value_bounds", "kernel"))


# ---------------------------------------------------- fitted objects
U12 = np.random.default_rng(12).standard_normal(12)
FACTOR, ORDER, OFFSET = 3, 5, 1
Y4 = np.random.default_rng(4).standard_normal(4)  # len(range(1, 12, 3)) == 4


@cache
def gaussian_process():
    return FIRGaussianProcess(
        C(1.0) * DC(0.8, 0.7), factor=FACTOR, order=ORDER, offset=OFFSET,
        noise_level=0.1, optimizer=None,
    ).fit(U12, Y4)


@cache
def least_squares():
    u = np.random.default_rng(30).standard_normal(30)
    y = np.random.default_rng(10).standard_normal(10)
    return LeastSquaresFIR(factor=3, order=4).fit(u, y)


@cache
def operator():
    return DownsampledConvolution(U12, FACTOR, ORDER, OFFSET)


# ------------------------------------------------------------ estimators
@dataclass(frozen=True)
class Layout:
    u: np.ndarray
    factor: int
    order: int
    offset: int
    y_slow: np.ndarray


@st.composite
def layouts(draw, max_samples: int = 10):
    n = draw(st.integers(2, max_samples))
    factor = draw(st.integers(1, 4))
    offset = draw(st.integers(0, min(factor, n) - 1))
    order = draw(st.integers(1, n))
    rng = np.random.default_rng(draw(st.integers(0, 1000)))
    m = len(range(offset, n, factor))
    return Layout(rng.standard_normal(n), factor, order, offset, rng.standard_normal(m))


def bad_offsets(layout: Layout):
    options = [bad_ints(0, layout.factor - 1)]
    if layout.factor > len(layout.u):  # an offset past the record
        options.append(st.integers(len(layout.u), layout.factor - 1))
    return st.one_of(options)


@st.composite
def fit_cases(draw):
    lay = draw(layouts())
    n, m = len(lay.u), len(lay.y_slow)
    params = dict(factor=lay.factor, order=lay.order, offset=lay.offset, optimizer=None,
                  kernel=C(1.0) * DC(0.8, 0.7))
    data = dict(u=lay.u, y_slow=lay.y_slow)
    slot = draw(st.sampled_from([
        "u", "y_slow", "factor", "order", "offset", "noise_level", "noise_level_bounds",
        "optimizer", "n_restarts_optimizer", "random_state", "kernel", "kernel bounds",
    ]))
    names = (slot,)
    if slot == "u":
        data["u"] = draw(bad_fit_inputs(n))
    elif slot == "y_slow":
        data["y_slow"] = draw(bad_slow_outputs(m) | wrong_lengths(m))
    elif slot == "factor":
        params["factor"] = draw(bad_ints(1))
    elif slot == "order":
        params["order"] = draw(bad_ints(1, n, none_is_bad=False))
    elif slot == "offset":
        params["offset"] = draw(bad_offsets(lay))
    elif slot == "noise_level":
        params["noise_level"] = draw(bad_positive())
    elif slot == "noise_level_bounds":
        params["noise_level_bounds"] = draw(st.sampled_from(BAD_BOUNDS + (None, "Fixed")))
    elif slot == "optimizer":
        params["optimizer"] = draw(st.sampled_from(
            ["ML", "", "fmin_l_bfgs_b", 1, True, {}, Opaque(), np.array([1, 2])]
        ))
    elif slot == "n_restarts_optimizer":
        params["n_restarts_optimizer"] = draw(bad_ints(0))
    elif slot == "random_state":
        # used by the tuning; with optimizer=None it is never looked at
        params.update(random_state=draw(bad_seeds(sklearn=True)),
                      optimizer="marginal_likelihood", n_restarts_optimizer=1)
    elif slot == "kernel":
        bad = draw(bad_kernels())
        params["kernel"], names = bad.value, bad.names
        params["optimizer"] = draw(st.sampled_from([None, "marginal_likelihood"]))
    else:
        bad = draw(kernels_with_bad_bounds())
        params["kernel"], names = bad.value, bad.names
        params["optimizer"] = "marginal_likelihood"
    shown = ", ".join(f"{k}={show(v)}" for k, v in params.items())
    label = (f"FIRGaussianProcess({shown}).fit(u={show(data['u'])}, "
             f"y_slow={show(data['y_slow'])})")
    return Case(label, lambda: FIRGaussianProcess(**params).fit(**data), names)


@pytest.mark.slow
def test_fit_rejects_bad_arguments():
    run_hostile(fit_cases(), "fit")


def fitted_model_slots(model: Callable, name: str) -> list[Slot]:
    """predict, score and frequency_response, shared by both estimators."""
    n = 12
    u, y_fast = U12, np.random.default_rng(5).standard_normal(n)
    # a list of sequences is a list of records, which predict accepts
    single_bad = bad_signals(n).filter(lambda v: not is_record_list(v))
    return [
        Slot(name + ".predict(u={})", lambda v: model().predict(v), single_bad, ("u",)),
        Slot(name + ".predict(u={}, return_std=True)",
             lambda v: model().predict(v, return_std=True), single_bad, ("u",)),
        Slot(name + ".score(u={}, y_fast)", lambda v: model().score(v, y_fast),
             bad_signals(n), ("u",)),
        Slot(name + ".score(u, y_fast={})", lambda v: model().score(u, v),
             bad_signals(n) | wrong_lengths(n) | constant_signals(n), ("y_fast",)),
        Slot(name + ".frequency_response(freqs={})",
             lambda v: model().frequency_response(v), bad_frequencies(), ("freqs",)),
        # sample_time=None means the model's own sample time
        Slot(name + ".frequency_response(sample_time={})",
             lambda v: model().frequency_response(sample_time=v),
             bad_positive(none_is_bad=False), ("sample_time",)),
        Slot(name + ".frequency_response([0.1, 0.2], sample_time={})",
             lambda v: model().frequency_response([0.1, 0.2], sample_time=v),
             bad_positive(none_is_bad=False), ("sample_time",)),
        Slot(name + ".frequency_response(level={})",
             lambda v: model().frequency_response(level=v), bad_levels(), ("level",)),
    ]


N_THETA = 4  # log of the constant and alpha, artanh(beta) of C * DC, log of the noise level


def bad_thetas():
    return st.one_of(
        st.integers(0, 7).filter(lambda k: k != N_THETA).flatmap(finite_vectors),
        vectors_with_non_finite(N_THETA),
        bad_signals(N_THETA, none_is_bad=False),
    )


NOT_FITTED = st.sampled_from([
    ("predict", lambda e: e.predict(U12)),
    ("score", lambda e: e.score(U12, U12)),
    ("frequency_response", lambda e: e.frequency_response()),
    ("impulse_response", lambda e: e.impulse_response()),
    ("sample_impulse_responses", lambda e: e.sample_impulse_responses()),
    ("log_marginal_likelihood", lambda e: e.log_marginal_likelihood()),
])


def unfitted_cases():
    def case(pair):
        method, call = pair
        return Case(f"FIRGaussianProcess().{method}(...) before fit",
                    partial(call, FIRGaussianProcess()), ("fit",), (NotFittedError,))

    return NOT_FITTED.map(case)


def gaussian_process_method_cases():
    gp = gaussian_process
    slots = fitted_model_slots(gp, "gp") + [
        Slot("gp.impulse_response(lags={})", lambda v: gp().impulse_response(v),
             bad_lags(none_is_bad=False), ("lags",)),
        Slot("gp.impulse_response(lags={}, return_std=True)",
             lambda v: gp().impulse_response(v, return_std=True),
             bad_lags(none_is_bad=False), ("lags",)),
        Slot("gp.impulse_response(lags={}, return_cov=True)",
             lambda v: gp().impulse_response(v, return_cov=True),
             bad_lags(none_is_bad=False), ("lags",)),
        Slot("gp.impulse_response(lags={}, return_std=True, return_cov=True)",
             lambda v: gp().impulse_response(v, return_std=True, return_cov=True),
             st.sampled_from([None, [0.5, 1.5]]), ("return_std", "return_cov")),
        Slot("gp.sample_impulse_responses(lags={})",
             lambda v: gp().sample_impulse_responses(v), bad_lags(none_is_bad=False),
             ("lags",)),
        Slot("gp.sample_impulse_responses(n_samples={})",
             lambda v: gp().sample_impulse_responses(n_samples=v), bad_ints(1), ("n_samples",)),
        Slot("gp.sample_impulse_responses(random_state={})",
             lambda v: gp().sample_impulse_responses(random_state=v),
             bad_seeds(sklearn=True), ("random_state",)),
        Slot("gp.log_marginal_likelihood(theta={})",
             lambda v: gp().log_marginal_likelihood(v), bad_thetas(), ("theta",)),
        Slot("gp.log_marginal_likelihood(theta={}, eval_gradient=True)",
             lambda v: gp().log_marginal_likelihood(v, eval_gradient=True),
             st.just(None), ("theta", "eval_gradient")),
    ]
    return slot_cases(*slots) | unfitted_cases()


def test_gaussian_process_methods_reject_bad_arguments():
    run_hostile(gaussian_process_method_cases(), "gp_methods")


def zero_order_hold_input():
    return np.repeat(np.random.default_rng(8).standard_normal(8), 3)  # 24 samples, factor 3


@st.composite
def least_squares_fit_cases(draw):
    lay = draw(layouts(max_samples=12))
    n, m = len(lay.u), len(lay.y_slow)
    params = dict(factor=lay.factor, order=lay.order, offset=lay.offset)
    data = dict(u=lay.u, y_slow=lay.y_slow)
    slot = draw(st.sampled_from(["u", "y_slow", "factor", "order", "offset", "unidentifiable"]))
    names = (slot,)
    if slot == "u":
        data["u"] = draw(bad_fit_inputs(n))
    elif slot == "y_slow":
        data["y_slow"] = draw(bad_slow_outputs(m) | wrong_lengths(m))
    elif slot == "factor":
        params["factor"] = draw(bad_ints(1))
    elif slot == "order":
        # None (no default order) and order >= M (Lemma 1) are invalid too
        params["order"] = draw(bad_ints(1) | st.integers(m, m + 5))
    elif slot == "offset":
        params["offset"] = draw(bad_offsets(lay))
    else:  # zero-order-hold input: rank-deficient regressor (Lemma 2)
        params = dict(factor=3, order=draw(st.integers(3, 6)), offset=0)
        data = dict(u=zero_order_hold_input(), y_slow=np.random.default_rng(1).standard_normal(8))
        names = ("order",)
    shown = ", ".join(f"{k}={show(v)}" for k, v in params.items())
    label = f"LeastSquaresFIR({shown}).fit(u={show(data['u'])}, y_slow={show(data['y_slow'])})"
    return Case(label, lambda: LeastSquaresFIR(**params).fit(**data), names)


def test_least_squares_rejects_bad_arguments():
    cases = least_squares_fit_cases() | slot_cases(*fitted_model_slots(least_squares, "ls"))
    run_hostile(cases, "least_squares")


# -------------------------------------------------------------- operator
@st.composite
def operator_constructor_cases(draw):
    lay = draw(layouts())
    args = dict(u=lay.u, factor=lay.factor, order=lay.order, offset=lay.offset)
    slot = draw(st.sampled_from(sorted(args)))
    args[slot] = draw({
        "u": bad_signals(len(lay.u)),
        "factor": bad_ints(1),
        "order": bad_ints(1, len(lay.u)),
        "offset": bad_offsets(lay),
    }[slot])
    label = "DownsampledConvolution({})".format(
        ", ".join(f"{k}={show(v)}" for k, v in args.items()))
    return Case(label, lambda: DownsampledConvolution(**args), (slot,))


def bad_operands(rows: int):
    """Anything but a finite real array of shape (rows,) or (rows, k)."""
    return st.one_of(
        bad_signals(rows).filter(lambda v: not (isinstance(v, np.ndarray) and v.ndim == 2)),
        wrong_lengths(rows),
        hnp.arrays(float, (rows, 2), elements=st.floats(-1, 1)).map(
            lambda a: np.where(np.arange(2) == 0, NAN, a)),
        hnp.arrays(float, (rows, 2, 2), elements=st.floats(-1, 1)),
        st.integers(1, 3).filter(lambda k: k != rows).flatmap(
            lambda k: hnp.arrays(float, (k, 2), elements=st.floats(-1, 1))),
    )


def operator_cases():
    op = operator
    return operator_constructor_cases() | slot_cases(
        Slot("op.matvec(coef={})", lambda v: op().matvec(v), bad_operands(ORDER), ("coef",)),
        Slot("op.rmatvec(y={})", lambda v: op().rmatvec(v), bad_operands(4), ("y",)),
    )


def test_operator_rejects_bad_arguments():
    run_hostile(operator_cases(), "operator")


# -------------------------------------------------------- observed kernel
def bad_slow_indices():
    """Anything but integer slow-sample indices in 0..3 of shape (n, 1) or (n,)."""
    return st.one_of(
        st.floats(0.1, 2.9).filter(lambda x: x != int(x)).map(lambda x: np.array([[0.0], [x]])),
        st.integers(max_value=-1).map(lambda k: np.array([[0], [k]])),
        st.integers(min_value=4, max_value=10**6).map(lambda k: np.array([[k]])),
        non_finite.map(lambda x: np.array([[0.0], [x]])),
        st.sampled_from([
            np.empty((0, 1)),
            np.array([[0, 1], [1, 2]]),  # two columns: only (n, 1) indexes slow samples
            np.zeros((2, 1, 1)),
            np.array([[True], [False]]),
            np.array([[0 + 1j]]),
        ]),
        junk_or_none,
    )


def observed_kernel_cases():
    X = np.arange(4)[:, None]

    def observed(kernel=C(1.0) * DC(0.8, 0.7), op=VALID):
        return ObservedKernel(kernel, operator() if op is VALID else op)

    bad_operators = st.sampled_from(["op", None, {}, Opaque(), LinearRegression(), DC(),
                                     np.eye(4), U12])
    kernel_cases = bad_kernels(amplitudes=False).map(lambda bad: Case(
        f"ObservedKernel({bad!r}, op)(X)", lambda: observed(kernel=bad.value)(X), bad.names))
    return kernel_cases | slot_cases(
        Slot("ObservedKernel(kernel, {})(X)", lambda v: observed(op=v)(X), bad_operators,
             ("observation",)),
        Slot("ObservedKernel(kernel, op)(X={})", lambda v: observed()(v), bad_slow_indices(),
             ("X",)),
        Slot("ObservedKernel(kernel, op)(X={}, eval_gradient=True)",
             lambda v: observed()(v, eval_gradient=True), bad_slow_indices(), ("X",)),
        Slot("ObservedKernel(kernel, op)(X, Y={})", lambda v: observed()(X, v),
             bad_slow_indices().filter(lambda v: v is not None), ("Y",)),
        Slot("ObservedKernel(kernel, op).diag(X={})", lambda v: observed().diag(v),
             bad_slow_indices(), ("X",)),
    )


def test_observed_kernel_rejects_bad_arguments():
    run_hostile(observed_kernel_cases(), "observed_kernel")


# ----------------------------------------------------------- lag kernels
VALID_KERNELS = (TC(0.8), DC(0.8, 0.6), SS(0.9), PK(0.9, 0.6, 1.0, 0.5))
LAGS = np.array([[0.0], [0.5], [2.0]])


def lag_kernel_cases():
    kernels = st.sampled_from(VALID_KERNELS)

    def with_kernel(template, call, values, names):
        return st.tuples(kernels, values).map(lambda kv: Case(
            template.format(type(kv[0]).__name__, show(kv[1])),
            partial(call, *kv), names))

    hyper = kernels_with_bad_hyperparameter().flatmap(lambda bad: st.sampled_from([
        Case(f"{bad!r}(X)", lambda: bad.value(LAGS), bad.names),
        Case(f"{bad!r}.diag(X)", lambda: bad.value.diag(LAGS), bad.names),
        Case(f"{bad!r}(X, eval_gradient=True)",
             lambda: bad.value(LAGS, eval_gradient=True), bad.names),
    ]))
    from_hz = slot_cases(
        Slot("PK.from_hz(frequency={}, sample_time=0.1)",
             lambda v: PK.from_hz(v, 0.1),  # above 1 / sample_time, omega would exceed 2 pi
             bad_positive() | st.floats(10.0, 1e6, exclude_min=True), ("frequency",)),
        Slot("PK.from_hz(1.0, sample_time={})", lambda v: PK.from_hz(1.0, v), bad_positive(),
             ("sample_time",)),
        Slot("PK.from_hz(1.0, 0.1, frequency_bounds={})",
             lambda v: PK.from_hz(1.0, 0.1, frequency_bounds=v),
             st.sampled_from(BAD_BOUNDS), ("frequency_bounds",)),
    )
    return st.one_of(
        with_kernel("{}(X={})", lambda k, v: k(v), bad_lags(none_is_bad=True), ("X",)),
        with_kernel("{}(LAGS, Y={})", lambda k, v: k(LAGS, v), bad_lags(none_is_bad=False),
                    ("Y",)),
        with_kernel("{}.diag(X={})", lambda k, v: k.diag(v), bad_lags(none_is_bad=True),
                    ("X",)),
        with_kernel("{}(X={}, eval_gradient=True)", lambda k, v: k(v, eval_gradient=True),
                    bad_lags(none_is_bad=True), ("X",)),
        with_kernel("{}(LAGS, Y={}, eval_gradient=True)",
                    lambda k, v: k(LAGS, v, eval_gradient=True), st.just(LAGS), ("Y",)),
        hyper,
        from_hz,
    )


def test_lag_kernels_reject_bad_arguments():
    run_hostile(lag_kernel_cases(), "lag_kernels")


# ------------------------------------------------------------- metrics
def goodness_of_fit_cases():
    y = np.array([1.0, 2.0, 4.0, 3.0, 0.0, 5.0, 6.0])
    return slot_cases(
        Slot("goodness_of_fit(y_true={}, y_pred)", lambda v: goodness_of_fit(v, y),
             bad_signals(7), ("y_true",)),
        Slot("goodness_of_fit(y_true={}, y_pred)", lambda v: goodness_of_fit(v, y),
             constant_signals(7), ("y_true",)),
        Slot("goodness_of_fit(y_true, y_pred={})", lambda v: goodness_of_fit(y, v),
             bad_signals(7) | wrong_lengths(7), ("y_pred",)),
        Slot("fit_percent(y_true={}, y_pred)", lambda v: fit_percent(v, y),
             bad_signals(7) | constant_signals(7), ("y_true",)),
        Slot("fit_percent(y_true, y_pred={})", lambda v: fit_percent(y, v),
             bad_signals(7) | wrong_lengths(7), ("y_pred",)),
    )


def test_goodness_of_fit_rejects_bad_arguments():
    run_hostile(goodness_of_fit_cases(), "goodness_of_fit")


# ---------------------------------------------------------- persistence
@cache
def saved_bytes(kind: str) -> bytes:
    buffer = io.BytesIO()
    save_model(gaussian_process() if kind == "gp" else least_squares(), buffer)
    return buffer.getvalue()


def read_members(data: bytes) -> dict:
    with np.load(io.BytesIO(data), allow_pickle=False) as archive:
        return {key: archive[key] for key in archive.files}


def sign(header: dict, arrays: dict) -> str:
    """SHA-256 of a header and arrays, as the file format documents it."""
    digest = hashlib.sha256()
    content = {k: v for k, v in header.items() if k != "sha256"}
    digest.update(json.dumps(content, sort_keys=True, separators=(",", ":")).encode() + b"\n")
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        shape = ",".join(str(n) for n in array.shape)
        digest.update(f"{name}:{array.dtype.str}:{shape}\n".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def forge(kind: str, edit: Callable[[dict], None]) -> io.BytesIO:
    """A model file whose header is edited and then signed again (a valid checksum)."""
    members = read_members(saved_bytes(kind))
    header = json.loads(bytes(members.pop("header")).decode())
    edit(header)
    header["sha256"] = sign(header, members)
    buffer = io.BytesIO()
    encoded = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    np.savez(buffer, header=encoded, **members)
    buffer.seek(0)
    return buffer


def test_forged_files_are_signed_as_documented():
    assert load_model(forge("gp", lambda header: None)).coef_.shape == (ORDER,)


def setter(*path_and_value):
    *path, value = path_and_value

    def edit(header):
        target = header
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value

    return edit


FORGERIES = (
    ("gp", setter("fitted", "factor", 0)),
    ("gp", setter("fitted", "order", -1)),
    ("gp", setter("fitted", "offset", 7)),
    ("ls", setter("fitted", "factor", "3")),
    ("ls", setter("fitted", "order", 10**9)),
    ("ls", setter("fitted", "noise_variance_", "nan")),
    ("gp", setter("fitted", "noise_level_", -1.0)),
    ("gp", setter("fitted", "noise_level_", {"type": "float", "value": "inf"})),
    ("gp", setter("fitted", "kernel_", {"class": "os.system", "params": {}})),
    ("gp", setter("fitted", "kernel_", {"class": "DC", "params": {"alpha": 5.0}})),
    ("gp", setter("fitted", "kernel_", {"class": "DC", "params": {"gamma": 1.0}})),
    ("gp", setter("fitted", "kernel_", {"class": "Sum", "k1": {"class": "DC"}})),
    ("gp", setter("fitted", "kernel_", "DC")),
    ("gp", setter("params", "factor", 2)),
    ("gp", setter("params", "unknown", 1)),
    ("gp", setter("estimator", "LinearRegression")),
    ("ls", setter("estimator", "FIRGaussianProcess")),
    ("gp", setter("format_version", 99)),
    ("gp", setter("format_version", "1")),
    ("gp", setter("library_version", "99.0")),
    ("gp", setter("format", "something-else")),
    ("gp", lambda header: header.pop("fitted")),
)


@st.composite
def corrupted_files(draw):
    kind = draw(st.sampled_from(["gp", "ls"]))
    data = saved_bytes(kind)
    how = draw(st.sampled_from(["truncated", "garbage", "forged", "header bytes", "npy"]))
    if how == "truncated":
        cut = draw(st.integers(0, len(data) - 1))
        return f"{kind} file truncated to {cut} bytes", io.BytesIO(data[:cut])
    if how == "garbage":
        blob = draw(st.binary(max_size=64))
        return f"BytesIO({blob!r})", io.BytesIO(blob)
    if how == "forged":
        index = draw(st.integers(0, len(FORGERIES) - 1))
        kind, edit = FORGERIES[index]
        return f"{kind} file with forged header #{index}", forge(kind, edit)
    if how == "npy":
        buffer = io.BytesIO()
        np.save(buffer, np.arange(3.0))
        buffer.seek(0)
        return "an .npy file", buffer
    # flip a byte of the stored header JSON, which the zip CRC and the checksum protect
    start = data.index(b'{"')
    position = draw(st.integers(start, start + 200))
    flipped = bytearray(data)
    flipped[position] ^= 0x20
    return f"{kind} file with byte {position} flipped", io.BytesIO(bytes(flipped))


def bad_paths(*, text_file: bool):
    options = [
        st.sampled_from([None, 1.5, {}, [], ("a.npz",), Opaque(), 1 + 2j, "a\x00b.npz",
                         b"a\x00b"]),
        st.integers(max_value=-1),
        st.integers(min_value=2**31),  # never a file descriptor
    ]
    if text_file:  # a text stream cannot take the binary archive
        options.append(st.builds(io.StringIO))
    return st.one_of(options)


class FIRSubclass(FIRGaussianProcess):
    pass


@cache
def fitted_subclass():
    return FIRSubclass(C(1.0) * DC(), factor=3, order=4, optimizer=None).fit(U12, Y4)


@cache
def unstorable_model():
    return FIRGaussianProcess(
        C(1.0) * DC(), factor=3, order=4, optimizer=None,
        random_state=np.random.default_rng(0),  # a Generator, not a RandomState
    ).fit(U12, Y4)


def persistence_cases():
    fitted_estimator = LinearRegression().fit([[0.0], [1.0]], [0.0, 1.0])
    bad_models = st.sampled_from(
        [(show(m), partial(lambda m: m, m), ("model",)) for m in JUNK + (None, fitted_estimator)]
        + [
            ("FIRSubclass(...), fitted", fitted_subclass, ("model",)),
            ("FIRGaussianProcess(random_state=Generator), fitted", unstorable_model,
             ("random_state",)),
        ]
    )

    def save_bad_model(triple):
        label, model, names = triple
        return Case(f"save_model({label}, BytesIO())",
                    lambda: save_model(model(), io.BytesIO()), names)

    unfitted = st.sampled_from([FIRGaussianProcess(), LeastSquaresFIR(order=3)]).map(
        lambda m: Case(f"save_model({show(m)}, BytesIO()) unfitted",
                       lambda: save_model(m, io.BytesIO()), ("fit",), (NotFittedError,)))
    corrupted = corrupted_files().map(lambda pair: Case(
        f"load_model({pair[0]})", lambda: load_model(pair[1]), ("file", "header", "kernel"),
        (ModelFileError,)))
    return st.one_of(
        bad_models.map(save_bad_model),
        unfitted,
        slot_cases(
            Slot("save_model(gp, path={})", lambda v: save_model(gaussian_process(), v),
                 bad_paths(text_file=True), ("path",)),
            Slot("load_model(path={})", lambda v: load_model(v), bad_paths(text_file=False),
                 ("path",)),
        ),
        corrupted,
    )


def test_persistence_rejects_bad_paths_and_objects():
    run_hostile(persistence_cases(), "persistence")


def test_save_model_rejects_a_file_descriptor_as_path(tmp_path):
    # An int (or a bool: True is 1, stdout) is not a documented path; open()
    # would write to, and then close, whatever file this process has open there.
    fd = os.open(tmp_path / "target.npz", os.O_WRONLY | os.O_CREAT)
    inode = os.fstat(fd).st_ino
    try:
        with pytest.raises(TypeError, match="path"):
            save_model(gaussian_process(), fd)
    finally:
        try:
            still_ours = os.fstat(fd).st_ino == inode
        except OSError:
            still_ours = False
        if still_ours:
            os.close(fd)


def test_load_model_of_a_missing_file_raises_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_model(tmp_path / "missing.npz")


# ----------------------------------------------------------- simulation
def simulation_cases():
    seeds = bad_seeds(sklearn=False)
    y8 = np.sin(np.arange(8.0))
    system = sim.DiscreteSystem([[0.5]], [1.0], [1.0], 0.0, sample_time=0.1)
    bad_bands = st.sampled_from(["ab", {}, (2.0, 1.0), (-1.0, 1.0), (NAN, 1.0), (1.0,),
                                 (0.0, 1.0, 2.0), (1e6, 2e6), [[0.0, 1.0]], 1.0])
    bad_nominal = st.sampled_from(["abc", None, 1.0, [1.0, 2.0], {"k1": "a"}, {"k1": NAN},
                                   {"k1": INF}, {"k1": None}])
    not_systems = st.sampled_from(["system", None, {}, Opaque(), LinearRegression(),
                                   np.eye(2)])
    bad_matrices = st.sampled_from(["abc", None, {}, np.ones((2, 3)), np.empty((0, 0)),
                                    [[NAN]], [[INF]], np.ones((1, 1, 1)), [[1 + 1j]]])
    bad_vectors = st.sampled_from(["abc", None, {}, np.ones(3), [[NAN]], [1 + 1j],
                                   np.ones((2, 2))])
    bad_snr = st.one_of(non_finite, st.booleans(), complex_numbers, junk_or_none,
                        st.just(np.array([10.0])))
    bad_perturbations = st.one_of(st.floats(max_value=-1e-300), st.floats(min_value=1.0),
                                  non_finite, st.booleans(), complex_numbers, junk_or_none)
    experiment = partial(sim.simulate_experiment, system, np.ones(6), 3)
    return slot_cases(
        Slot("multisine(n_samples={})", lambda v: sim.multisine(v), bad_ints(3), ("n_samples",)),
        Slot("multisine(8, sample_time={})", lambda v: sim.multisine(8, sample_time=v),
             bad_positive(), ("sample_time",)),
        Slot("multisine(8, band={})", lambda v: sim.multisine(8, band=v), bad_bands, ("band",)),
        Slot("multisine(8, rms={})", lambda v: sim.multisine(8, rms=v), bad_positive(), ("rms",)),
        Slot("multisine(8, random_state={})", lambda v: sim.multisine(8, random_state=v),
             seeds, ("random_state",)),
        Slot("random_binary_sequence(n_samples={})", sim.random_binary_sequence, bad_ints(1),
             ("n_samples",)),
        Slot("random_binary_sequence(4, amplitude={})",
             lambda v: sim.random_binary_sequence(4, amplitude=v), bad_positive(),
             ("amplitude",)),
        Slot("random_binary_sequence(4, random_state={})",
             lambda v: sim.random_binary_sequence(4, random_state=v), seeds, ("random_state",)),
        Slot("zero_order_hold(u_slow={}, 2)", lambda v: sim.zero_order_hold(v, 2),
             bad_signals(3), ("u_slow",)),
        Slot("zero_order_hold([1.0, 2.0], factor={})",
             lambda v: sim.zero_order_hold([1.0, 2.0], v), bad_ints(1), ("factor",)),
        Slot("zoh_input(n_samples={}, 2)", lambda v: sim.zoh_input(v, 2), bad_ints(1),
             ("n_samples",)),
        Slot("zoh_input(6, factor={})", lambda v: sim.zoh_input(6, v), bad_ints(1), ("factor",)),
        Slot("zoh_input(6, 2, random_state={})", lambda v: sim.zoh_input(6, 2, random_state=v),
             seeds, ("random_state",)),
        Slot("add_output_noise(y={}, 20.0)", lambda v: sim.add_output_noise(v, 20.0),
             bad_signals(8), ("y",)),
        Slot("add_output_noise(y, snr_db={})", lambda v: sim.add_output_noise(y8, v), bad_snr,
             ("snr_db",)),
        Slot("add_output_noise(y, 20.0, random_state={})",
             lambda v: sim.add_output_noise(y8, 20.0, random_state=v), seeds, ("random_state",)),
        Slot("downsample(y={}, 2)", lambda v: sim.downsample(v, 2), bad_signals(8), ("y",)),
        Slot("downsample(y, factor={})", lambda v: sim.downsample(y8, v), bad_ints(1),
             ("factor",)),
        Slot("downsample(y, 3, offset={})", lambda v: sim.downsample(y8, 3, offset=v),
             bad_ints(0, 2), ("offset",)),
        Slot("paper_system(sample_time={})", lambda v: sim.paper_system(sample_time=v),
             bad_positive(), ("sample_time",)),
        Slot("paper_system(perturbation={})", lambda v: sim.paper_system(perturbation=v),
             bad_perturbations, ("perturbation",)),
        Slot("paper_system(perturbation=0.1, random_state={})",
             lambda v: sim.paper_system(perturbation=0.1, random_state=v), seeds,
             ("random_state",)),
        Slot("wafer_stage_surrogate(sample_time={})",
             lambda v: sim.wafer_stage_surrogate(sample_time=v), bad_positive(),
             ("sample_time",)),
        Slot("wafer_stage_surrogate(perturbation={})",
             lambda v: sim.wafer_stage_surrogate(perturbation=v), bad_perturbations,
             ("perturbation",)),
        Slot("perturb_parameters(nominal={}, 0.1)", lambda v: sim.perturb_parameters(v, 0.1),
             bad_nominal, ("nominal",)),
        Slot("two_mass_spring_damper(k1={})", lambda v: sim.two_mass_spring_damper(k1=v),
             bad_positive(), ("k1",)),
        Slot("two_mass_spring_damper(m2={})", lambda v: sim.two_mass_spring_damper(m2=v),
             bad_positive(), ("m2",)),
        Slot("simulate_experiment(system={}, u, 3)",
             lambda v: sim.simulate_experiment(v, np.ones(6), 3), not_systems, ("system",)),
        Slot("simulate_experiment(system, u={}, 3)",
             lambda v: sim.simulate_experiment(system, v, 3), bad_signals(6), ("u",)),
        Slot("simulate_experiment(system, u, factor={})",
             lambda v: sim.simulate_experiment(system, np.ones(6), v), bad_ints(1),
             ("factor",)),
        Slot("simulate_experiment(system, u, 3, snr_db={})", lambda v: experiment(snr_db=v),
             bad_snr.filter(lambda v: v is not None), ("snr_db",)),
        Slot("simulate_experiment(system, u, 3, offset={})", lambda v: experiment(offset=v),
             bad_ints(0, 2), ("offset",)),
        Slot("simulate_experiment(system, u, 3, snr_db=20, random_state={})",
             lambda v: experiment(snr_db=20.0, random_state=v), seeds, ("random_state",)),
        Slot("DiscreteSystem(A={}, ...)", lambda v: sim.DiscreteSystem(v, [1.0], [1.0], 0.0, 0.1),
             bad_matrices, ("A",)),
        Slot("DiscreteSystem(B={}, ...)", lambda v: sim.DiscreteSystem([[0.5]], v, [1.0], 0.0, 0.1),
             bad_vectors, ("B",)),
        Slot("DiscreteSystem(..., sample_time={})",
             lambda v: sim.DiscreteSystem([[0.5]], [1.0], [1.0], 0.0, v), bad_positive(),
             ("sample_time",)),
        Slot("system.simulate(u={})", lambda v: system.simulate(v), bad_signals(4), ("u",)),
        Slot("system.impulse_response(n_lags={})", lambda v: system.impulse_response(v),
             bad_ints(1), ("n_lags",)),
        Slot("system.frequency_response(freqs={})", lambda v: system.frequency_response(v),
             st.one_of(st.integers(1, 3).flatmap(vectors_with_non_finite),
                       st.integers(1, 3).flatmap(complex_vectors), junk_or_none), ("freqs",)),
        Slot("system.slow_nyquist(factor={})", lambda v: system.slow_nyquist(v), bad_ints(1),
             ("factor",)),
    )


def test_simulation_rejects_bad_arguments():
    run_hostile(simulation_cases(), "simulation")


# ----------------------------------------------------- minimal reproducers
def fit_case(kernel, names, optimizer="marginal_likelihood"):
    model = FIRGaussianProcess(kernel, factor=FACTOR, order=ORDER, offset=OFFSET,
                               optimizer=optimizer)
    return Case(f"FIRGaussianProcess({show(kernel)}, optimizer={optimizer!r}).fit(u, y_slow)",
                lambda: model.fit(U12, Y4), names)


AMPLITUDE = ("constant_value", "kernel")
# Each is the smallest input of a distinct defect the generated tests found;
# kept as separate deterministic tests so that each reads as its own failure.
MINIMAL_REPRODUCERS = (
    Case("FIRGaussianProcess(C(nan) * DC(), factor=1, order=1).fit([0.5, -0.5], [1.0, 0.2])",
         lambda: FIRGaussianProcess(C(NAN) * DC(), factor=1, order=1).fit(
             [0.5, -0.5], [1.0, 0.2]), AMPLITUDE),
    fit_case(C(-1.0) * DC(), AMPLITUDE),
    fit_case(C(-1.0) * DC(), AMPLITUDE, optimizer=None),
    fit_case(TC(alpha_bounds=(2.0, 1.0)), ("alpha_bounds", "bounds", "kernel")),
    fit_case(TC(alpha=-0.5), ("alpha", "kernel")),
    fit_case(TC(alpha="0.5"), ("alpha", "kernel"), optimizer=None),
    Case("FIRGaussianProcess().fit(u + 1j, y_slow)",
         lambda: FIRGaussianProcess(factor=FACTOR, order=ORDER, offset=OFFSET,
                                    optimizer=None).fit(U12 + 1j, Y4), ("u",)),
    Case("gp.score(u, y_fast=np.full(12, 0.1))",
         lambda: gaussian_process().score(U12, np.full(12, 0.1)), ("y_fast",)),
    Case("gp.sample_impulse_responses(random_state=-1)",
         lambda: gaussian_process().sample_impulse_responses(random_state=-1),
         ("random_state",)),
    Case("goodness_of_fit(np.full(3, 0.1), np.zeros(3))",
         lambda: goodness_of_fit(np.full(3, 0.1), np.zeros(3)), ("y_true",)),
    Case("op.matvec(None)", lambda: operator().matvec(None), ("coef",)),
    Case("op.matvec([nan] * 5)", lambda: operator().matvec([NAN] * ORDER), ("coef",)),
    Case("op.rmatvec('abc')", lambda: operator().rmatvec("abc"), ("y",)),
    Case("ObservedKernel(DC(), 'op')(X)",
         lambda: ObservedKernel(DC(), "op")(np.arange(4)[:, None]), ("observation",)),
    Case("ObservedKernel('DC', op)(X)",
         lambda: ObservedKernel("DC", operator())(np.arange(4)[:, None]), ("kernel",)),
    Case("ObservedKernel(DC(), op)(X of shape (2, 2))",
         lambda: ObservedKernel(DC(), operator())(np.array([[0, 1], [1, 2]])), ("X",)),
    Case("TC()(X + 1j)", lambda: TC()(LAGS + 1j), ("X",)),
    Case("TC(alpha=0.5 + 0j)(X)", lambda: TC(alpha=0.5 + 0j)(LAGS), ("alpha",)),
    Case("PK.from_hz(100.0, sample_time=0.1)", lambda: PK.from_hz(100.0, 0.1),
         ("frequency",)),
    Case("PK.from_hz(1.0, 0.1, frequency_bounds='abc')",
         lambda: PK.from_hz(1.0, 0.1, frequency_bounds="abc"), ("frequency_bounds",)),
    Case("save_model(gp, None)", lambda: save_model(gaussian_process(), None), ("path",)),
    Case("load_model(None)", lambda: load_model(None), ("path",)),
    Case("simulate_experiment('system', np.ones(6), 3)",
         lambda: sim.simulate_experiment("system", np.ones(6), 3), ("system",)),
    Case("perturb_parameters({'k1': inf}, 0.1)",
         lambda: sim.perturb_parameters({"k1": INF}, 0.1), ("nominal",)),
    Case("downsample('abc', 2)", lambda: sim.downsample("abc", 2), ("y",)),
    Case("multisine(8, random_state=-1)", lambda: sim.multisine(8, random_state=-1),
         ("random_state",)),
    Case("DiscreteSystem('abc', [1.0], [1.0], 0.0, 0.1)",
         lambda: sim.DiscreteSystem("abc", [1.0], [1.0], 0.0, 0.1), ("A",)),
)


@pytest.mark.parametrize("case", MINIMAL_REPRODUCERS, ids=repr)
def test_minimal_reproducer_is_rejected(case):
    assert_rejected(case)


# ------------------------------------------------------------------ totals
# Keep this test last in the module: it reads what the generated tests above
# recorded while they ran.
def test_generated_tests_checked_at_least_1000_examples():
    missing = sorted(set(BUDGET) - set(RAN))
    if missing:
        pytest.skip(f"needs every generated test in this session; not run: {missing}")
    short = {key: (RAN[key], BUDGET[key]) for key in BUDGET if RAN[key] < BUDGET[key]}
    assert not short, f"examples checked below budget (ran, budget): {short}"
    assert sum(RAN.values()) >= MIN_TOTAL_EXAMPLES, RAN


def test_a_noise_kernel_of_several_dimensions_is_named():
    from sklearn.gaussian_process.kernels import RBF

    u = np.random.default_rng(0).standard_normal(90)
    with pytest.raises(ValueError, match="^noise_kernel must act on one dimension") as error:
        FIRGaussianProcess(order=10, factor=3, noise_kernel=RBF([1.0, 2.0])).fit(u, u[::3])
    assert "length_scale=[1, 2]" in str(error.value)
