"""Every message speaks of the user's arguments; one answer per question; one rule for lists.

Regression tests of the cases of the third reliability round: a message
never names an internal (``y_true``, ``coef``, ``freqs``, an integer
overflow), ``impulse_response`` at the integer lags is ``coef_`` for every
kernel scikit-learn accepts, and a list is a list of records only when both
``u`` and ``y_slow`` are.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import RBF, DotProduct, Matern, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import IdentifiabilityError, inference, tuning
from gpmultirate.kernels import DC

RNG = np.random.default_rng(7)
U = RNG.standard_normal(120)
G = 0.8 ** np.arange(30)
Y = np.convolve(U, G)[:120][::3] + 0.01 * RNG.standard_normal(40)


def quiet_fit(model, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return model.fit(*args, **kwargs)


# ----------------------------------------------------------- one answer
KERNELS = {
    "white": lambda: WhiteKernel(),
    "DC + white": lambda: C(1.0) * DC() + WhiteKernel(1e-3),
    "white * RBF": lambda: WhiteKernel() * RBF(),
    "RBF": lambda: C(1.0) * RBF(3.0),
    "Matern": lambda: C(1.0) * Matern(3.0),
    "DotProduct": lambda: DotProduct(),
    "DC": lambda: C(1.0) * DC(),
}


@pytest.mark.parametrize("order", [30, 60], ids=["parameter space", "data space"])
@pytest.mark.parametrize("name", list(KERNELS))
def test_impulse_response_at_integer_lags_is_coef(name, order):
    model = quiet_fit(gm.FIRGaussianProcess(KERNELS[name](), factor=3, order=order), U, Y)
    np.testing.assert_allclose(model.impulse_response(), model.coef_, rtol=1e-9,
                               atol=1e-9 * np.abs(model.coef_).max())
    # the same through the covariance route, at lags given one by one
    mean, cov = model.impulse_response([0.0, 1.0, 2.0], return_cov=True)
    np.testing.assert_allclose(mean, model.coef_[:3], rtol=1e-9, atol=1e-12)
    _, std = model.impulse_response([0.0, 1.0, 2.0], return_std=True)
    np.testing.assert_allclose(std, np.sqrt(np.diag(cov)), rtol=1e-6)


def test_white_kernel_between_lags_is_its_prior():
    # a white prior over lag: g(0.5) is independent of g(0), g(1), ... and of the data
    model = quiet_fit(gm.FIRGaussianProcess(WhiteKernel(0.3), factor=3, order=30,
                                            optimizer=None, noise_level=1e-4), U, Y)
    assert model.coef_[0] == pytest.approx(1.0, abs=0.05)
    mean, std = model.impulse_response([0.5, 1.0], return_std=True)
    assert mean[0] == 0.0 and std[0] == pytest.approx(np.sqrt(0.3), rel=1e-12)
    assert mean[1] == pytest.approx(model.coef_[1], rel=1e-12)


# ---------------------------------------------------------- user's terms
@pytest.mark.parametrize("index", [1e20, 2.0**63, -1e20])
def test_sample_indices_out_of_range_before_any_cast(index):
    with pytest.raises(ValueError, match=r"^sample_indices must lie in 0\.\.119") as error:
        gm.FIRGaussianProcess(order=10).fit(U, [1.0, 2.0], sample_indices=[0, index])
    assert "-9223372036854775808" not in str(error.value)
    big = np.array([0, 2**64 - 1], dtype=np.uint64)
    with pytest.raises(ValueError, match=r"sample_indices must lie in 0\.\.119.*18446744073709551615"):
        gm.LeastSquaresFIR(order=1).fit(U, [1.0, 2.0], sample_indices=big)


@pytest.mark.parametrize("sample_time", [1e-320, 1e-310, 5e-309])
def test_sample_time_whose_rate_overflows_is_refused_by_name(sample_time):
    for model in (gm.FIRGaussianProcess(factor=3, order=10, sample_time=sample_time),
                  gm.LeastSquaresFIR(factor=3, order=10, sample_time=sample_time)):
        with pytest.raises(ValueError, match="^sample_time must be a sample time"):
            model.fit(U, Y)
    model = gm.LeastSquaresFIR(factor=3, order=10).fit(U, Y)
    with pytest.raises(ValueError, match="^sample_time"):
        model.frequency_response(sample_time=sample_time)
    assert np.all(np.isfinite(model.frequency_response(sample_time=1e-300).freqs))


@pytest.mark.parametrize("order", [None, 60])
@pytest.mark.parametrize("value", [1.0, 0.0, -3e5])
@pytest.mark.parametrize("noise_kernel", ["white", "auto"])
def test_constant_output_fits(order, value, noise_kernel):
    model = quiet_fit(gm.FIRGaussianProcess(factor=3, order=order, noise_kernel=noise_kernel),
                      U, np.full(40, value))
    assert np.all(np.isfinite(model.coef_))
    fitted, std = model.predict(U, return_std=True, include_noise=True)
    assert np.all(np.isfinite(fitted)) and np.all(np.isfinite(std))
    if model.noise_kernel_ == "white":
        # the model predicts the slow samples it was given, to within its noise level
        bound = 3 * np.sqrt(model.noise_level_) + 1e-9 * abs(value)
        assert np.max(np.abs(fitted[::3] - value)) <= bound
    else:  # "auto" may read a constant as a slow disturbance, never as noise of the system
        assert noise_kernel == "auto" and value != 0.0


def test_an_all_zero_input_is_refused_by_name():
    for model in (gm.FIRGaussianProcess(factor=3), gm.LeastSquaresFIR(factor=3, order=5)):
        with pytest.raises(ValueError, match="^u is zero at every sample"):
            model.fit(np.zeros(120), Y)
        two = np.column_stack([U, np.zeros(120)])
        with pytest.raises(ValueError, match=r"^u\[:, 1\] is zero at every sample"):
            model.fit(two, Y)
        with pytest.raises(ValueError, match=r"^u is zero at every sample"):
            model.fit([np.zeros(60), np.zeros(60)], [Y[:20], Y[20:]])


def test_an_impulse_is_not_called_zero_order_hold():
    impulse = np.r_[1.0, np.zeros(119)]
    with pytest.raises(IdentifiabilityError) as error:
        gm.LeastSquaresFIR(factor=3, order=10).fit(impulse, Y)
    assert "zero-order hold" not in str(error.value)
    held = np.repeat(RNG.standard_normal(40), 3)
    with pytest.raises(IdentifiabilityError, match="zero-order hold"):
        gm.LeastSquaresFIR(factor=3, order=10).fit(held, Y)


def test_a_prefit_that_finds_no_finite_evidence_leaves_the_start(monkeypatch):
    # every start of the prefit failing (an infinite objective, as data whose squares
    # overflow once gave) must not end in AttributeError on the failed optimizer
    from scipy.optimize import OptimizeResult

    op = gm.DownsampledConvolution(U, 3, 20)
    evidence = inference.LogEvidence(op, Y, C(1.0) * DC(), 1.0, (1e-3, 1e3))
    monkeypatch.setattr(tuning.optimize, "minimize",
                        lambda f, x0, **k: OptimizeResult(x=x0, fun=np.inf))
    theta = tuning.prefit_scale_and_noise(evidence)
    np.testing.assert_array_equal(theta, evidence.theta)


# ------------------------------------------------------------------ lists
def test_lists_are_arrays_unless_both_are_lists_of_arrays():
    u2 = RNG.standard_normal((120, 2))
    y2 = (np.convolve(u2[:, 0], G)[:120] - np.convolve(u2[:, 1], G)[:120])[::3]
    for make in (lambda: gm.FIRGaussianProcess(factor=3, order=10),
                 lambda: gm.LeastSquaresFIR(factor=3, order=10)):
        array = quiet_fit(make(), u2, y2)
        listed = quiet_fit(make(), u2.tolist(), y2)
        assert listed.coef_.shape == (2, 10)
        np.testing.assert_array_equal(listed.coef_, array.coef_)
        column = quiet_fit(make(), U, Y[:, None].tolist())
        np.testing.assert_array_equal(column.coef_, quiet_fit(make(), U, Y[:, None]).coef_)
        np.testing.assert_array_equal(column.coef_, quiet_fit(make(), U, Y).coef_)
        # both lists of arrays: records
        records = quiet_fit(make(), [U[:60], U[60:]], [Y[:20], Y[20:]])
        assert len(records.observation_.records) == 2
    with pytest.raises(ValueError, match="y_slow must be a list with one entry per record"):
        gm.FIRGaussianProcess(factor=3, order=10).fit([U[:60], U[60:]], Y)
