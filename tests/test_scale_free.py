"""Every finite record in any units: the fit of ``u * a``, ``y_slow * b`` is the unit fit rescaled.

The estimators divide ``u`` (per input) and ``y_slow`` by exact powers of two
of their magnitude (:mod:`gpmultirate.units`), so for ``a`` and ``b`` powers
of two every result must be the unit-scale result times ``b / a`` bit for
bit, over the whole float range; for powers of ten (not exact in binary) the
tuning starts from the same normalized problem and the results agree to the
optimizer's tolerance.  The regression cases are those of the issue that
found units breaking past about ``1e150``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.exceptions import NumericalWarning
from gpmultirate.kernels import DC, PK, SS, TC
from gpmultirate.units import normalize

N, FACTOR, ORDER = 90, 3, 15
G = 0.8 ** np.arange(ORDER) * np.cos(0.6 * np.arange(ORDER))


def _data(n_inputs=1, noise=1e-2, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((N, n_inputs)) if n_inputs > 1 else rng.standard_normal(N)
    x = u if n_inputs > 1 else u[:, None]
    y = sum(np.convolve(x[:, k], (-1) ** k * G)[:N] for k in range(x.shape[1]))
    y_slow = y[::FACTOR] + noise * rng.standard_normal(N // FACTOR)
    return u, y_slow


ESTIMATORS = {
    "default": lambda: gm.FIRGaussianProcess(factor=FACTOR, order=ORDER),
    "C*DC": lambda: gm.FIRGaussianProcess(C(1.0) * DC(), factor=FACTOR, order=ORDER),
    "TC": lambda: gm.FIRGaussianProcess(C(1.0) * TC(), factor=FACTOR, order=ORDER),
    "SS": lambda: gm.FIRGaussianProcess(C(1.0) * SS(), factor=FACTOR, order=ORDER),
    "DC+PK": lambda: gm.FIRGaussianProcess(
        C(1.0) * DC() + PK.from_hz(0.1, sample_time=1.0), factor=FACTOR, order=ORDER),
    "least squares": lambda: gm.LeastSquaresFIR(factor=FACTOR, order=8),
}


def _quiet(function):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function()


def _fit(name, u, y):
    return _quiet(lambda: ESTIMATORS[name]().fit(u, y))


_REFERENCES = {}


def _reference(name, n_inputs=1):
    key = (name, n_inputs)
    if key not in _REFERENCES:
        u, y = _data(n_inputs)
        _REFERENCES[key] = (u, y, _fit(name, u, y))
    return _REFERENCES[key]


def assert_scaled_equal(actual, unit, exponent):
    """``actual == unit * 2**exponent`` bit for bit where that is a normal float; in the
    subnormal range, where a scaling rounds, to the last subnormal place."""
    desired = np.ldexp(unit, exponent)
    normal = np.abs(desired) >= np.finfo(float).tiny
    np.testing.assert_array_equal(actual[normal], desired[normal])
    assert np.all(np.abs(actual[~normal] - desired[~normal]) <= 2.0 ** -1074)


def assert_rescaled(name, i, j, n_inputs=1):
    """The fit of ``u 2**i``, ``y 2**j`` is the unit fit times ``2**(j - i)``, exactly."""
    u, y, ref = _reference(name, n_inputs)
    model = _fit(name, np.ldexp(u, i), np.ldexp(y, j))
    assert_scaled_equal(model.coef_, ref.coef_, j - i)
    mean, std = model.impulse_response(return_std=True)
    mean0, std0 = ref.impulse_response(return_std=True)
    assert_scaled_equal(mean, mean0, j - i)
    assert_scaled_equal(std, std0, j - i)
    assert np.all(np.isfinite(std)) and np.all(std > 0)
    prediction, band = model.predict(np.ldexp(u, i), return_std=True)
    prediction0, band0 = ref.predict(u, return_std=True)
    assert_scaled_equal(prediction, prediction0, j)
    assert_scaled_equal(band, band0, j)
    k = {} if n_inputs == 1 else {"input": 1}
    frf, frf0 = model.frequency_response(**k), ref.frequency_response(**k)
    assert_scaled_equal(frf.magnitude_upper, frf0.magnitude_upper, j - i)
    assert_scaled_equal(frf.real_std, frf0.real_std, j - i)
    np.testing.assert_allclose(frf.phase, frf0.phase, rtol=0, atol=1e-12)  # subnormal means
    draws = model.sample_impulse_responses(n_samples=3, random_state=0)
    draws0 = ref.sample_impulse_responses(n_samples=3, random_state=0)
    if isinstance(model, gm.FIRGaussianProcess) or abs(j - i) <= 60:
        # least squares keeps a moderate covariance in the data's units (as its model
        # files store it); LAPACK's eigendecomposition rescales a matrix beyond about
        # 1e+-146 internally, which may pick another eigenbasis of equal eigenvalues:
        # the same distribution, other draws
        assert_scaled_equal(draws, draws0, j - i)
    else:
        assert draws.shape == draws0.shape and np.all(np.isfinite(draws))
    if isinstance(model, gm.FIRGaussianProcess):
        M = ref.y_slow_.shape[0]
        # the Jacobian of y -> y 2**j: log p shifts by -M j log 2
        assert model.log_marginal_likelihood_value_ == pytest.approx(
            ref.log_marginal_likelihood_value_ - M * j * math.log(2.0), rel=1e-12, abs=1e-9)
        if model.hyperparameter_units_ == "data":
            assert model.noise_level_ == np.ldexp(ref.noise_level_, 2 * j)
            # the prior in the data's units: covariance times (2**(j - i))**2
            lags = np.linspace(0.0, ORDER - 1, 7)[:, None]
            if n_inputs > 1:
                lags = np.column_stack([np.arange(7) % n_inputs, lags[:, 0]])
            np.testing.assert_allclose(model.kernel_(lags),
                                       np.ldexp(ref.kernel_(lags), 2 * (j - i)), rtol=1e-12)
        # the evidence at the user's theta equals the fitted value
        theta = np.append(model.kernel_.theta, np.log(model.noise_level_)) if (
            model.hyperparameter_units_ == "data" and model.optimizer is not None) else None
        if theta is not None:
            assert model.log_marginal_likelihood(theta) == pytest.approx(
                model.log_marginal_likelihood_value_, rel=1e-10)
    elif abs(j) < 500:
        assert model.noise_variance_ == np.ldexp(ref.noise_variance_, 2 * j)


exponents = st.integers(-990, 990)
pairs = st.tuples(exponents, exponents).filter(lambda p: abs(p[1] - p[0]) <= 990)


@pytest.mark.parametrize("name", ["default", "DC+PK", "least squares"])
@settings(max_examples=3, deadline=None, derandomize=True)
@given(pair=pairs)
def test_any_power_of_two_units_rescale_exactly(name, pair):
    assert_rescaled(name, *pair)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(ESTIMATORS))
@settings(max_examples=25, deadline=None, derandomize=True)
@given(pair=pairs)
def test_any_power_of_two_units_rescale_exactly_many(name, pair):
    assert_rescaled(name, *pair)


@pytest.mark.parametrize("i, j", [(0, 0), (-900, 100), (700, -250), (3, 990)])
def test_two_inputs_rescale_exactly(i, j):
    assert_rescaled("default", i, j, n_inputs=2)
    assert_rescaled("least squares", i, j, n_inputs=2)


@settings(max_examples=3, deadline=None, derandomize=True)
@given(pair=pairs)
def test_several_outputs_rescale_exactly(pair):
    i, j = pair
    u, y = _data()
    y2 = np.column_stack([y, -2.0 * y + 0.01 * np.sin(np.arange(y.shape[0]))])
    fit = lambda u_, y_: _quiet(lambda: gm.MultiOutputFIR(  # noqa: E731
        gm.FIRGaussianProcess(factor=FACTOR, order=ORDER)).fit(u_, y_))
    ref, model = fit(u, y2), fit(np.ldexp(u, i), np.ldexp(y2, j))
    assert_scaled_equal(model.coef_, ref.coef_, j - i)
    assert_scaled_equal(model.predict(np.ldexp(u, i)), ref.predict(u), j)


@pytest.mark.parametrize("name", ["default", pytest.param("C*DC", marks=pytest.mark.slow),
                                  "least squares"])
@pytest.mark.parametrize("a, b", [(1.0, 1e200), (1.0, 1e-155), (1e150, 1.0), (1e300, 1.0),
                                  (1e-300, 1.0), (1.0, 1e-300), (1e-300, 1e-300), (1e300, 1e300)])
def test_issue_units(name, a, b):
    # powers of ten are not exact in binary: the normalized problems differ by a factor
    # in [0.5, 2], whose logarithm shifts the tuning coordinates; agreement to the tuning's
    # tolerance, and no error, NaN or infinity
    u, y, ref = _reference(name)
    model = _fit(name, u * a, y * b)
    ratio = b / a
    np.testing.assert_allclose(model.coef_ / ratio, ref.coef_, rtol=1e-6,
                               atol=1e-8 * np.abs(ref.coef_).max())
    _, std = model.impulse_response(return_std=True)
    _, std0 = ref.impulse_response(return_std=True)
    assert np.all(np.isfinite(std))
    np.testing.assert_allclose(std / ratio, std0, rtol=1e-4)
    _, band = model.predict(u * a, return_std=True)
    assert np.all(np.isfinite(band)) and np.all(band > 0)


@pytest.mark.parametrize("i, j", [(0, 0), (-400, 100), (300, -200), (5, 450)])
def test_given_hyperparameters_in_the_data_units_rescale_exactly(i, j):
    # without tuning the kernel and noise level are the user's, in the data's units:
    # the same prior in other units (amplitude 4**(j - i), noise 4**j) gives the same fit
    u, y = _data()

    def fit(amplitude, noise, u_, y_):
        return _quiet(lambda: gm.FIRGaussianProcess(
            C(amplitude, "fixed") * DC(0.8, 0.5), factor=FACTOR, order=ORDER,
            noise_level=noise, optimizer=None).fit(u_, y_))

    ref = fit(1.0, 1e-4, u, y)
    model = fit(np.ldexp(1.0, 2 * (j - i)), np.ldexp(1e-4, 2 * j), np.ldexp(u, i), np.ldexp(y, j))
    assert_scaled_equal(model.coef_, ref.coef_, j - i)
    _, std = model.impulse_response([3.0], return_std=True)
    _, std0 = ref.impulse_response([3.0], return_std=True)
    assert_scaled_equal(std, std0, j - i)
    # between the ticks the interpolation's sums of the normalized kernel round differently
    _, std = model.impulse_response([0.5], return_std=True)
    _, std0 = ref.impulse_response([0.5], return_std=True)
    np.testing.assert_allclose(std, np.ldexp(std0, j - i), rtol=1e-12)
    assert model.kernel_.k1.constant_value == np.ldexp(1.0, 2 * (j - i))
    assert model.noise_level_ == np.ldexp(1e-4, 2 * j)
    assert model.log_marginal_likelihood_value_ == pytest.approx(
        ref.log_marginal_likelihood_value_ - ref.y_slow_.shape[0] * j * math.log(2.0), rel=1e-12)


def test_least_squares_at_1e160_has_finite_noise_and_std():
    u, y = _data(noise=1e-9)
    model = gm.LeastSquaresFIR(factor=FACTOR, order=ORDER).fit(u, y * 1e160)
    ref = gm.LeastSquaresFIR(factor=FACTOR, order=ORDER).fit(u, y)
    assert np.isfinite(model.noise_variance_)
    assert model.noise_variance_ / 1e160 / 1e160 == pytest.approx(ref.noise_variance_, rel=1e-6)
    _, std = model.impulse_response(return_std=True)
    assert np.all(np.isfinite(std)) and np.all(std > 0)
    _, band = model.predict(u, return_std=True)
    assert np.all(np.isfinite(band))


def test_unrepresentable_hyperparameters_stay_normalized_and_say_so():
    u, y = _data()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = gm.FIRGaussianProcess(factor=FACTOR, order=ORDER).fit(u * 1e-300, y)
    assert any(issubclass(w.category, NumericalWarning) and "normalized units" in str(w.message)
               for w in caught)
    assert model.hyperparameter_units_ == "normalized"
    assert model.input_scale_[0] == 2.0 ** np.frexp(np.max(np.abs(u * 1e-300)))[1]
    assert np.isfinite(model.noise_level_) and np.all(np.isfinite(model.kernel_.theta))
    assert np.all(np.isfinite(model.coef_)) and np.abs(model.coef_).max() > 1e299


@pytest.mark.parametrize("argument", ["u", "y_slow"])
def test_subnormal_data_are_refused_by_name(argument):
    u, y = _data()
    data = {"u": u, "y_slow": y}
    data[argument] = data[argument] * 1e-310
    with pytest.raises(ValueError, match=f"^{argument} is subnormal"):
        gm.FIRGaussianProcess(factor=FACTOR, order=ORDER).fit(data["u"], data["y_slow"])
    with pytest.raises(ValueError, match=f"^{argument} is subnormal"):
        gm.LeastSquaresFIR(factor=FACTOR, order=8).fit(data["u"], data["y_slow"])


def test_normalize_is_exact_and_leaves_the_caller_alone():
    u, y = _data(n_inputs=2)
    u[:, 1] *= 1e-200
    y_in = y * 1e250
    u_copy, y_copy = u.copy(), y_in.copy()
    u_n, y_n, scale = normalize(u, y_in)
    np.testing.assert_array_equal(u, u_copy)
    np.testing.assert_array_equal(y_in, y_copy)
    for k in range(2):
        assert 0.5 <= np.abs(u_n[:, k]).max() < 1.0
        np.testing.assert_array_equal(np.ldexp(u_n[:, k], scale.input_exponents[k]), u[:, k])
    assert 0.5 <= np.abs(y_n).max() < 1.0
    np.testing.assert_array_equal(np.ldexp(y_n, scale.output_exponent), y_in)
