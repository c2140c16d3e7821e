"""Bands by FFT (gpmultirate.bands) against the dense row-by-row computation."""

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate import prediction
from gpmultirate.bands import convolution_variance, dft_bins, dft_variances
from gpmultirate.covariance.posteriors import GaussianCoefficients
from gpmultirate.responses import dft_matrix


def random_covariance(size, rng):
    root = rng.standard_normal((size, size)) / np.sqrt(size)
    return root @ root.T


def toeplitz_rows(u, order):
    n = u.shape[0]
    return np.array([[u[i - j] if i >= j else 0.0 for j in range(order)] for i in range(n)])


@pytest.mark.parametrize("n, order, n_inputs", [(50, 8, 1), (30, 45, 1), (40, 12, 2)])
def test_convolution_variance_equals_the_dense_diagonal(n, order, n_inputs):
    rng = np.random.default_rng(0)
    u = rng.standard_normal((n, n_inputs))
    cov = random_covariance(n_inputs * order, rng)
    T = np.hstack([toeplitz_rows(u[:, i], order) for i in range(n_inputs)])
    np.testing.assert_allclose(convolution_variance(u, cov), np.einsum("ij,jk,ik->i", T, cov, T),
                               rtol=1e-10, atol=1e-12)


def test_convolution_variance_in_blocks_of_columns(monkeypatch):
    import gpmultirate.bands as bands

    monkeypatch.setattr(bands, "_BLOCK_ENTRIES", 100)  # a few columns per block
    rng = np.random.default_rng(1)
    u, cov = rng.standard_normal((60, 1)), random_covariance(20, rng)
    T = toeplitz_rows(u[:, 0], 20)
    np.testing.assert_allclose(convolution_variance(u, cov), np.diag(T @ cov @ T.T), rtol=1e-10)


@pytest.mark.parametrize("order, length", [(10, 32), (50, 32), (64, 64), (7, 7)])
def test_dft_variances_equal_the_dense_pair_variances(order, length):
    rng = np.random.default_rng(2)
    mean, cov = rng.standard_normal(order), random_covariance(order, rng)
    freqs = np.fft.rfftfreq(length, 0.01)
    assert dft_bins(freqs, 0.01) == length
    E = dft_matrix(freqs, 0.01, order)
    # the dense computation: rows of the real and imaginary parts of E, K = cov and no data
    dense = GaussianCoefficients(mean, cov, np.zeros((1, order)))
    var_re, var_im, cov_re_im = dense.pair_variances(np.ascontiguousarray(E.real),
                                                     np.ascontiguousarray(E.imag))
    frf, *found = dft_variances(mean, cov, freqs.size, length)
    np.testing.assert_allclose(frf, E @ mean, atol=1e-10)
    for a, b in zip(found, (var_re, var_im, cov_re_im)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-10)


def test_dft_bins_recognizes_only_the_bins():
    assert dft_bins(np.fft.rfftfreq(1000, 0.001), 0.001) == 1000
    assert dft_bins(np.fft.rfftfreq(1000, 0.001)[:20], 0.001) == 1000
    assert dft_bins(np.geomspace(0.1, 400.0, 50), 0.001) is None
    assert dft_bins(np.r_[0.0, np.fft.rfftfreq(1000, 0.001)[2:]], 0.001) is None
    assert dft_bins(np.array([0.0, 0.3, 0.6]), 0.001) is None  # 1 / 0.0003 is no integer
    assert dft_bins(np.array([1.0]), 1.0) is None


@pytest.fixture(scope="module")
def long_model():
    rng = np.random.default_rng(3)
    u = rng.standard_normal(900)
    g = 0.97 ** np.arange(150) * np.sin(0.4 * np.arange(150))
    y = np.convolve(u, g)[:900] + 0.02 * rng.standard_normal(900)
    return gm.FIRGaussianProcess(order=150, factor=3, sample_time=0.01).fit(u, y[::3]), u


def test_predict_band_by_fft_equals_the_row_by_row_band(long_model, monkeypatch):
    model, u = long_model
    mean, std = model.predict(u[:400], return_std=True)
    monkeypatch.setattr(prediction, "_FFT_MIN_ORDER", 10**9)
    dense_mean, dense_std = model.predict(u[:400], return_std=True)
    np.testing.assert_allclose(mean, dense_mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(std, dense_std, rtol=1e-7)


def test_frequency_response_band_by_fft_equals_the_dense_band(long_model, monkeypatch):
    model, _ = long_model
    frf = model.frequency_response()
    monkeypatch.setattr(prediction, "_FFT_MIN_ORDER", 10**9)
    dense = model.frequency_response()
    np.testing.assert_allclose(frf.mean, dense.mean, atol=1e-10 * np.abs(dense.mean).max())
    for name in ("real_std", "imag_std", "magnitude_lower", "magnitude_upper"):
        np.testing.assert_allclose(getattr(frf, name), getattr(dense, name), rtol=1e-6,
                                   atol=1e-9 * np.abs(dense.mean).max())


@pytest.mark.parametrize("order", [1, 6, 40])
def test_frequency_variances_at_any_frequency_equal_the_dense_pair_variances(order):
    from gpmultirate.bands import frequency_variances

    rng = np.random.default_rng(4)
    mean, cov = rng.standard_normal(order), random_covariance(order, rng)
    freqs = np.r_[0.0, np.geomspace(0.01, 50.0, 37)]  # no DFT bins
    E = dft_matrix(freqs, 0.01, order)
    dense = GaussianCoefficients(mean, cov, np.zeros((1, order)))
    expected = dense.pair_variances(np.ascontiguousarray(E.real), np.ascontiguousarray(E.imag))
    frf, *found = frequency_variances(mean, cov, 2 * np.pi * 0.01 * freqs)
    np.testing.assert_allclose(frf, E @ mean, atol=1e-10)
    for a, b in zip(found, expected):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-10)


