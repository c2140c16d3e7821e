"""The misspecification check: the innovations against a dense solve, their law under the
model by Monte Carlo, the warning on a misspecified fit and not on well-specified ones."""

import warnings

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern, WhiteKernel

import gpmultirate as gm
from gpmultirate import DownsampledConvolution
from gpmultirate.kernels import DC, TC
from gpmultirate.misspecification import check_fit, innovations
from gpmultirate.noise import KernelNoise, noise_instants
from gpmultirate.observations import convolution_matrix
from gpmultirate.report import noise_summary
from gpmultirate.simulation import DiscreteSystem


def _dense_covariance(u, factor, order, kernel, noise):
    """Phi K Phi^T + N from the convolution matrix and the kernel's own matrix."""
    Phi = convolution_matrix(u, order)[::factor]
    return Phi @ kernel(np.arange(order, dtype=float)[:, None]) @ Phi.T + noise


def test_innovations_are_the_whitened_data_of_the_dense_covariance():
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal(150), rng.standard_normal(50)
    kernel = C(0.7) * TC(alpha=0.85)
    observation = DownsampledConvolution(u, 3, 20)
    e = innovations(observation, y, kernel, 0.05)
    Ky = _dense_covariance(u, 3, 20, kernel, 0.05 * np.eye(50))
    # e^T e = y^T Ky^{-1} y, and L e = y with L lower triangular
    assert e @ e == pytest.approx(y @ np.linalg.solve(Ky, y), rel=1e-10)
    np.testing.assert_allclose(np.linalg.cholesky(Ky) @ e, y, rtol=1e-9, atol=1e-12)
    # with a disturbance model: its matrix is the noise
    noise = KernelNoise(WhiteKernel(0.01) + C(0.1) * Matern(12.0, nu=1.5), noise_instants(
        observation))
    e = innovations(observation, y, kernel, 0.01, noise)
    Ky = _dense_covariance(u, 3, 20, kernel, noise.matrix())
    assert e @ e == pytest.approx(y @ np.linalg.solve(Ky, y), rel=1e-10)


def test_a_data_space_fit_gives_its_innovations_from_its_own_factor():
    # the fit's posterior holds the factor of Ky: the same innovations without a second
    # covariance; in the data's units (a normalized fit) the same numbers
    rng = np.random.default_rng(4)
    u = 1e3 * rng.standard_normal(150)
    y = 1e-2 * np.convolve(u, 0.8 ** np.arange(20))[:150:3] + 0.1 * rng.standard_normal(50)
    model = gm.FIRGaussianProcess(factor=3, order=60).fit(u, y)
    observation, kernel = model.observation_, model.kernel_
    e = innovations(observation, y, kernel, model.noise_level_)
    Ky = _dense_covariance(u, 3, 60, kernel, model.noise_level_ * np.eye(50))
    assert e @ e == pytest.approx(y @ np.linalg.solve(Ky, y), rel=1e-8)
    np.testing.assert_allclose(model.posterior_.innovations(y), e, rtol=1e-7, atol=1e-9)
    assert model.posterior_.normalized.innovations(y) is not None  # another scale
    assert not np.allclose(model.posterior_.normalized.innovations(y), e)
    with_posterior = check_fit(observation, y, kernel, model.noise_level_,
                               posterior=model.posterior_)
    alone = check_fit(observation, y, kernel, model.noise_level_)
    assert with_posterior.ljung_box_p_value == pytest.approx(alone.ljung_box_p_value, rel=1e-6)
    assert with_posterior.variance_p_value == pytest.approx(alone.variance_p_value, rel=1e-6)
    # a posterior without that factor (a long record's parameter space) answers None
    long = gm.FIRGaussianProcess(factor=3, order=10).fit(u, y)
    assert long.posterior_.innovations(y) is None


def test_the_check_holds_its_level_on_data_drawn_from_the_model():
    """Monte Carlo: data drawn from the model (known hyperparameters) are flagged at about
    twice the level of each test (two tests), never far more."""
    rng = np.random.default_rng(1)
    u = rng.standard_normal(300)
    kernel = C(1.0) * TC(alpha=0.8)
    observation = DownsampledConvolution(u, 3, 30)
    L = np.linalg.cholesky(_dense_covariance(u, 3, 30, kernel, 0.01 * np.eye(100)))
    flagged = sum(not check_fit(observation, L @ rng.standard_normal(100), kernel, 0.01).trusted
                  for _ in range(400))
    # expected about 2e-3 * 400 = 0.8; P(more than 6) < 1e-4 under the binomial law
    assert flagged <= 6
    # and data drawn with the wrong noise level are flagged
    wrong = check_fit(observation, L @ rng.standard_normal(100) * 3.0, kernel, 0.01)
    assert "larger than the model says" in " ".join(wrong.reasons)


