"""Monte Carlo calibration: 95 % bands contain draws from the prior 95 % of the time.

Impulse responses are drawn from the prior jointly at the integer lags the data see
and at non-integer lags the data never see; slow data are simulated with the known
noise level; the model is conditioned with the true hyperparameters
(``optimizer=None``).  Coverage is counted for the impulse response at non-integer
lags, the 2-D credible region of the FRF (below and above the slow Nyquist frequency;
the magnitude band, its projection, covers at least as often) and the
fast-rate output between slow samples.  Under-dispersed bands (for example one
standard deviation instead of 1.96) give about 68 % and fail.
"""

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.kernels import DC, PK

pytestmark = pytest.mark.slow

N, FACTOR, ORDER, NOISE = 90, 3, 40, 0.05
RUNS = 400
OFF_GRID = np.array([0.5, 2.25, 6.7, 13.5])
FREQS = np.array([0.05, 0.15, 0.25, 0.4])  # slow Nyquist is 1/6 for T = 1
LEVEL = 0.95


@pytest.fixture(scope="module")
def coverage():
    kernel = C(1.0) * DC(alpha=0.9, beta=0.8) + PK(alpha=0.93, omega=1.9, sigma1=0.7, sigma2=0.7)
    rng = np.random.default_rng(2024)
    lags = np.concatenate([np.arange(ORDER, dtype=float), OFF_GRID])
    prior = kernel(lags[:, None])
    values, vectors = np.linalg.eigh(prior)
    root = vectors * np.sqrt(np.clip(values, 0, None))
    hits = {"impulse": [], "frf": [], "frf magnitude": [], "intersample": []}
    z = 1.959963984540054
    between = np.array([n for n in range(N) if n % FACTOR != 0])
    E = np.exp(-2j * np.pi * np.outer(FREQS, np.arange(ORDER)))
    for _ in range(RUNS):
        g = root @ rng.standard_normal(lags.size)
        g_grid, g_off = g[:ORDER], g[ORDER:]
        u = rng.standard_normal(N)
        y_fast = np.convolve(u, g_grid)[:N]
        y_slow = y_fast[::FACTOR] + np.sqrt(NOISE) * rng.standard_normal(N // FACTOR)
        model = gm.FIRGaussianProcess(
            kernel, factor=FACTOR, order=ORDER, noise_level=NOISE, optimizer=None
        ).fit(u, y_slow)
        mean, std = model.impulse_response(OFF_GRID, return_std=True)
        hits["impulse"].extend(np.abs(g_off - mean) <= z * std)
        frf = model.frequency_response(FREQS, sample_time=1.0, level=LEVEL)
        true_frf = E @ g_grid
        d = true_frf - frf.mean
        var_r, var_i = frf.real_std ** 2, frf.imag_std ** 2
        cov = frf.real_imag_corr * frf.real_std * frf.imag_std
        distance = (var_i * d.real ** 2 - 2 * cov * d.real * d.imag + var_r * d.imag ** 2) / (
            var_r * var_i - cov ** 2)
        region = distance <= -2.0 * np.log(1.0 - LEVEL)  # chi-square, 2 degrees of freedom
        magnitude = np.abs(true_frf)
        in_band = (frf.magnitude_lower <= magnitude) & (magnitude <= frf.magnitude_upper)
        hits["frf"].extend(region)
        # the magnitude band is the projection of the region: it holds the truth
        # wherever the region does
        assert np.all(in_band[region])
        hits["frf magnitude"].extend(in_band)
        y_mean, y_std = model.predict(u, return_std=True)
        inside = np.abs(y_fast - y_mean) <= z * y_std
        hits["intersample"].extend(inside[between[::7]])
    return {key: float(np.mean(value)) for key, value in hits.items()}


@pytest.mark.parametrize("quantity", ["impulse", "frf", "intersample"])
def test_95_percent_bands_are_calibrated(coverage, quantity):
    assert 0.925 <= coverage[quantity] <= 0.975, coverage


def test_frf_magnitude_band_is_conservative(coverage):
    assert coverage["frf"] <= coverage["frf magnitude"] <= 1.0, coverage