def test_frequency_response_band_at_log_frequencies_equals_the_dense_band(long_model,
                                                                          monkeypatch):
    model, _ = long_model
    freqs = np.geomspace(0.05, 49.0, 200)  # at 50 Hz (Nyquist) Im G = 0: no correlation
    frf = model.frequency_response(freqs)
    monkeypatch.setattr(prediction, "_FFT_MIN_ORDER", 10**9)
    dense = model.frequency_response(freqs)
    np.testing.assert_allclose(frf.mean, dense.mean, atol=1e-10 * np.abs(dense.mean).max())
    for name in ("real_std", "imag_std", "real_imag_corr", "magnitude_upper", "phase_lower"):
        np.testing.assert_allclose(getattr(frf, name), getattr(dense, name), rtol=1e-6,
                                   atol=1e-8)


def test_draws_through_a_cholesky_factor_have_the_covariance():
    from gpmultirate.covariance import posteriors

    rng = np.random.default_rng(5)
    size = posteriors.CHOLESKY_MIN_SIZE
    # a covariance as a posterior's: a smooth prior less what the data explain, singular-ish
    lags = np.arange(size)
    prior = 0.99 ** np.maximum.outer(lags, lags)
    Phi = rng.standard_normal((40, size))
    PhiK = Phi @ prior
    cov = prior - PhiK.T @ np.linalg.solve(PhiK @ Phi.T + 0.01 * np.eye(40), PhiK)
    root = posteriors._cholesky_root(cov)
    np.testing.assert_allclose(root @ root.T, cov, atol=1e-7 * np.max(np.diag(cov)))
    mean = rng.standard_normal(size)
    draws = posteriors.gaussian_samples(mean, cov, 4000, np.random.default_rng(6))
    # the variance of a few projections, Monte Carlo (2.2 % standard error; 5 of them)
    for a in (np.ones(size), lags / size, rng.standard_normal(size)):
        sample = a @ (draws - mean[:, None])
        assert np.var(sample) == pytest.approx(a @ cov @ a, rel=0.12)
    assert np.abs(draws.mean(axis=1) - mean).max() < 5 * np.sqrt(np.diag(cov).max() / 4000)


def test_small_draws_move_with_the_covariance_only_by_rounding():
    """Below the Cholesky size the root is ``V sqrt(L) V^T``: a seed's draws survive the last digits.

    The covariance has nearly equal eigenvalues, where ``eigh``'s vectors
    (and their signs) turn with a change in the 13th digit; draws built on
    the vectors themselves then differ by the size of the draws.
    """
    from gpmultirate.covariance import posteriors

    rng = np.random.default_rng(8)
    size = 40
    basis, _ = np.linalg.qr(rng.standard_normal((size, size)))
    values = np.r_[np.full(10, 1.0), np.full(10, 1.0 + 1e-12), np.linspace(0.1, 0.5, 20)]
    cov = (basis * values) @ basis.T
    nudge = rng.standard_normal((size, size)) * 1e-13
    nudged = cov + (nudge + nudge.T) / 2
    mean = np.zeros(size)
    a = posteriors.gaussian_samples(mean, cov, 5, np.random.default_rng(9))
    b = posteriors.gaussian_samples(mean, nudged, 5, np.random.default_rng(9))
    np.testing.assert_allclose(a, b, atol=1e-6)
    root = np.linalg.cholesky(cov)  # an independent root: the same covariance
    draws = posteriors.gaussian_samples(mean, cov, 20000, np.random.default_rng(10))
    np.testing.assert_allclose(np.cov(draws), root @ root.T, atol=0.05)


def test_cholesky_root_refuses_what_it_cannot_factor():
    from gpmultirate.covariance import posteriors

    assert posteriors._cholesky_root(np.zeros((3, 3))) is None
    assert posteriors._cholesky_root(-np.eye(3)) is None


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_the_posterior_covariance_is_kept_for_its_posterior_only(long_model):
    model, u = long_model
    posterior = gm.prediction.units.split(model.posterior_)[0]
    first = prediction._covariance(posterior)
    assert prediction._covariance(posterior) is first
    np.testing.assert_array_equal(first, posterior.covariance())
    other = gm.FIRGaussianProcess(order=150, factor=3, noise_kernel="white").fit(
        u, np.convolve(u, 0.5 ** np.arange(9))[:900:3])  # another posterior (no disturbance check)
    assert prediction._covariance(gm.prediction.units.split(other.posterior_)[0]) is not first
    assert len(prediction._COVARIANCES) == 1
