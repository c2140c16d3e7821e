"""Experiment design: predicted bands against independent computations.

* the predicted band against the posterior of the paper's equations with a
  brute-force regressor (eq. 8) and the DC kernel written out (eq. 17), mapped
  to the FRF by the DFT sum;
* against a fit with the same hyperparameters held fixed, in the user's units;
* against Monte Carlo: responses drawn from the prior, simulated, fitted with
  fixed hyperparameters, the spread of the error and the coverage of the truth;
* the criterion's gradient against central finite differences;
* the designed input, the confounded frequencies, the sampling comparison and
  the record length against their definitions; input validation; the command.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import design
from gpmultirate.design.criterion import BandCriterion
from gpmultirate.kernels import DC, PK
from hold_reference import lagrange_rows

ALPHA, BETA, SCALE = 0.8, 0.6, 2.0
KERNEL = C(SCALE) * DC(alpha=ALPHA, beta=BETA)
ORDER, N, FACTOR, NOISE = 24, 72, 3, 1e-2


def dc_matrix(lags):
    """eq. (17) written out: c alpha^((i+j)/2) beta^|i-j|."""
    i, j = np.meshgrid(lags, lags, indexing="ij")
    return SCALE * ALPHA ** ((i + j) / 2.0) * BETA ** np.abs(i - j)


def brute_regressor(u, instants, order, periodic=False):
    """eq. (8) by loops: Phi[m, i] = u[n_m - i] (zero before the record, or periodic)."""
    phi = np.zeros((len(instants), order))
    for m, n in enumerate(instants):
        for i in range(order):
            if periodic:
                phi[m, i] = u[(n - i) % len(u)]
            elif n - i >= 0:
                phi[m, i] = u[n - i]
    return phi


def dense_posterior_covariance(u, instants, order, noise):
    K = dc_matrix(np.arange(order))
    phi = brute_regressor(u, instants, order)
    Ky = phi @ K @ phi.T + noise * np.eye(len(instants))
    return K - K @ phi.T @ np.linalg.solve(Ky, phi @ K)


def frf_moments(sigma, freqs, sample_time):
    E = np.exp(-2j * np.pi * sample_time * np.outer(freqs, np.arange(sigma.shape[0])))
    var_re = np.einsum("fi,ij,fj->f", E.real, sigma, E.real)
    var_im = np.einsum("fi,ij,fj->f", E.imag, sigma, E.imag)
    cov = np.einsum("fi,ij,fj->f", E.real, sigma, E.imag)
    return var_re, var_im, cov


@pytest.fixture(scope="module")
def u():
    return np.random.default_rng(0).standard_normal(N)


# --------------------------------------------------------------- the predicted band
@pytest.mark.parametrize("offset", [0, 2, (0, 1)])
def test_predicted_band_is_the_dense_posterior_of_the_papers_equations(u, offset):
    offsets = np.atleast_1d(offset)
    instants = np.unique(np.concatenate([np.arange(o, N, FACTOR) for o in offsets]))
    sigma = dense_posterior_covariance(u, instants, ORDER, NOISE)
    freqs = np.linspace(0.0, 5.0, 37)  # on and off the DFT bins, up to the fast Nyquist
    var_re, var_im, cov = frf_moments(sigma, freqs, 0.1)
    frf = design.predicted_frequency_response(KERNEL, u, FACTOR, offset, noise_level=NOISE,
                                              freqs=freqs, order=ORDER, sample_time=0.1)
    np.testing.assert_allclose(frf.real_std, np.sqrt(var_re), rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(frf.imag_std, np.sqrt(var_im), rtol=1e-7, atol=1e-12)
    inside = (var_re > 1e-12) & (var_im > 1e-12)
    np.testing.assert_allclose(frf.real_imag_corr[inside],
                               cov[inside] / np.sqrt(var_re * var_im)[inside], atol=1e-7)
    assert np.all(frf.mean == 0)
    assert frf.slow_nyquist == pytest.approx(0.5 / (FACTOR * 0.1))
    # the readings at those instants, given as stamps in seconds, are the same experiment
    again = design.predicted_frequency_response(KERNEL, u, sample_times=instants * 0.1,
                                                noise_level=NOISE, freqs=freqs, order=ORDER,
                                                sample_time=0.1)
    np.testing.assert_allclose(again.real_std, frf.real_std, rtol=1e-9)


def test_predicted_impulse_response_is_the_dense_posterior_on_and_between_the_lags(u):
    instants = np.arange(0, N, FACTOR)
    phi = brute_regressor(u, instants, ORDER)
    lags = np.array([0.0, 0.5, 3.0, 7.25, 23.0])
    k_lags = dc_matrix(np.arange(ORDER))
    # between integer lags the hold's prior: Lagrange on the lags n - 5 .. n + 6 (zero
    # below 0) plus the bridge 0.1^2 sin(pi d)^2 k(n, n)
    grid = np.arange(ORDER + 8)
    W = lagrange_rows(lags, grid.shape[0])
    k_grid = dc_matrix(grid)
    cross = W @ k_grid[:, :ORDER]
    Ky = phi @ k_lags @ phi.T + NOISE * np.eye(len(instants))
    prior_var = np.diag(W @ k_grid @ W.T) + 0.1**2 * np.sin(np.pi * lags) ** 2 * (
        SCALE * ALPHA ** np.floor(lags))
    var = prior_var - np.einsum("ij,ji->i", cross @ phi.T, np.linalg.solve(Ky, phi @ cross.T))
    got_lags, std = design.predicted_impulse_response(KERNEL, u, FACTOR, noise_level=NOISE,
                                                      lags=lags, order=ORDER)
    np.testing.assert_array_equal(got_lags, lags)
    np.testing.assert_allclose(std, np.sqrt(var), rtol=1e-7)


def test_predicted_band_is_the_band_of_a_fit_with_fixed_hyperparameters_in_the_users_units(u):
    # a pilot fit in large units; the design of a new input in the same units
    rng = np.random.default_rng(1)
    g = 0.85 ** np.arange(ORDER) * np.sin(0.7 * np.arange(ORDER))
    y = 1e3 * (np.convolve(u, g)[:N][::FACTOR] + 0.01 * rng.standard_normal(N // FACTOR))
    pilot = gm.FIRGaussianProcess(C(1.0) * DC(), factor=FACTOR, order=ORDER,
                                  sample_time=0.01).fit(u * 1e-2, y)
    new_u = 1e-2 * rng.standard_normal(N)
    frf = design.predicted_frequency_response(pilot, new_u, FACTOR, level=0.9)
    fixed = gm.FIRGaussianProcess(pilot.kernel_, factor=FACTOR, order=ORDER,
                                  noise_level=pilot.noise_level_, optimizer=None,
                                  sample_time=0.01)
    for output in (rng.standard_normal(N // FACTOR), 1e6 * rng.standard_normal(N // FACTOR)):
        fitted = fixed.fit(new_u, output).frequency_response(level=0.9)
        np.testing.assert_allclose(frf.freqs, fitted.freqs)
        np.testing.assert_allclose(frf.real_std, fitted.real_std, rtol=1e-6)
        np.testing.assert_allclose(frf.imag_std, fitted.imag_std, rtol=1e-6, atol=1e-12)
    lags, std = design.predicted_impulse_response(pilot, new_u, FACTOR, lags=[0.0, 2.5])
    np.testing.assert_allclose(std, fixed.impulse_response(lags, return_std=True)[1], rtol=1e-6)


def test_readings_between_the_ticks_with_exposure_are_those_of_the_fit(u):
    times = np.arange(0, N, FACTOR) + 0.4
    frf = design.predicted_frequency_response(KERNEL, u, sample_times=times, exposure=0.7,
                                              noise_level=NOISE, order=ORDER)
    fixed = gm.FIRGaussianProcess(KERNEL, order=ORDER, noise_level=NOISE, optimizer=None,
                                  exposure=0.7, between_ticks="exact")
    fitted = fixed.fit(u, np.ones(times.shape[0]), sample_times=times).frequency_response()
    np.testing.assert_allclose(frf.real_std, fitted.real_std, rtol=1e-6)
    # and exposure changes the band: the readings average the output
    plain = design.predicted_frequency_response(KERNEL, u, sample_times=times,
                                                noise_level=NOISE, order=ORDER)
    assert not np.allclose(plain.real_std, frf.real_std, rtol=1e-3)


def test_a_disturbance_model_enters_the_band_as_the_dense_noise_covariance(u):
    # white noise plus gamma * exp(-|t - s| / 10) over the instants (make_noise's Matern 1/2)
    prior = design.DesignPrior(KERNEL, ORDER, NOISE, noise_kernel="matern12")
    instants = np.arange(0, N, FACTOR)
    K = dc_matrix(np.arange(ORDER))
    phi = brute_regressor(u, instants, ORDER)
    R = NOISE * (np.eye(len(instants)) + np.exp(-np.abs(np.subtract.outer(instants,
                                                                           instants)) / 10.0))
    sigma = K - K @ phi.T @ np.linalg.solve(phi @ K @ phi.T + R, phi @ K)
    freqs = np.linspace(0.0, 0.5, 9)
    var_re, _, _ = frf_moments(sigma, freqs, 1.0)
    frf = design.predicted_frequency_response(prior, u, FACTOR, freqs=freqs)
    np.testing.assert_allclose(frf.real_std, np.sqrt(var_re), rtol=1e-7)
    white = design.predicted_frequency_response(KERNEL, u, FACTOR, freqs=freqs, order=ORDER,
                                                noise_level=NOISE)
    assert np.all(frf.real_std >= white.real_std - 1e-12)


@pytest.mark.slow
def test_predicted_band_matches_monte_carlo_of_the_posterior():
    # responses drawn from the prior, simulated, fitted with the hyperparameters held fixed:
    # the error's spread is the predicted one and the ellipse covers the truth at its level
    rng = np.random.default_rng(2)
    u = rng.standard_normal(N)
    freqs = np.array([0.05, 0.13, 0.2, 0.27, 0.41, 0.5])  # cycles per sample, both sides of 1/6
    frf = design.predicted_frequency_response(KERNEL, u, FACTOR, noise_level=NOISE,
                                              freqs=freqs, order=ORDER)
    K = dc_matrix(np.arange(ORDER))
    root = np.linalg.cholesky(K + 1e-12 * np.eye(ORDER))
    phi = brute_regressor(u, np.arange(0, N, FACTOR), ORDER)
    E = np.exp(-2j * np.pi * np.outer(freqs, np.arange(ORDER)))
    model = gm.FIRGaussianProcess(KERNEL, factor=FACTOR, order=ORDER, noise_level=NOISE,
                                  optimizer=None)
    n_runs, errors = 400, []
    for _ in range(n_runs):
        g = root @ rng.standard_normal(ORDER)
        y = phi @ g + np.sqrt(NOISE) * rng.standard_normal(phi.shape[0])
        errors.append(E @ g - model.fit(u, y).frequency_response(freqs).mean)
    errors = np.array(errors)
    # sample standard deviations of 400 draws: within 10 % (about 3 standard errors)
    np.testing.assert_allclose(errors.real.std(axis=0), frf.real_std, rtol=0.1)
    np.testing.assert_allclose(errors.imag[:, 1:-1].std(axis=0), frf.imag_std[1:-1], rtol=0.1)
    # coverage of the 95 % ellipse
    cov = np.stack([[frf.real_std ** 2, frf.real_imag_corr * frf.real_std * frf.imag_std],
                    [frf.real_imag_corr * frf.real_std * frf.imag_std, frf.imag_std ** 2]])
    inside = []
    for k in range(1, len(freqs) - 1):
        z = np.stack([errors.real[:, k], errors.imag[:, k]])
        inside.append(np.einsum("in,ij,jn->n", z, np.linalg.inv(cov[:, :, k]), z) <= 5.991)
    assert 0.93 <= np.mean(inside) <= 0.97


# ------------------------------------------------------------ criterion and design
@pytest.mark.parametrize("criterion", ["mean", "worst"])
@pytest.mark.parametrize("scheme", [design.SamplingScheme(FACTOR),
                                    design.SamplingScheme(FACTOR, offsets=(0, 2))])
def test_criterion_gradient_matches_finite_differences(criterion, scheme):
    kernel = KERNEL + PK(alpha=0.9, omega=2.0, sigma1=0.5, sigma2=0.5)
    prior = design.design_prior(kernel, order=ORDER, noise_level=NOISE)
    weights = np.linspace(1.0, 2.0, 15)
    objective = BandCriterion(prior, np.linspace(0.02, 0.5, 15), criterion, weights)
    u = np.random.default_rng(3).standard_normal(N)
    value, gradient = objective.value_and_gradient(u, scheme)
    assert value.value == pytest.approx(objective.value(u, scheme).value, rel=1e-10)
    step = 1e-5
    numeric = np.array([(objective.value(u + step * e, scheme).value
                         - objective.value(u - step * e, scheme).value) / (2 * step)
                        for e in np.eye(N)])
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())


def test_criterion_is_the_band_radius_of_the_predicted_response(u):
    prior = design.design_prior(KERNEL, order=ORDER, noise_level=NOISE)
    freqs = np.linspace(0.0, 0.5, 11)
    frf = design.predicted_frequency_response(prior, u, FACTOR, freqs=freqs)
    radius = np.sqrt(5.991464547107979 * (frf.real_std ** 2 + frf.imag_std ** 2) / 2)
    value = BandCriterion(prior, freqs, "worst").value(u, design.SamplingScheme(FACTOR))
    np.testing.assert_allclose(value.radius, radius, rtol=1e-9)
    assert value.worst == pytest.approx(radius.max())
    assert radius.mean() <= value.value <= radius.max()  # the smooth maximum


def test_designed_multisine_has_the_rms_its_spectrum_and_a_narrower_band():
    kernel = KERNEL + PK(alpha=0.92, omega=2.2, sigma1=1.0, sigma2=1.0)
    band = (0.1, 0.45)
    u, found = design.design_multisine(kernel, 90, FACTOR, band, rms=3.0, noise_level=NOISE,
                                       random_state=4, order=30, return_design=True)
    assert np.sqrt(np.mean(u ** 2)) == pytest.approx(3.0, rel=1e-12)
    n = np.arange(90)[:, None]
    rebuilt = (found.amplitudes * np.sqrt(2) * np.cos(
        2 * np.pi * found.freqs * n + found.phases)).sum(axis=1)
    np.testing.assert_allclose(rebuilt, u, atol=1e-10)
    assert np.all((found.freqs >= band[0]) & (found.freqs <= band[1]))
    # the flat reference: equal amplitudes on the same bins, the same rms
    spectrum = np.abs(np.fft.rfft(found.flat))
    excited = spectrum[spectrum > 1e-8 * spectrum.max()]
    np.testing.assert_allclose(excited, excited[0], rtol=1e-9)
    assert np.sqrt(np.mean(found.flat ** 2)) == pytest.approx(3.0)
    # the reported criteria are the predicted bands' radii, independently computed
    for signal, value in ((u, found.designed), (found.flat, found.reference)):
        frf = design.predicted_frequency_response(kernel, signal, FACTOR, noise_level=NOISE,
                                                  freqs=found.eval_freqs, order=30)
        assert value.mean == pytest.approx(design.band_radius(frf).mean(), rel=1e-9)
    assert found.narrowing > 1.2
    assert design.design_multisine(kernel, 90, FACTOR, band, rms=3.0, noise_level=NOISE,
                                   random_state=4, order=30).shape == (90,)


def test_worst_case_and_relative_designs_narrow_what_they_minimize():
    kernel = KERNEL + PK(alpha=0.92, omega=2.2, sigma1=1.0, sigma2=1.0)
    _, worst = design.design_multisine(kernel, 90, FACTOR, (0.05, 0.45), noise_level=NOISE,
                                       random_state=8, order=30, criterion="worst",
                                       return_design=True)
    assert worst.designed.worst < worst.reference.worst
    rng = np.random.default_rng(9)
    g = 0.85 ** np.arange(30) * np.sin(2.2 * np.arange(30))
    x = rng.standard_normal(90)
    pilot = gm.FIRGaussianProcess(kernel, factor=FACTOR, order=30, noise_level=NOISE,
                                  optimizer=None).fit(x, np.convolve(x, g)[:90][::FACTOR])
    _, relative = design.design_multisine(pilot, 90, FACTOR, (0.05, 0.45), random_state=8,
                                          relative=True, return_design=True)
    magnitude = np.abs(pilot.frequency_response(relative.eval_freqs).mean)
    frf = design.predicted_frequency_response(pilot, relative.u, FACTOR,
                                              freqs=relative.eval_freqs)
    assert relative.designed.mean == pytest.approx(
        np.mean(design.band_radius(frf) / magnitude), rel=1e-6)
    assert relative.designed.value <= relative.reference.value
    with pytest.raises(ValueError, match="pilot"):
        design.design_multisine(kernel, 90, FACTOR, (0.05, 0.45), order=30, relative=True)


@pytest.mark.parametrize("floor", [0.0, 0.5])
def test_power_shares_keep_the_rms_and_the_floor_and_pull_gradients_back(floor):
    from gpmultirate.design.multisine import PowerShares

    shares = PowerShares(rms=1.7, floor=floor, n_bins=6)
    x = np.random.default_rng(10).standard_normal(6)
    a = shares(x)
    assert np.linalg.norm(a) == pytest.approx(1.7)
    assert np.all(np.abs(a) >= floor * 1.7 / np.sqrt(6) - 1e-12)
    weights = np.random.default_rng(11).standard_normal(6)
    step = 1e-6
    numeric = [(weights @ shares(x + step * e) - weights @ shares(x - step * e)) / (2 * step)
               for e in np.eye(6)]
    np.testing.assert_allclose(shares.pullback(x, weights), numeric, atol=1e-8)


def test_the_floor_keeps_every_bin_excited():
    kernel = KERNEL + PK(alpha=0.92, omega=2.2, sigma1=1.0, sigma2=1.0)
    args = dict(order=30, noise_level=NOISE, random_state=4, return_design=True)
    _, free = design.design_multisine(kernel, 90, FACTOR, (0.1, 0.45), floor=0.0, **args)
    _, kept = design.design_multisine(kernel, 90, FACTOR, (0.1, 0.45), floor=0.6, **args)
    flat_amplitude = 1.0 / np.sqrt(kept.freqs.shape[0])
    assert kept.amplitudes.min() >= 0.6 * flat_amplitude - 1e-12
    assert free.designed.value <= kept.designed.value * (1 + 1e-6)  # the floor costs band
    with pytest.raises(ValueError, match="floor"):
        design.design_multisine(kernel, 90, FACTOR, (0.1, 0.45), floor=1.0, **args)


def test_confounded_frequencies_are_those_whose_slow_samples_coincide():
    n = np.arange(120)
    bins = [5, 15, 35, 45, 50]  # F = 4: 30 bins per slow period
    u = sum(np.cos(2 * np.pi * k * n / 120 + 0.3 * k) for k in bins)
    found = design.confounded_frequencies(u, 4, sample_time=0.5)
    np.testing.assert_allclose(found.freqs * 120 * 0.5, bins)
    # brute force: two frequencies are confounded when the slow samples of their
    # cosine and sine span the same plane
    def plane(k):
        phase = 2 * np.pi * k * n[::4] / 120
        return np.stack([np.cos(phase), np.sin(phase)])

    expected = []
    for a in bins:
        same = [b for b in bins if np.linalg.matrix_rank(np.vstack([plane(a), plane(b)]),
                                                         tol=1e-8) <= 2]
        if len(same) > 1 and same not in expected:
            expected.append(same)
    got = [sorted(np.round(g * 60).astype(int).tolist()) for g in found.groups]
    assert sorted(got) == sorted(expected) == [[5, 35], [15, 45]]
    assert found.confounded.tolist() == [True, True, True, True, False]
    assert design.alias_frequency(found.freqs, 4, 0.5) == pytest.approx(
        [5 / 60, 15 / 60, 5 / 60, 15 / 60, 10 / 60])


def test_sampling_comparison_ranks_schemes_by_their_bands(u):
    schemes = [design.SamplingScheme(FACTOR), design.SamplingScheme(FACTOR, offsets=(0, 1)),
               design.SamplingScheme(FACTOR, jitter=0.4, random_state=1),
               design.SamplingScheme(FACTOR, exposure=1.0, name="exposed")]
    found = design.compare_sampling(KERNEL, u, schemes, band_hz=(0.0, 0.5), noise_level=NOISE,
                                    order=ORDER)
    assert found.n_readings.tolist() == [24, 48, 24, 24]
    for scheme, frf, mean in zip(schemes, found.frequency_responses, found.mean_radius):
        again = design.predicted_frequency_response(KERNEL, u, noise_level=NOISE, order=ORDER,
                                                    scheme=scheme, freqs=frf.freqs)
        assert mean == pytest.approx(design.band_radius(again).mean(), rel=1e-9)
    assert found.best is schemes[int(np.argmin(found.mean_radius))]
    assert found.mean_radius[1] < found.mean_radius[0]  # twice the readings
    assert "exposed" in found.table()


def test_required_length_is_the_shortest_that_meets_the_target():
    prior = design.design_prior(KERNEL, order=ORDER, noise_level=NOISE)
    answer = design.required_length(prior, 0.15, (0.05, 0.45), FACTOR, n_draws=4,
                                    random_state=5, resolution=0.0)
    assert answer.n_samples % FACTOR == 0 and answer.n_samples >= ORDER
    assert answer.achieved <= 0.15
    shorter = [n for n, value in answer.tried.items() if n < answer.n_samples]
    if shorter:
        # every shorter length tried misses; the one just below was tried
        assert all(answer.tried[n] > 0.15 for n in shorter)
        assert max(shorter) == answer.n_samples - FACTOR
    # independently: the same flat inputs at that length meet the target
    seeds = np.random.RandomState(5).randint(0, 2**31 - 1, size=4)
    freqs = np.linspace(0.05, 0.45, 101)
    values = [design.band_radius(design.predicted_frequency_response(
        prior, design.flat_multisine(answer.n_samples, (0.05, 0.45), random_state=s),
        FACTOR, freqs=freqs)).mean() for s in seeds]
    t = 2.3533634348018264  # Student's t, 3 degrees of freedom, 0.95
    bound = np.mean(values) + t * np.std(values, ddof=1) * np.sqrt(1 + 1 / 4)
    assert bound == pytest.approx(answer.achieved, rel=1e-9)


# --------------------------------------------------------------------- validation
@pytest.mark.parametrize("call, name", [
    (lambda u: design.predicted_frequency_response(KERNEL, u, FACTOR), "order"),
    (lambda u: design.predicted_frequency_response(KERNEL, u[:10], FACTOR, order=ORDER), "u"),
    (lambda u: design.predicted_frequency_response(KERNEL, u, 0, order=ORDER), "factor"),
    (lambda u: design.predicted_frequency_response(KERNEL, u, 3, 3, order=ORDER), "offsets"),
    (lambda u: design.predicted_frequency_response(KERNEL, u, order=ORDER, level=1.5), "level"),
    (lambda u: design.predicted_frequency_response(KERNEL, u, order=ORDER, noise_level=-1.0),
     "noise_level"),
    (lambda u: design.predicted_frequency_response(KERNEL, u, order=ORDER, freqs=[-1.0]),
     "freqs"),
    (lambda u: design.predicted_frequency_response("DC", u, order=ORDER), "prior"),
    (lambda u: design.design_multisine(KERNEL, N, band_hz=(0.4, 0.1), order=ORDER), "band_hz"),
    (lambda u: design.design_multisine(KERNEL, N, band_hz=(0.1, 0.4), rms=0.0, order=ORDER),
     "rms"),
    (lambda u: design.design_multisine(KERNEL, N, band_hz=(0.1, 0.4), order=ORDER,
                                       criterion="median"), "criterion"),
    (lambda u: design.design_multisine(KERNEL, 10, band_hz=(0.1, 0.4), order=ORDER),
     "n_samples"),
    (lambda u: design.required_length(KERNEL, -1.0, (0.1, 0.4), order=ORDER), "target"),
    (lambda u: design.required_length(KERNEL, 0.1, (0.1, 0.4), order=ORDER, input="prbs"),
     "input"),
    (lambda u: design.SamplingScheme(3, jitter=2.0), "jitter"),
    (lambda u: design.compare_sampling(KERNEL, u, [3], order=ORDER), "schemes"),
    (lambda u: design.confounded_frequencies(u, 0), "factor"),
])
def test_bad_input_is_refused_naming_the_argument(u, call, name):
    with pytest.raises(ValueError, match=name):
        call(u)


def test_the_callers_input_is_not_modified(u):
    frozen = u.copy()
    frozen.setflags(write=False)
    design.predicted_frequency_response(KERNEL, frozen, FACTOR, order=ORDER)
    design.compare_sampling(KERNEL, frozen, [design.SamplingScheme(FACTOR)], order=ORDER)
    np.testing.assert_array_equal(frozen, u)


# ------------------------------------------------------------------------ command
@pytest.mark.slow
def test_design_command_end_to_end(tmp_path, capsys):
    from gpmultirate.cli import main

    rng = np.random.default_rng(6)
    g = 0.8 ** np.arange(30) * np.cos(0.9 * np.arange(30))
    u = rng.standard_normal(90)
    y = np.convolve(u, g)[:90][::3] + 0.01 * rng.standard_normal(30)
    model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=30, sample_time=0.01).fit(u, y)
    gm.save_model(model, tmp_path / "model.npz")
    out = tmp_path / "design"
    status = main(["design", str(tmp_path / "model.npz"), "--band", "10", "45", "--out",
                   str(out), "--rms", "2", "--quiet"])
    assert status == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["input.csv", "bands.png", "summary.md", "summary.json"])
    table = np.genfromtxt(out / "input.csv", delimiter=",", names=True)
    assert table["u"].shape == (90,) and np.sqrt(np.mean(table["u"] ** 2)) == pytest.approx(2.0)
    summary = json.loads((out / "summary.json").read_text())
    # the summary's numbers are the predicted bands of the written input
    freqs = np.fft.rfftfreq(180, d=0.01)
    inside = (freqs >= 10) & (freqs <= 45)
    frf = design.predicted_frequency_response(model, table["u"], 3, freqs=freqs)
    assert summary["designed"]["mean_band_radius"] == pytest.approx(
        design.band_radius(frf)[inside].mean(), rel=1e-6)
    assert summary["narrowing_mean"] > 1.0
    assert "narrower" in capsys.readouterr().out
    assert (out / "bands.png").read_bytes().startswith(b"\x89PNG")
    # an existing result is kept unless --force; a bad band names its option
    with pytest.raises(SystemExit):
        main(["design", str(tmp_path / "model.npz"), "--band", "10", "45", "--out", str(out),
              "--quiet"])
    with pytest.raises(SystemExit):
        main(["design", str(tmp_path / "model.npz"), "--band", "45", "10", "--out",
              str(tmp_path / "other"), "--quiet"])
    assert "--band" in capsys.readouterr().err
    # a given input to compare with: its length is the record's, its band the "before"
    given = tmp_path / "given.csv"
    given.write_text("u\n" + "\n".join(f"{v:.17g}" for v in u) + "\n")
    assert main(["design", str(tmp_path / "model.npz"), "--band", "10", "45", "--compare",
                 str(given), "--out", str(tmp_path / "compared"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "compared" / "summary.json").read_text())
    frf = design.predicted_frequency_response(model, u, 3, freqs=freqs)
    assert summary["before"]["mean_band_radius"] == pytest.approx(
        design.band_radius(frf)[inside].mean(), rel=1e-6)
    assert summary["before_input"] == "the given input"
    assert summary["rms"] == pytest.approx(np.sqrt(np.mean(u ** 2)))  # equal power


def test_stamps_and_exposure_are_in_the_units_of_the_pilots_sample_time():
    """A pilot fitted with sample_time T: its exposure (seconds) and the planned stamps
    (seconds) are read as fit reads them."""
    T, n = 0.01, 240
    rng = np.random.default_rng(3)
    u = rng.standard_normal(n)
    ticks = np.arange(1.5, n - 1, 3.0)
    pilot = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=30, sample_time=T,
                                  exposure=0.5 * T, optimizer=None, noise_level=1e-3)
    pilot.fit(u, np.zeros(ticks.size), sample_times=ticks * T)
    assert design.design_prior(pilot).exposure == pytest.approx(0.5)
    own = design.predicted_frequency_response(pilot, u, sample_times=ticks * T)
    given = design.predicted_frequency_response(pilot, u, sample_times=ticks * T,
                                                exposure=0.5 * T)
    none = design.predicted_frequency_response(pilot, u, sample_times=ticks * T, exposure=0.0)
    np.testing.assert_allclose(own.real_std, given.real_std, rtol=1e-12)
    assert np.max(np.abs(none.real_std - own.real_std)) > 1e-6
    with pytest.raises(ValueError, match="sample_times"):  # fast periods where seconds are due
        design.predicted_frequency_response(pilot, u, sample_times=ticks)
