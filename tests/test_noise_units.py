"""A disturbance model in the data's units: exact under powers of two, and through a model file."""

import warnings

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import Matern, WhiteKernel

import gpmultirate as gm
from gpmultirate.units import scaled_noise_kernel


@pytest.fixture(scope="module")
def drifting():
    rng = np.random.default_rng(1)
    n = 300
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.8 ** np.arange(30))[:n]
    drift = np.zeros(n)
    steps = rng.standard_normal(n)
    for i in range(1, n):
        drift[i] = 0.95 * drift[i - 1] + 0.1 * steps[i]
    return u, (y + drift + 0.01 * rng.standard_normal(n))[::3]


def _fit(u, y_slow, **params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gm.FIRGaussianProcess(order=30, factor=3, **params).fit(u, y_slow)


def test_scaled_noise_kernel_multiplies_the_covariance():
    kernel = WhiteKernel(0.5, (1e-3, 1.0)) + C(2.0) * Matern(10.0, nu=1.5)
    X = np.arange(6.0)[:, None]
    np.testing.assert_allclose(scaled_noise_kernel(kernel, 8.0)(X), 8.0 * kernel(X), rtol=1e-14)
    assert scaled_noise_kernel(kernel, 8.0).k1.noise_level_bounds == (8e-3, 8.0)


def test_disturbance_fit_is_exact_under_a_power_of_two(drifting):
    u, y_slow = drifting
    plain = _fit(u, y_slow, noise_kernel="matern32")
    scaled = _fit(u, y_slow * 2.0**20, noise_kernel="matern32")
    assert not isinstance(plain.noise_kernel_, str)
    X = np.arange(8.0)[:, None]
    np.testing.assert_allclose(scaled.noise_kernel_(X), 2.0**40 * plain.noise_kernel_(X),
                               rtol=1e-12)
    mean, std = plain.predict(u, return_std=True, include_noise=True)
    mean2, std2 = scaled.predict(u, return_std=True, include_noise=True)
    np.testing.assert_allclose(mean2, 2.0**20 * mean, rtol=1e-12, atol=1e-12 * 2.0**20)
    np.testing.assert_allclose(std2, 2.0**20 * std, rtol=1e-12)


def test_disturbance_model_file_keeps_the_data_units(drifting, tmp_path):
    u, y_slow = drifting
    model = _fit(u, y_slow * 2.0**20, noise_kernel="matern32")
    gm.save_model(model, tmp_path / "model.npz")
    loaded = gm.load_model(tmp_path / "model.npz")
    X = np.arange(8.0)[:, None]
    np.testing.assert_allclose(loaded.noise_kernel_(X), model.noise_kernel_(X), rtol=1e-12)
    mean, std = model.predict(u, return_std=True, include_noise=True)
    mean2, std2 = loaded.predict(u, return_std=True, include_noise=True)
    np.testing.assert_allclose(mean2, mean, rtol=1e-10, atol=1e-10 * np.abs(mean).max())
    np.testing.assert_allclose(std2, std, rtol=1e-10)


def test_bound_warning_of_a_disturbance_names_the_data_units(drifting):
    from sklearn.exceptions import ConvergenceWarning

    u, y_slow = drifting
    scale = 1000.0
    power = np.mean((scale * y_slow) ** 2)
    # read in normalized units (the output over its RMS): far too small a
    # disturbance for the drift, so it ends on the bound
    hi = 1e-6
    kernel = WhiteKernel(1e-4) + C(0.5 * hi, (1e-3 * hi, hi)) * Matern(20.0, (1.0, 1e4), nu=1.5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = gm.FIRGaussianProcess(order=30, factor=3, noise_kernel=kernel).fit(
            u, scale * y_slow)
    messages = [str(w.message) for w in caught if issubclass(w.category, ConvergenceWarning)]
    named = [m for m in messages if "noise_kernel__k2__k1__constant_value" in m]
    assert named, messages
    assert f"upper bound {hi * power:.4g}" in named[0]
    assert model.noise_kernel_.k2.k1.constant_value == pytest.approx(hi * power, rel=1e-6)


@pytest.mark.parametrize("noise_kernel", [
    lambda: WhiteKernel() + C(1.0) * Matern(5.0, nu=1.5),
    lambda: WhiteKernel(1e-3, "fixed") + C(0.1, "fixed") * Matern(8.0, "fixed", nu=1.5),
])
def test_a_noise_kernel_is_read_in_normalized_units(drifting, noise_kernel):
    # the same data in three units: the same fit, the same normalized
    # hyperparameters (the data-unit ones over the output's power)
    u, y_slow = drifting
    rng = np.random.default_rng(5)
    u_val = rng.standard_normal(300)
    y_val = np.convolve(u_val, 0.8 ** np.arange(30))[:300]
    fits = {}
    for scale in (1e-6, 1.0, 1e6):
        model = gm.FIRGaussianProcess(order=30, factor=3, noise_kernel=noise_kernel()).fit(
            u, y_slow * scale)
        power = np.mean((y_slow * scale) ** 2)
        normalized = scaled_noise_kernel(model.noise_kernel_, 1.0 / power)
        fits[scale] = (model.score(u_val, y_val * scale), normalized.theta,
                       model.coef_ / scale)
    gof, theta, coef = fits[1.0]
    assert gof > 90.0
    for scale in (1e-6, 1e6):
        assert fits[scale][0] == pytest.approx(gof, abs=1e-8)
        np.testing.assert_allclose(fits[scale][1], theta, rtol=0, atol=1e-8)
        np.testing.assert_allclose(fits[scale][2], coef, rtol=1e-6, atol=1e-8)
