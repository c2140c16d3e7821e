"""LeastSquaresFIR against numpy.linalg.lstsq and the paper's Lemma 1 and 2."""

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate.simulation import zoh_input


def regressor(u, factor, order, offset=0):
    rows = range(offset, len(u), factor)
    return np.array([[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in rows])


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(2)
    u = rng.standard_normal(300)
    g = 0.8 ** np.arange(20) * np.sin(np.arange(20))
    y = np.convolve(u, g)[:300][2::3] + 0.05 * rng.standard_normal(100)
    return u, y, g


def test_matches_lstsq_and_residual_variance(data):
    u, y, _ = data
    model = gm.LeastSquaresFIR(factor=3, order=20, offset=2).fit(u, y)
    Phi = regressor(u, 3, 20, 2)
    coef, residual, *_ = np.linalg.lstsq(Phi, y, rcond=None)
    np.testing.assert_allclose(model.coef_, coef, rtol=1e-9, atol=1e-12)
    assert model.noise_variance_ == pytest.approx(residual[0] / (100 - 20))
    expected_cov = model.noise_variance_ * np.linalg.inv(Phi.T @ Phi)
    np.testing.assert_allclose(model.coef_covariance_, expected_cov, rtol=1e-7, atol=1e-12)


def test_predict_std_and_frf(data):
    u, y, _ = data
    model = gm.LeastSquaresFIR(factor=3, order=20, offset=2).fit(u, y)
    T = regressor(u[:50], 1, 20)
    mean, std = model.predict(u[:50], return_std=True)
    np.testing.assert_allclose(mean, T @ model.coef_)
    np.testing.assert_allclose(std, np.sqrt(np.diag(T @ model.coef_covariance_ @ T.T)), rtol=1e-7)
    frf = model.frequency_response([0.1, 0.4], sample_time=1.0)
    direct = [np.sum(model.coef_ * np.exp(-2j * np.pi * f * np.arange(20))) for f in (0.1, 0.4)]
    np.testing.assert_allclose(frf.mean, direct)


def test_order_at_least_m_is_lemma_1(data):
    u, y, _ = data
    with pytest.raises(gm.IdentifiabilityError, match="Lemma 1"):
        gm.LeastSquaresFIR(factor=3, order=100, offset=2).fit(u, y)
    with pytest.raises(ValueError, match="order=150"):
        gm.LeastSquaresFIR(factor=3, order=150, offset=2).fit(u, y)


def test_zero_order_hold_input_is_lemma_2():
    u = zoh_input(300, factor=3, random_state=0)
    y = np.convolve(u, 0.5 ** np.arange(10))[:300][::3]
    with pytest.raises(gm.IdentifiabilityError, match="zero-order hold"):
        gm.LeastSquaresFIR(factor=3, order=10).fit(u, y)
    # ... while the kernel estimator gives a unique answer (Theorem 1)
    model = gm.FIRGaussianProcess(factor=3, order=10).fit(u, y)
    assert np.all(np.isfinite(model.coef_))


def test_rank_deficient_non_zoh_input():
    u = np.zeros(90)
    u[0] = 1.0  # impulse: slow samples only see every third coefficient
    y = np.zeros(30)
    with pytest.raises(gm.IdentifiabilityError, match="rank"):
        gm.LeastSquaresFIR(factor=3, order=10).fit(u, y)


def test_factor_one_is_plain_fir_least_squares():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(200)
    g = 0.6 ** np.arange(8)
    model = gm.LeastSquaresFIR(order=8).fit(u, np.convolve(u, g)[:200])
    np.testing.assert_allclose(model.coef_, g, atol=1e-10)


@pytest.mark.parametrize(
    "params, name",
    [(dict(order=None), "order"), (dict(order=0), "order"), (dict(factor=0), "factor"),
     (dict(offset=5), "offset")],
)
def test_invalid_arguments(data, params, name):
    u, y, _ = data
    base = dict(factor=3, order=20, offset=2)
    base.update(params)
    with pytest.raises(ValueError, match=name):
        gm.LeastSquaresFIR(**base).fit(u, y)


def test_goodness_of_fit_formula_and_errors():
    y = np.array([1.0, 3.0, 2.0, 5.0])
    y_hat = np.array([1.5, 2.5, 2.0, 4.0])
    expected = 100 * (1 - np.sum((y - y_hat) ** 2) / np.sum((y - y.mean()) ** 2))
    assert gm.goodness_of_fit(y, y_hat) == pytest.approx(expected)
    assert gm.goodness_of_fit(y, y) == 100.0
    with pytest.raises(ValueError, match="y_true"):
        gm.goodness_of_fit(np.ones(3), np.ones(3))
    with pytest.raises(ValueError, match="y_pred"):
        gm.goodness_of_fit(y, y[:2])


def test_fit_percent_is_matlab_compare_fit():
    y = np.array([1.0, 3.0, 2.0, 5.0])
    y_hat = np.array([1.5, 2.5, 2.0, 4.0])
    # written out element by element, as MATLAB's compare documents it
    error = np.sqrt(sum((a - b) ** 2 for a, b in zip(y, y_hat)))
    spread = np.sqrt(sum((a - 2.75) ** 2 for a in y))
    assert gm.fit_percent(y, y_hat) == pytest.approx(100 * (1 - error / spread))
    assert gm.fit_percent(y, y) == 100.0
    assert gm.fit_percent(y, np.full(4, 2.75)) == pytest.approx(0.0)
    gof = gm.goodness_of_fit(y, y_hat)
    assert gm.fit_percent(y, y_hat) == pytest.approx(100 * (1 - np.sqrt(1 - gof / 100)))
    with pytest.raises(ValueError, match="y_true"):
        gm.fit_percent(np.ones(3), np.ones(3))
    with pytest.raises(ValueError, match="y_pred"):
        gm.fit_percent(y, y[:2])