def test_a_noise_estimate_at_its_lower_bound_is_a_sign():
    rng = np.random.default_rng(2)
    observation = DownsampledConvolution(rng.standard_normal(300), 3, 30)
    kernel = C(1.0) * TC(alpha=0.8)
    y = observation.matvec(0.8 ** np.arange(30)) + 0.1 * rng.standard_normal(100)
    check = check_fit(observation, y, kernel, 1e-10, noise_bounds=(1e-10, 1e2))
    assert check.noise_at_bound and "lower bound" in check.reasons[-1]
    assert not check_fit(observation, y, kernel, 1e-2, noise_bounds=(1e-10, 1e2)).noise_at_bound


def _resonant_record(seed, snr_db=40.0):
    """A lightly damped two-mode system at 0.1 s, factor 3, N = 600, white noise."""
    rng = np.random.default_rng(seed)
    poles = [0.97 * np.exp(1j * 0.3), 0.95 * np.exp(1j * 1.6)]
    A = np.zeros((4, 4))
    for k, p in enumerate(poles):
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[p.real, -p.imag], [p.imag, p.real]]
    system = DiscreteSystem(A, np.array([[1.0], [0.0], [1.0], [0.0]]),
                            np.array([[0.0, 1.0, 0.0, 0.4]]), 0.0, 0.1)
    u = rng.standard_normal(600)
    y = system.simulate(u)
    return u, (y + rng.standard_normal(600) * np.sqrt(np.var(y) / 10 ** (snr_db / 10)))[::3]


def test_a_misspecified_fit_warns_once_and_names_what_to_try():
    u, y_slow = _resonant_record(0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=200,
                                      noise_kernel="white").fit(u, y_slow)
    raised = [w for w in caught if w.category is gm.MisspecificationWarning]
    assert len(raised) == 1
    message = str(raised[0].message)
    assert "may not hold their level" in message and "innovations are correlated" in message
    assert 'kernel="auto"' in message
    assert model.misspecification_ == message
    assert noise_summary(model)["misspecification"] == message


@pytest.mark.parametrize("seed", [0, 1])
def test_a_well_specified_fit_does_not_warn(seed):
    """A response drawn from the TC prior, white noise: the default fit is trusted."""
    rng = np.random.default_rng(seed)
    lags = np.arange(150)
    K = 0.85 ** np.maximum.outer(lags, lags)
    g = np.linalg.cholesky(K + 1e-12 * np.eye(150)) @ rng.standard_normal(150)
    u = rng.standard_normal(600)
    y = np.convolve(u, g)[:600]
    y_slow = (y + rng.standard_normal(600) * 0.01 * np.std(y))[::3]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = gm.FIRGaussianProcess(factor=3, order=150, noise_kernel="white").fit(u, y_slow)
    assert not [w for w in caught if w.category is gm.MisspecificationWarning]
    assert model.misspecification_ is None
    assert "misspecification" not in noise_summary(model)



def test_a_significant_but_small_correlation_is_not_a_sign():
    # the spectrum against its definition written out, and the gate: with 2,000
    # innovations an AR(1) of coefficient 0.1 is significant (Ljung-Box) but moves
    # the spectrum by about 1.2 at most, inside TRUSTED_RATIO; 0.5 does not
    from scipy import signal

    from gpmultirate.misspecification import (
        TRUSTED_RATIO, _autocorrelation, _ljung_box, innovation_spectrum,
    )

    r = np.array([0.3, -0.1, 0.05])
    w = np.linspace(0, np.pi, 7)
    written = 1 + 2 * (0.75 * 0.3 * np.cos(w) - 0.5 * 0.1 * np.cos(2 * w)
                       + 0.25 * 0.05 * np.cos(3 * w))
    np.testing.assert_allclose(innovation_spectrum(r, 7), written)
    low, high = TRUSTED_RATIO
    assert (1.96 / 2.326) ** 2 == pytest.approx(low, abs=0.005)
    assert (1.96 / 1.645) ** 2 == pytest.approx(high, abs=0.005)
    rng = np.random.default_rng(5)
    for pole, counts in ((0.1, False), (0.5, True)):
        e = signal.lfilter([1.0], [1.0, -pole], rng.standard_normal(2000))
        r = _autocorrelation(e / e.std(), 25)
        assert _ljung_box(r, e.size) < 1e-3
        check = gm.misspecification.check_fit(
            gm.DownsampledConvolution(np.zeros(2000), 1, 1), e / e.std(), C(1e-12, "fixed") * DC(),
            1.0)
        assert (not check.trusted) is counts, innovation_spectrum(r)
