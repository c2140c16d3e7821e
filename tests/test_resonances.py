"""Resonances found from the data: ``kernel="auto"`` and :mod:`gpmultirate.resonances`."""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.base import clone
import pytest
from scipy import optimize, signal
from sklearn.gaussian_process.kernels import ConstantKernel as C
from threadpoolctl import threadpool_limits

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.inference import LogEvidence, log_marginal_likelihood
from gpmultirate.kernels import DC, PK, PerInputKernel
from gpmultirate.kernels.lag import resonance_summands
from gpmultirate.kernels.spread import conditioning_kernel
from gpmultirate.metrics import goodness_of_fit
from gpmultirate.kernels import observe
from gpmultirate.resonances import (
    EVIDENCE_THRESHOLD,
    Resonance,
    _ResonantModel,
    PERSISTENT_CYCLES,
    PERSISTENT_DAMPING,
    damping_ratio,
    persistent_aliases,
    resonance_scan,
    search_resonances,
)

T, FACTOR = 0.1, 3


def _paper_kernel(name, frequencies=()):
    a, b = np.exp(-0.5 * T), np.exp(-0.1 * T)
    kernel = C(1.0, (1e-12, 1e5)) * DC(alpha=a, beta=b)
    for f in frequencies:
        kernel = kernel + PK.from_hz(f, T, alpha=a)
    return kernel


def _experiment(system, n, rng, snr_db=None):
    u = sim.multisine(n, random_state=rng)
    u_val = sim.multisine(n, random_state=rng)
    snr = rng.uniform(40, 60) if snr_db is None else snr_db
    data = sim.simulate_experiment(system, u, FACTOR, snr_db=snr, random_state=rng)
    return u, data.y_slow, u_val, system.simulate(u_val)


def random_two_mass(rng, n=600):
    """A two-mass-spring-damper with one mode above the slow Nyquist frequency.

    Masses, stiffnesses and dampers are drawn at random until the faster
    mode lies between the slow Nyquist frequency and 90 % of the fast one,
    the slower above 0.1 Hz, and the response has decayed within ``n`` lags.
    """
    slow_nyquist, fast_nyquist = 0.5 / (FACTOR * T), 0.5 / T
    while True:
        params = dict(k1=rng.uniform(2, 200), k2=rng.uniform(2, 800), m1=rng.uniform(0.5, 2),
                      m2=rng.uniform(0.5, 2), d1=rng.uniform(0.05, 1.0), d2=rng.uniform(0.01, 0.3))
        A, B, Cm, D = sim.two_mass_spring_damper(**params)
        Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, Cm, D), T, method="zoh")
        system = sim.DiscreteSystem(Ad, Bd, Cd, Dd, T)
        f = system.natural_frequencies
        if (len(f) == 2 and 1.05 * slow_nyquist < f[1] < 0.9 * fast_nyquist and f[0] > 0.1
                and np.abs(system.poles).max() ** n < 1e-3):
            return system


def _fit(kernel, u, y, n, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gm.FIRGaussianProcess(kernel, factor=FACTOR, order=n, noise_level=1e-5,
                                     sample_time=T, **kwargs).fit(u, y)


def _gofs(system, n, seed, noise_kernel="auto"):
    """Validation GoF of DC, PK at the true frequencies and auto, and the auto model."""
    rng = np.random.default_rng(seed)
    u, y, u_val, y_val = _experiment(system, n, rng)
    out = {}
    for name, kernel in (("DC", _paper_kernel("DC")),
                         ("PK", _paper_kernel("PK", system.natural_frequencies)),
                         ("auto", "auto")):
        model = _fit(kernel, u, y, n, noise_kernel=noise_kernel)
        out[name] = goodness_of_fit(y_val, model.predict(u_val))
    return out, model


# ---------------------------------------------------------------- the parts
def _small_problem(seed=0, n=240, order=120):
    rng = np.random.default_rng(seed)
    op = gm.DownsampledConvolution(rng.standard_normal(n), factor=FACTOR, order=order)
    t = np.arange(order)
    g = 0.9**t + 0.97**t * np.sin(2.3 * t)
    y = op.matvec(g) + 0.01 * rng.standard_normal(op.n_outputs)
    return op, y


def test_scan_gain_is_the_dense_evidence_difference():
    op, y = _small_problem()
    kernel, noise = C(0.3) * DC(alpha=0.8, beta=0.9), 1e-3
    omegas, alphas, amplitudes = np.array([0.7, 2.3]), np.array([0.95, 0.99]), np.array([0.2, 1.0])
    gain, sigma, _, _ = resonance_scan(op, y, kernel, noise, omegas=omegas, alphas=alphas,
                                       amplitudes=amplitudes)
    base = log_marginal_likelihood(op, kernel, noise, y, False, True)
    for a, alpha in enumerate(alphas):
        for j, omega in enumerate(omegas):
            dense = [
                log_marginal_likelihood(
                    op, kernel + PK(alpha=alpha, omega=omega, sigma1=s, sigma2=s), noise, y,
                    False, True,
                ) - base
                for s in amplitudes
            ]
            assert gain[a, j] == pytest.approx(max(max(dense), 0.0), rel=1e-8, abs=1e-8)
            assert sigma[a, j] == amplitudes[int(np.argmax(dense))]
    # the default (FFT) grid gives the same gains as the dense products
    gain_fft, _, grid, _ = resonance_scan(op, y, kernel, noise)
    gain_dense, _, _, _ = resonance_scan(op, y, kernel, noise, omegas=grid)
    np.testing.assert_allclose(gain_fft, gain_dense, rtol=1e-9, atol=1e-9)
    assert grid.max() == pytest.approx(np.pi)
    best = grid[np.argmax(gain_fft.max(axis=0))]
    assert best == pytest.approx(2.3, abs=0.03)


def _check_joint_model(op, y):
    """The search's joint model of two PK terms on ``op``: its evidence against the dense
    one, its gradient against central differences; the paper's terms and the search's
    (``hold``: zero at lag 0, the mode's step response on the first cell)."""
    for hold in (False, True):
        _check_joint_terms(op, y, hold)


def _check_joint_terms(op, y, hold):
    evidence = LogEvidence(op, y, C(0.3) * DC(alpha=0.8, beta=0.9), 1e-3, (1e-8, 1.0))
    model = _ResonantModel(evidence)
    model.terms = [(0, PK(alpha=0.97, omega=2.2, sigma1=0.5, sigma2=0.8, hold=hold)),
                   (0, PK(alpha=0.9, omega=0.6, sigma1=0.1, sigma2=0.2, hold=hold))]
    x = model._pack() + 0.05
    value, grad = model._log_evidence(x, eval_gradient=True)
    step = 1e-6
    numeric = [(model._log_evidence(x + h) - model._log_evidence(x - h)) / (2 * step)
               for h in step * np.eye(x.size)]
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-5)
    # the Fisher information against 1/2 tr(K^-1 dK_i K^-1 dK_j), with dK_i central
    # differences of the dense data covariance of the model's kernel and noise
    value_f, grad_f, fisher = model._log_evidence(x, eval_gradient=True, eval_fisher=True)
    assert value_f == value
    np.testing.assert_array_equal(grad_f, grad)

    dense_fisher = dense_fisher_of(model, x)
    np.testing.assert_allclose(fisher, dense_fisher, rtol=1e-5,
                               atol=1e-6 * np.abs(dense_fisher).max())
    # and without terms: the diagonal parameters alone
    bare = model._copy()
    bare.terms = []
    fisher0 = bare._log_evidence(x[:2], eval_gradient=True, eval_fisher=True)[2]
    np.testing.assert_allclose(fisher0, dense_fisher_of(bare, x[:2]), rtol=1e-6)
    model._unpack(x)
    dense = log_marginal_likelihood(op, model.kernel(), model.noise_level, y, False, True)
    assert value == pytest.approx(dense, rel=1e-10)


def dense_fisher_of(model, x, step=1e-5):
    """``1/2 tr(K^-1 dK_i K^-1 dK_j)`` of ``model`` at ``x`` from its dense data covariance."""
    def covariance(z):
        copy = model._copy()
        copy._unpack(z)
        Ky = observe(copy.kernel(), model.evidence.data).covariance()
        return Ky + copy.noise_level * np.eye(Ky.shape[0])

    inverse = np.linalg.inv(covariance(x))
    dK = [(covariance(x + h) - covariance(x - h)) / (2 * step) for h in step * np.eye(x.size)]
    return np.array([[0.5 * np.sum((inverse @ a) * (inverse @ b).T) for b in dK] for a in dK])


def test_joint_model_evidence_and_gradient():
    _check_joint_model(*_small_problem(1))


def test_joint_model_of_readings_with_exposure_evidence_and_gradient():
    # readings at their own instants: the terms' bases through the readings' functionals,
    # rotated into the base kernel's eigenvectors
    rng = np.random.default_rng(4)
    u = rng.standard_normal(240)
    times = np.sort(rng.uniform(60.0, 239.0, 70))
    op = gm.TimedConvolution(u, times, order=60, exposure=0.7, latency=0.2)
    t = np.arange(60)
    fast = np.convolve(u, 0.9**t + 0.97**t * np.sin(2.3 * t))[:240]
    _check_joint_model(op, np.interp(times, np.arange(240), fast)
                       + 0.01 * rng.standard_normal(70))


def test_damping_ratio_of_a_sampled_continuous_mode():
    zeta, wn = 0.05, 2 * np.pi * 1.3
    s = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    z = np.exp(s * T)
    alpha = np.abs(z) ** 2  # the variance decays as |z|^(2t), alpha^(t/2) = |z|^t
    assert damping_ratio(alpha, np.angle(z)) == pytest.approx(zeta, rel=1e-12)


# ------------------------------------------------------------ the contract
@pytest.mark.parametrize("bad", [-1, 1.5, "2", True, None])
def test_bad_max_resonances(bad):
    op, y = _small_problem()
    with pytest.raises(ValueError, match="max_resonances"):
        search_resonances(op, y, C(1.0) * DC(), 1e-3, (1e-8, 1.0), max_resonances=bad)
    model = gm.FIRGaussianProcess("auto", factor=FACTOR, order=60, max_resonances=bad)
    with pytest.raises(ValueError, match="max_resonances"):
        model.fit(np.random.default_rng(0).standard_normal(120), np.ones(40))


def test_max_resonances_zero_is_the_default_dc_fit():
    rng = np.random.default_rng(3)
    u, y, _, _ = _experiment(sim.paper_system(T), 240, rng)
    auto = _fit("auto", u, y, 120, max_resonances=0)
    plain = _fit(None, u, y, 120)
    assert auto.resonances_ == []
    assert repr(auto.kernel_) == repr(plain.kernel_)
    np.testing.assert_allclose(auto.coef_, plain.coef_, rtol=1e-10, atol=1e-14)
    assert auto.log_marginal_likelihood_value_ == pytest.approx(
        plain.log_marginal_likelihood_value_, rel=1e-12
    )


def _single_mode(frequency_hz, zeta):
    wn = 2 * np.pi * frequency_hz
    A = np.array([[0.0, 1.0], [-wn**2, -2 * zeta * wn]])
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete(
        (A, np.array([[0.0], [wn**2]]), np.array([[1.0, 0.0]]), np.zeros((1, 1))), T, "zoh"
    )
    return sim.DiscreteSystem(Ad, Bd, Cd, Dd, T)


def test_mode_above_the_slow_nyquist_frequency_is_found():
    system = _single_mode(2.3, 0.02)  # slow Nyquist 1.67 Hz, fast 5 Hz
    rng = np.random.default_rng(0)
    u, y, u_val, y_val = _experiment(system, 300, rng, snr_db=40)
    model = _fit("auto", u, y, 300)
    assert len(model.resonances_) == 1
    found = model.resonances_[0]
    assert isinstance(found, Resonance)
    assert found.frequency_hz == pytest.approx(system.natural_frequencies[0], rel=0.02)
    assert found.damping == pytest.approx(0.02, abs=0.01)
    assert found.evidence_gain > EVIDENCE_THRESHOLD
    assert found.input == 0
    # the reported values are those of the fitted kernel's PK term
    term = model.kernel_.k2
    assert isinstance(term, PK)
    assert found.frequency_hz == pytest.approx(term.omega / (2 * np.pi * T), rel=1e-12)
    assert found.damping == pytest.approx(damping_ratio(term.alpha, term.omega), rel=1e-12)
    assert goodness_of_fit(y_val, model.predict(u_val)) > 99.9


def test_saved_and_loaded_models_keep_the_found_resonances(tmp_path):
    system = _single_mode(2.3, 0.02)
    u, y, u_val, _ = _experiment(system, 300, np.random.default_rng(1), snr_db=40)
    model = _fit("auto", u, y, 300)
    gm.save_model(model, tmp_path / "auto.npz")
    loaded = gm.load_model(tmp_path / "auto.npz")
    assert loaded.resonances_ == model.resonances_ and len(loaded.resonances_) == 1
    assert loaded.get_params()["kernel"] == "auto"
    np.testing.assert_array_equal(loaded.predict(u_val), model.predict(u_val))


def test_evidence_gain_is_the_evidence_without_the_term_refitted():
    """The gain against a dense refit of the scale and noise without the term."""
    system = _single_mode(2.3, 0.02)
    rng = np.random.default_rng(1)
    u, y, _, _ = _experiment(system, 240, rng, snr_db=40)
    model = _fit("auto", u, y, 240)
    (found,) = model.resonances_
    rest = model.kernel_.k1  # C * DC, tuned with the term
    op, z = model.observation_, model.y_slow_

    def negative(x):
        kernel = C(np.exp(x[0]), (1e-300, 1e300)) * rest
        value, grad = log_marginal_likelihood(op, kernel, np.exp(x[1]), z, True, True)
        return -value, -grad[[0, -1]]  # d/d log c is first, d/d log gamma last

    with threadpool_limits(limits=1, user_api="blas"):  # small matrices
        best = optimize.minimize(negative, [0.0, np.log(model.noise_level_)], jac=True,
                                 method="L-BFGS-B", options={"ftol": 1e-15, "gtol": 1e-9})
    # the gain is of the tuned term, before the prior is given its frequency's spread
    term = clone(model.kernel_.k2).set_params(omega_std=0.0, rate_std=0.0)
    tuned = log_marginal_likelihood(op, model.kernel_.k1 + term, model.noise_level_, z,
                                    False, True)
    expected = tuned + best.fun
    assert found.evidence_gain == pytest.approx(expected, rel=1e-4)
    assert model.kernel_.k2.omega_std > 0.0 and model.kernel_.k2.rate_std > 0.0


def test_long_record_and_missing_samples():
    """More slow samples than coefficients (the reduced evidence) and NaN samples."""
    system = _single_mode(2.3, 0.02)
    rng = np.random.default_rng(4)
    u = rng.standard_normal(1800)
    y = sim.simulate_experiment(system, u, FACTOR, snr_db=40, random_state=rng).y_slow
    y[::7] = np.nan
    model = _fit("auto", u, y, 150)
    assert model.observation_.n_outputs > 150  # the evidence is that of the reduction
    (found,) = model.resonances_
    assert found.frequency_hz == pytest.approx(system.natural_frequencies[0], rel=0.02)
    # the evidence is that of the kernel without the frequencies' spread (added after)
    assert model.log_marginal_likelihood_value_ == pytest.approx(
        log_marginal_likelihood(model.observation_, conditioning_kernel(model.kernel_),
                                model.noise_level_, model.y_slow_, False, True), rel=1e-9
    )
    assert model.log_marginal_likelihood_value_ != pytest.approx(
        log_marginal_likelihood(model.observation_, model.kernel_, model.noise_level_,
                                model.y_slow_, False, True), rel=1e-9
    )


@pytest.mark.parametrize("kind", ["first_order", "overdamped"])
def test_no_resonance_in_a_system_without_one(kind):
    if kind == "first_order":
        system = sim.DiscreteSystem([[0.95]], [1.0], [1.0], 0.0, T)
    else:
        system = sim.DiscreteSystem([[0.9, 1.0], [0.0, 0.97]], [0.0, 1.0], [1.0, 0.0], 0.0, T)
    for seed in range(2):
        rng = np.random.default_rng(seed)
        u, y, _, _ = _experiment(system, 300, rng)
        model = _fit("auto", u, y, 300)
        assert model.resonances_ == []
        assert not any(isinstance(p, PK) for p in model.kernel_.get_params().values())


@pytest.mark.slow
def test_several_inputs_get_their_own_resonances():
    rng = np.random.default_rng(2)
    n = 300
    u = np.column_stack([sim.multisine(n, random_state=rng) for _ in range(2)])
    resonant = _single_mode(2.3, 0.02)
    y_fast = 0.5 * 0.9 ** np.arange(n)
    y = np.convolve(u[:, 0], y_fast)[:n] + resonant.simulate(u[:, 1])
    y_slow = (y + 1e-3 * np.std(y) * rng.standard_normal(n))[::FACTOR]
    model = _fit("auto", u, y_slow, n)
    assert isinstance(model.kernel_, PerInputKernel)
    assert [r.input for r in model.resonances_] == [1]
    assert model.resonances_[0].frequency_hz == pytest.approx(
        resonant.natural_frequencies[0], rel=0.02
    )


def test_search_does_not_modify_its_inputs():
    op, y = _small_problem()
    y0 = y.copy()
    base = C(1.0) * DC()
    before = repr(base), base.theta.copy()
    search = search_resonances(op, y, base, 1e-3, (1e-8, 1.0), max_resonances=1)
    np.testing.assert_array_equal(y, y0)
    assert (repr(base), base.theta.tolist()) == (before[0], before[1].tolist())
    assert len(search.resonances) == 1
    assert search.log_marginal_likelihood == pytest.approx(
        log_marginal_likelihood(op, conditioning_kernel(search.kernel), search.noise_level, y,
                                False, True), rel=1e-9
    )


# ---------------------------------------------------------------- targets
@pytest.mark.slow
def test_paper_system_quick():
    scores, model = _gofs(sim.paper_system(T, perturbation=0.1, random_state=0), 300, 0)
    assert scores["auto"] > scores["DC"]
    assert scores["auto"] >= scores["PK"] - 0.05
    assert len(model.resonances_) == 2


@pytest.mark.slow
def test_targets_on_paper_systems():
    """Mean GoF of auto within 0.05 of PK at the true frequencies and above DC.

    (The same targets on random two-mass systems: the next test, which asks more.)
    """
    systems = [sim.paper_system(T, perturbation=0.1, random_state=s) for s in range(5)]
    # white-noise records, the three kernels with white noise: the search's targets (the
    # disturbance's choice after the search, 13 of this test's 36 s, has tests of its own)
    scores = [_gofs(system, 600, seed, noise_kernel="white")[0]
              for seed, system in enumerate(systems)]
    mean = {k: np.mean([s[k] for s in scores]) for k in ("DC", "PK", "auto")}
    assert mean["auto"] >= mean["PK"] - 0.05, mean
    assert mean["auto"] > mean["DC"], mean


@pytest.mark.slow
def test_random_two_mass_systems_fit_as_well_as_their_true_modes():
    # what the search is for: the validation fit of the true modes' kernel; the lower
    # mode (below the slow Nyquist frequency) is found at its frequency, the upper one
    # may be kept as a broad term where its damping is poorly pinned (seeds 200, 202:
    # 3.36 Hz at damping 0.21 for 3.22 Hz at 0.03, 99.9996 % against 99.99999 %)
    # (issue targets: within 0.05 points of it on average, never 0.5 below)
    gaps, over_dc = [], []
    for seed in range(4):
        system = random_two_mass(np.random.default_rng(200 + seed))
        gofs, model = _gofs(system, 600, seed)
        gaps.append(gofs["PK"] - gofs["auto"])
        over_dc.append(gofs["auto"] - gofs["DC"])
        assert gaps[-1] < 0.5 and over_dc[-1] >= -1e-6, (seed, gofs)
        found = [r.frequency_hz for r in model.resonances_]
        low = min(system.natural_frequencies)
        assert any(abs(f - low) < 0.03 * low for f in found), (seed, found)
    assert np.mean(gaps) < 0.05, gaps
    assert np.mean(over_dc) > 0.0, over_dc


def test_excitation_is_the_input_power_the_slow_samples_see():
    rng = np.random.default_rng(2)
    # low-pass input: (almost) no power above 0.25 pi rad/sample
    b, a = signal.butter(8, 0.25)
    u = signal.lfilter(b, a, rng.standard_normal(900))
    op = gm.DownsampledConvolution(u, 3, 120)
    omegas = np.linspace(0.05, np.pi, 60)
    e = gm.resonances.excitation(op.matrix, omegas)
    # against the definition written out with explicit sums
    t = np.arange(120)
    hann = np.sin(np.pi * (t + 0.5) / 120) ** 2
    direct = np.array([sum(np.dot(row, hann * np.cos(w * t)) ** 2
                           + np.dot(row, hann * np.sin(w * t)) ** 2
                           for row in op.matrix) for w in omegas])
    np.testing.assert_allclose(e, direct / direct.mean(), rtol=1e-10)
    assert np.all(e[omegas < 0.15 * np.pi] > 0.5) and np.all(e[omegas > 0.5 * np.pi] < 1e-3)


def test_no_resonance_is_searched_where_the_input_has_no_power():
    rng = np.random.default_rng(3)
    b, a = signal.butter(8, 0.25)
    u = signal.lfilter(b, a, rng.standard_normal(900))
    g = 0.9 ** np.arange(120)
    op = gm.DownsampledConvolution(u, 3, 120)
    # output noise with a strong component at 0.7 pi, where u has no power
    y = op.matvec(g) + 0.05 * rng.standard_normal(op.n_outputs) \
        + 0.5 * np.cos(0.7 * np.pi * 3 * np.arange(op.n_outputs))
    gain, _, omegas, _ = resonance_scan(op, y, C(1.0) * DC(), 0.01)
    unexcited = gm.resonances.excitation(op.matrix, omegas) < gm.resonances.MIN_EXCITATION
    assert unexcited.any() and np.all(gain[:, unexcited] == 0.0)
    assert np.all(omegas[unexcited] > 0.25 * np.pi)


# ------------------------------------------------------------ held-out check
def _held_out_mean_by_refits(op, y, kernel, noise, folds):
    """Each fold predicted by a GP conditioned on the other samples only (dense, no shortcut)."""
    Phi = op.matrix
    lags = np.arange(op.order, dtype=float)[:, None]
    K = Phi @ kernel(lags) @ Phi.T
    mean = np.empty_like(y)
    for B in folds:
        rest = np.setdiff1d(np.arange(y.shape[0]), B)
        Ky = K[np.ix_(rest, rest)] + noise * np.eye(rest.size)
        mean[B] = K[np.ix_(B, rest)] @ np.linalg.solve(Ky, y[rest])
    return mean


def test_held_out_check_drops_a_spurious_term_and_keeps_a_true_one():
    from gpmultirate.crossvalidation import contiguous_folds
    from gpmultirate.resonances import HELD_OUT_GAIN, held_out_resonances

    op, y = _small_problem()
    base = C(1.0) * DC(alpha=0.9, beta=0.9)
    true = PK(alpha=0.97, omega=2.3, sigma1=1.0, sigma2=1.0)
    spurious = PK(alpha=0.97, omega=1.1, sigma1=1.0, sigma2=1.0)
    noise = 1e-4
    check = held_out_resonances(op, y, base + true + spurious, noise, [0, 0], base, noise)
    assert check["kept_terms"] == [0] and check["dropped"] == 1
    # the fits are those of refits on the other folds, compared after the AR(4) filter that
    # whitens the base kernel's held-out residuals (fitted here by its normal equations)
    folds = contiguous_folds([op.n_outputs], 5)
    base_mean = _held_out_mean_by_refits(op, y, base, noise, folds)
    e = y - base_mean
    lagged = np.column_stack([e[3 - k : e.size - 1 - k] for k in range(4)])
    a = np.linalg.solve(lagged.T @ lagged, lagged.T @ e[4:])

    def whitened_fit(mean):
        def whiten(x):
            return x[4:] - np.column_stack([x[3 - k : x.size - 1 - k] for k in range(4)]) @ a
        return gm.fit_percent(whiten(y), whiten(mean))

    for name, candidate in (("base", base), ("kept", base + true), ("found", base + true + spurious)):
        expected = whitened_fit(_held_out_mean_by_refits(op, y, candidate, noise, folds))
        assert check[name] == pytest.approx(expected, abs=1e-6)
    assert check["kept"] > check["base"] + HELD_OUT_GAIN
    assert check["kernel"].k2.omega == 2.3
    # the gain needed is `margin` points, or a twentieth of the base kernel's held-out
    # error where that is less (here 1.3 and 1.8 points): the true term's 17.5 passes any
    # margin, the spurious term alone none
    assert 0.05 * (100 - check["base"]) < check["kept"] - check["base"]
    huge = held_out_resonances(op, y, base + true, noise, [0], base, noise, margin=1e3)
    assert huge["kept_terms"] == [0]
    none = held_out_resonances(op, y, base + spurious, noise, [0], base, noise)
    assert none["kept_terms"] == [] and none["kernel"] is base
    # more folds than slow samples: nothing to hold out, no check
    assert held_out_resonances(op, y, base + true, noise, [0], base, noise, n_folds=500) is None


def test_search_reports_the_held_out_check():
    op, y = _small_problem(n=210, order=90)
    found = search_resonances(op, y, C(1.0) * DC(), 1e-3, (1e-8, 1.0))
    assert [round(r.frequency_hz * 2 * np.pi, 1) for r in found.resonances] == [2.3]
    check = found.held_out
    assert check["dropped"] == 0 and check["kept"] == check["found"] > check["base"]


def test_tuning_budget_stops_early_without_a_warning():
    from gpmultirate import tuning

    rng = np.random.default_rng(3)
    op = gm.DownsampledConvolution(rng.standard_normal(1500), factor=FACTOR, order=300)
    y = op.matvec(0.9 ** np.arange(300)) + 0.01 * rng.standard_normal(op.n_outputs)
    evidence = LogEvidence(op, y, C(1.0) * DC(alpha=0.7, beta=0.5), 1e-2, (1e-8, 10.0))
    from sklearn.exceptions import ConvergenceWarning

    full = tuning.maximize(evidence)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        short = tuning.maximize(evidence, max_evaluations=4)
    assert short.nfev < full.nfev
    # what it returns is the evidence at its point, better than the start and at most the optimum
    assert -short.fun == pytest.approx(evidence(short.x), rel=1e-10)
    assert evidence(evidence.theta) < -short.fun <= -full.fun + 1e-6


@pytest.mark.slow
def test_resonances_that_only_follow_a_disturbance_are_dropped():
    """A smooth system under level steps: the search finds terms, the held-out check drops them.

    Without the check the terms (slow, nearly undamped) follow the steps through the
    input's history and the validation fit on a new record falls from about 90 % to 34 %.
    """
    rng = np.random.default_rng(0)
    n = 900
    u, u_val = (signal.lfilter([1], [1, -0.7], rng.standard_normal(n)) for _ in range(2))

    def system(x):
        return signal.lfilter([0.02, 0.02], [1, -1.8, 0.81], x)

    y0 = system(u)
    steps = np.repeat(rng.standard_normal(n // 100 + 1), 100)[:n]
    y = y0 + 0.5 * np.std(y0) * steps / np.std(steps) + 0.01 * np.std(y0) * rng.standard_normal(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = gm.FIRGaussianProcess(factor=FACTOR).fit(u, y[::FACTOR])
        auto = gm.FIRGaussianProcess("auto", factor=FACTOR).fit(u, y[::FACTOR])
    assert auto.resonances_ == []
    fits = [gm.fit_percent(system(u_val), m.predict(u_val)) for m in (plain, auto)]
    assert fits[1] >= fits[0] - 1.0 and fits[0] > 85.0


@pytest.mark.slow
def test_a_slow_rate_alias_of_a_found_mode_is_not_kept_on_the_robot_arm():
    # measured: at factor 3 the evidence adds a term at 0.206 cycles per sample,
    # 1/3 - 0.127, the slow-rate twin of the arm's mode at 0.127; with it the
    # validation fit was 88.6 % and the 95 % measurement band held 0.75 of the
    # validation samples, without it 89.6 % and 0.97
    from scipy import stats

    from gpmultirate.datasets import load_robot_arm
    from gpmultirate.holdout import holdout_split

    data = load_robot_arm()
    split = holdout_split(data.u, data.y, 3, center=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = gm.FIRGaussianProcess(factor=3, kernel="auto").fit(split.u_estimation,
                                                                  split.y_slow)
    found = [r.frequency_hz for r in model.resonances_]
    assert any(abs(f - 0.1267) < 0.002 for f in found), found
    assert not any(abs(f - (1 / 3 - 0.1267)) < 0.002 for f in found), found
    mean, std = model.predict(split.u, return_std=True, include_noise=True)
    n = split.n_estimation
    inside = np.abs(split.y_validation - split.y_mean - mean[n:]) <= stats.norm.ppf(0.975) * std[n:]
    # 342 validation samples: one is 0.003 (the binomial spread at 0.95 is 0.012); the held
    # terms with their frequencies' spread after conditioning leave 4 outside (0.988), in
    # the prior 6 (0.982), the paper's basis 9
    assert 0.92 <= np.mean(inside) <= 0.99
    assert split.evaluate(model).fit_percent > 89.0


def _pk_at(f, zeta):
    """A PK term at ``f`` cycles per sample of damping ratio ``zeta`` (pole radius by hand)."""
    omega = 2 * np.pi * f
    return PK(alpha=np.exp(-2 * zeta * omega / np.sqrt(1 - zeta**2)) , omega=omega)


def test_persistent_aliases_are_the_undamped_terms_whose_slow_image_is_near_dc():
    # 300 slow samples at factor 3: the resolution is 1/900 cycles per sample, so a
    # term is persistent within 16/900 = 0.0178 of 0, 1/3 (or 2/3 - f: none below pi)
    n_slow, band = 300, PERSISTENT_CYCLES / 900
    assert band == pytest.approx(0.01778, abs=1e-5)
    cases = [  # (frequency, damping ratio, persistent)
        (1 / 3 - 0.0093, 0.001, True),  # lures measured under drift: 0.324 ... 0.347
        (1 / 3 + 0.0137, 0.001, True),
        (0.011, 0.005, True),  # k = 0: a slow wandering term at the fast rate too
        (1 / 3 - 0.9 * band, 0.9 * PERSISTENT_DAMPING, True),
        (1 / 3 - 1.1 * band, 0.001, False),  # 19.8 cycles over the record
        (0.31, 0.005, False),
        (1 / 3 - 0.005, 1.1 * PERSISTENT_DAMPING, False),  # damped: not persistent
        (0.127, 0.001, False),
    ]
    terms = [(0, _pk_at(f, z)) for f, z, _ in cases]
    for (f, z, _), (_, term) in zip(cases, terms):  # the terms are what they claim
        assert term.omega / (2 * np.pi) == pytest.approx(f)
        assert damping_ratio(term.alpha, term.omega) == pytest.approx(z, rel=1e-6)
    expected = [i for i, (_, _, p) in enumerate(cases) if p]
    assert persistent_aliases(terms, 3, n_slow) == expected
    # a longer record resolves finer: the same lure, 0.0093 from 1/3, is 27.9 cycles
    # over 1,000 slow samples and is kept
    assert persistent_aliases(terms[:1], 3, 1000) == []
    # at the fast rate only k = 0 aliases to DC
    assert persistent_aliases([(0, _pk_at(0.004, 0.001)), (0, _pk_at(0.33, 0.001))], 1,
                              300) == [0]


@pytest.mark.slow
def test_a_drift_lure_near_the_slow_rate_alias_of_dc_is_dropped_a_mode_near_it_kept():
    """Smooth system plus drift: the evidence adds nearly undamped terms at ~1/3.

    Measured before the rule: three terms at 0.324-0.331 cycles per sample and a
    validation fit of 73.9 % against 96.2 % for the plain kernel.  A true lightly
    damped mode at 0.31 (21 cycles over the record from the alias) is kept.
    """
    n = 900

    def smooth(x):
        return signal.lfilter([0.02, 0.02], [1, -1.8, 0.81], x)

    rng = np.random.default_rng(2)  # the drift case of the measurement above
    u, u_val = (signal.lfilter([1], [1, -0.7], rng.standard_normal(n)) for _ in range(2))
    y0 = smooth(u)
    drift = np.cumsum(rng.standard_normal(n))
    drift -= np.linspace(drift[0], drift[-1], n)
    y = y0 + 0.5 * np.std(y0) * drift / np.std(drift) + 0.01 * np.std(y0) * rng.standard_normal(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = gm.FIRGaussianProcess(factor=FACTOR).fit(u, y[::FACTOR])
        auto = gm.FIRGaussianProcess("auto", factor=FACTOR).fit(u, y[::FACTOR])
    fits = [gm.fit_percent(smooth(u_val), m.predict(u_val)) for m in (plain, auto)]
    assert fits[1] >= fits[0] - 1.0 and fits[0] > 90.0, fits

    rng = np.random.default_rng(0)
    u, u_val = (signal.lfilter([1], [1, -0.7], rng.standard_normal(n)) for _ in range(2))
    f0, zeta = 0.31, 0.005
    radius, omega = np.exp(-zeta * 2 * np.pi * f0), 2 * np.pi * f0

    def system(x):
        return smooth(x) + signal.lfilter([0.05], [1, -2 * radius * np.cos(omega), radius**2], x)

    y0 = system(u)
    y = y0 + 0.01 * np.std(y0) * rng.standard_normal(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = gm.FIRGaussianProcess(factor=FACTOR).fit(u, y[::FACTOR])
        auto = gm.FIRGaussianProcess("auto", factor=FACTOR).fit(u, y[::FACTOR])
    found = [r.frequency_hz for r in auto.resonances_]
    assert any(abs(f - f0) < 0.002 for f in found), found
    fits = [gm.fit_percent(system(u_val), m.predict(u_val)) for m in (plain, auto)]
    # the mode kept leaves at most half the plain fit's error (measured 99.29 against 98.29;
    # 99.7 against 89.5 before the default order saw the mode's memory)
    assert 100.0 - fits[1] < 0.5 * (100.0 - fits[0]), fits


# ------------------------------------------------- aliases judged by the data's evidence
def _two_mode_response(modes, order):
    """Impulse response of a sum of damped sinusoids ``(f cycles/sample, zeta, gain)``."""
    t = np.arange(order, dtype=float)
    g = np.zeros(order)
    for f, zeta, gain in modes:
        omega = 2 * np.pi * f
        g += gain * np.exp(-zeta * omega * t) * np.sin(omega * t)
    return g


def _alias_case(u, seed=0, order=300, snr_db=50.0):
    """A mode at 0.07 cycles/sample and one at 1/3 - 0.0705, its slow-rate twin at factor 3."""
    rng = np.random.default_rng(seed)
    modes = [(0.07, 0.03, 1.0), (1 / 3 - 0.0705, 0.02, 0.4)]
    g = _two_mode_response(modes, order)
    y = np.convolve(u, g)[: u.size]
    y_slow = (y + np.std(y) * 10 ** (-snr_db / 20) * rng.standard_normal(u.size))[::FACTOR]
    return g, y_slow, modes


def _pk_oracle(modes):
    kernel = C(1.0) * DC(0.9, 0.9)
    for f, zeta, _ in modes:
        omega = 2 * np.pi * f
        kernel = kernel + PK(alpha=np.exp(-2 * zeta * omega), omega=omega * np.sqrt(1 - zeta**2),
                             alpha_bounds="fixed", omega_bounds="fixed")
    return kernel


@pytest.mark.slow
def test_a_mode_whose_slow_rate_alias_falls_on_another_is_kept_when_the_input_separates_them():
    rng = np.random.default_rng(5)
    n, order = 600, 300
    u, u_val = rng.standard_normal(n), rng.standard_normal(n)  # white: both frequencies seen
    g, y_slow, modes = _alias_case(u, order=order)
    # the upper mode's slow-rate image is within 0.0005 cycles/sample of the lower mode
    assert abs((1 / 3 - modes[1][0]) - modes[0][0]) < 1e-3
    y_val = np.convolve(u_val, g)[:n]
    fits = {}
    for name, kernel in (("auto", "auto"), ("oracle", _pk_oracle(modes))):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = gm.FIRGaussianProcess(kernel, factor=FACTOR, order=order).fit(u, y_slow)
        fits[name] = goodness_of_fit(y_val, model.predict(u_val))
        if name == "auto":
            found = sorted(r.frequency_hz for r in model.resonances_)
    assert len(found) == 2, found
    assert found[0] == pytest.approx(0.07, abs=2e-3)
    assert found[1] == pytest.approx(1 / 3 - 0.0705, abs=2e-3)
    assert fits["auto"] > fits["oracle"] - 0.1, fits


def test_a_twin_the_input_does_not_separate_is_dropped_by_the_held_out_check():
    """The same two terms on a record whose input has no power near the upper mode."""
    from gpmultirate.resonances import held_out_resonances

    rng = np.random.default_rng(6)
    n, order = 600, 300
    u = signal.lfilter(*signal.butter(6, 0.3), rng.standard_normal(n))  # nothing above 0.15
    t = np.arange(order, dtype=float)
    g = np.exp(-0.03 * 2 * np.pi * 0.07 * t) * np.sin(2 * np.pi * 0.07 * t)  # one mode only
    op = gm.DownsampledConvolution(u, factor=FACTOR, order=order)
    y = op.matvec(g) + 1e-3 * np.std(op.matvec(g)) * rng.standard_normal(op.n_outputs)
    base = C(0.01) * DC(0.9, 0.9)
    mode = PK(alpha=np.exp(-2 * 0.03 * 2 * np.pi * 0.07), omega=2 * np.pi * 0.07,
              sigma1=0.5, sigma2=0.5)
    twin = PK(alpha=0.98, omega=2 * np.pi * (1 / 3 - 0.0705), sigma1=0.5, sigma2=0.5)
    # the search itself keeps one term: the mode
    found = search_resonances(op, y, C(1.0) * DC(), 1e-4, (1e-10, 1.0))
    assert [round(r.frequency_hz, 2) for r in found.resonances] == [0.07]
    # given both, the held-out check re-tunes the mode alone, which predicts as well: the twin
    # goes; held at the values it had beside the twin, the mode is kept as well
    from gpmultirate.resonances import _Retuned

    retuned = _Retuned(
        LogEvidence(op, y, base + mode + twin, 1e-6, (1e-10, 1.0)), base + mode + twin, 1e-6,
        [(0, mode), (0, twin)])
    check = held_out_resonances(op, y, base + mode + twin, 1e-6, [0, 0], base, 1e-6,
                                refit=lambda subset: retuned(subset)[:2])
    assert check["kept_terms"] == [0]


def test_no_resonance_is_kept_in_a_first_order_system_on_white_input():
    rng = np.random.default_rng(7)
    u = rng.standard_normal(600)
    y = signal.lfilter([0.1], [1, -0.9], u)
    y_slow = (y + 0.01 * np.std(y) * rng.standard_normal(600))[::FACTOR]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        auto = gm.FIRGaussianProcess("auto", factor=FACTOR, order=200).fit(u, y_slow)
        plain = gm.FIRGaussianProcess(factor=FACTOR, order=200).fit(u, y_slow)
    assert auto.resonances_ == []
    # without a term the fit is the default's: the same kernel, the same coefficients
    assert repr(auto.kernel_) == repr(plain.kernel_)
    np.testing.assert_allclose(auto.coef_, plain.coef_, rtol=1e-6, atol=1e-10)


# ------------------------------------------------------- the spread of a frequency
def test_pk_spread_is_the_covariance_of_the_first_order_change_with_frequency_and_decay():
    from gpmultirate.kernels import observe

    w_std, r_std = 0.02, 0.01
    kernel = PK(alpha=0.9, omega=0.7, sigma1=1.3, sigma2=0.6, omega_std=w_std, rate_std=r_std)
    X = np.arange(15.0)[:, None]
    K, dK = kernel(X, eval_gradient=True)
    # by Monte Carlo: a ~ N(0, diag(sigma^2)), d omega, d r independent; g + dg/domega domega
    # + dg/dr dr, with dg/domega = t e (-a1 sin + a2 cos), dg/dr = -t g
    rng = np.random.default_rng(0)
    t, n = X[:, 0], 200_000
    e = 0.9 ** (t / 2)
    a = rng.standard_normal((n, 2)) * [1.3, 0.6]
    dw, dr = rng.standard_normal(n) * w_std, rng.standard_normal(n) * r_std
    c, s = e * np.cos(0.7 * t), e * np.sin(0.7 * t)
    g = a[:, :1] * c + a[:, 1:] * s
    draws = g + dw[:, None] * t * (-a[:, :1] * s + a[:, 1:] * c) - dr[:, None] * t * g
    np.testing.assert_allclose(K, draws.T @ draws / n, atol=0.03 * np.abs(K).max())
    np.testing.assert_allclose(kernel.diag(X), np.diag(K))
    # gradients by central differences of theta
    for j in range(kernel.theta.size):
        step = np.zeros_like(kernel.theta)
        step[j] = 1e-6
        numeric = (kernel.clone_with_theta(kernel.theta + step)(X)
                   - kernel.clone_with_theta(kernel.theta - step)(X)) / 2e-6
        np.testing.assert_allclose(dK[:, :, j], numeric, atol=1e-7)
    # the observed low-rank term and its evidence gradient against the dense form
    op = gm.DownsampledConvolution(rng.standard_normal(60), factor=2, order=15)
    term = observe(kernel, op)
    np.testing.assert_allclose(term.covariance(), op.matrix @ K @ op.matrix.T, atol=1e-10)
    y = rng.standard_normal(op.n_outputs)
    evidence = LogEvidence(op, y, kernel, 0.1, "fixed")
    value, grad = evidence(evidence.theta, eval_gradient=True)
    for j in range(evidence.theta.size):
        step = np.zeros_like(evidence.theta)
        step[j] = 1e-6
        numeric = (evidence(evidence.theta + step) - evidence(evidence.theta - step)) / 2e-6
        assert grad[j] == pytest.approx(numeric, rel=1e-5, abs=1e-7)
    # no spread: the rank-two kernel as before
    assert repr(PK(alpha=0.9, omega=0.7)) == "PK(alpha=0.9, omega=0.7, sigma1=1, sigma2=1)"
    with pytest.raises(ValueError, match="omega_std"):
        PK(omega_std=-1.0)(X)


def test_band_of_a_pk_term_with_its_frequency_spread_covers_by_monte_carlo():
    """Responses whose frequency is drawn around the PK term's: the 95 % band holds them.

    The spread is first order in the frequency: it holds while the data do not resolve
    the second-order change (here a phase error of up to 0.3 rad at 10 dB); with a spread
    the data would resolve better (noise 1e-4) it holds 0.52 (0.03 without it).
    """
    rng = np.random.default_rng(1)
    order, factor, omega0, w_std, alpha = 80, 3, 1.1, 0.004, 0.95
    op = gm.DownsampledConvolution(rng.standard_normal(300), factor=factor, order=order)
    Phi, t, noise = op.matrix, np.arange(order, dtype=float), 0.1

    def band_coverage(kernel, draws):
        K = kernel(t[:, None])
        gain = np.linalg.solve(Phi @ K @ Phi.T + noise * np.eye(Phi.shape[0]), Phi @ K).T
        std = np.sqrt(np.maximum(np.diag(K - gain @ Phi @ K), 0.0))
        inside = [np.abs(g - gain @ y) <= 1.96 * std for g, y in draws]
        return float(np.mean(inside))

    draws = []
    for _ in range(300):
        omega = omega0 + w_std * rng.standard_normal()
        a = rng.standard_normal(2)
        g = alpha ** (t / 2) * (a[0] * np.cos(omega * t) + a[1] * np.sin(omega * t))
        draws.append((g, Phi @ g + np.sqrt(noise) * rng.standard_normal(Phi.shape[0])))
    spread = band_coverage(PK(alpha=alpha, omega=omega0, omega_std=w_std), draws)
    exact = band_coverage(PK(alpha=alpha, omega=omega0), draws)
    assert 0.9 <= spread <= 0.99, spread  # measured 0.93
    assert exact < 0.6, exact  # measured 0.40


def test_excitation_on_the_scan_grid_is_the_dense_excitation():
    from gpmultirate.resonances import _excitation_on_grid, excitation

    rng = np.random.default_rng(3)
    Phi = gm.DownsampledConvolution(rng.standard_normal(400), factor=3, order=90).matrix
    n_fft = 256
    index = np.arange(1, n_fft + 1)
    index = index[index * 90 >= 4 * n_fft]
    np.testing.assert_allclose(_excitation_on_grid(Phi, n_fft, index),
                               excitation(Phi, np.pi * index / n_fft), rtol=1e-9, atol=1e-12)


def test_the_search_scan_whitened_by_its_model_is_the_scan_of_the_dense_covariance():
    # the search whitens by the base kernel's eigenvectors and its terms as a low-rank
    # update; the public scan factors the dense data covariance of the same kernel
    from gpmultirate.inference import LogEvidence
    from gpmultirate.resonances import _ResonantModel, _scan, _tune

    rng = np.random.default_rng(1)
    op = gm.DownsampledConvolution(rng.standard_normal(600), factor=3, order=200)
    t = np.arange(200)
    g = 0.9**t + 0.98**t * np.sin(2.4 * t) + 0.97**t * np.cos(0.7 * t)
    y = op.matvec(g) + 0.01 * rng.standard_normal(op.n_outputs)
    evidence = LogEvidence(op, y, C(1.0) * DC(), 1e-4, (1e-8, 1.0))
    base, noise, _, _ = _tune(evidence, C(1.0) * DC(), 1e-4, 0)
    model = _ResonantModel(evidence.moved_to(base, noise))
    for _ in range(2):  # without a term, then with one
        dense, _, omegas, alphas = resonance_scan(op, y, model.kernel(), model.noise_level)
        whiten = model.whitener()
        mine = _scan(op, y, 0, lambda B: whiten(model.rotate(B)), seen={},
                     white_regressor=whiten(model.rotated_regressor(0)))[0]
        np.testing.assert_allclose(mine, dense, rtol=1e-7, atol=1e-7)
        a, j = np.unravel_index(np.argmax(dense), dense.shape)
        model = model.with_term(0, PK(alpha=alphas[a], omega=omegas[j], sigma1=0.1, sigma2=0.1,
                                      alpha_bounds=(1e-4, 0.999)))
    assert len(model.terms) == 2


# ------------------------------------------------ the base kernel under a disturbance
def _base_judged(first_order_gain, seed):
    """A held mode (plus a first-order part of ``first_order_gain``) seen at factor 3 with a
    Matern 3/2 disturbance: the kernel C * DC + PK at the mode judged with it.  Returns the
    kept terms, the judged kernel and the base's gain by the dense evidence."""
    from sklearn.gaussian_process.kernels import Matern, WhiteKernel

    from gpmultirate.noise import make_noise
    from gpmultirate.resonances import resonances_under_disturbance

    rng = np.random.default_rng(seed)
    P, N = 60, 600
    u = rng.standard_normal(N)
    mode = PK(alpha=0.9, omega=1.1, sigma1=0.5, sigma2=0.5, hold=True)
    c, s = mode.basis(np.arange(P, dtype=float))
    g = 0.4 * c + 0.3 * s + first_order_gain * 0.8 ** np.arange(P)
    op = gm.DownsampledConvolution(u, factor=3, order=P)
    instants = np.arange(op.n_outputs) * 3.0
    level, variance, length = 1e-4, 4e-3, 12.0
    noise_kernel = WhiteKernel(level, "fixed") + C(variance, "fixed") * Matern(
        length, length_scale_bounds="fixed", nu=1.5)
    Ny = noise_kernel(instants[:, None])
    y = op.matvec(g) + rng.multivariate_normal(np.zeros(op.n_outputs), Ny)
    kernel = C(0.05) * DC(alpha=0.8, beta=0.5) + clone(mode)
    noise = make_noise(noise_kernel, level, "fixed", instants)
    evidence = LogEvidence(op, y, kernel, level, "fixed", noise=noise)
    kept, judged = resonances_under_disturbance(op, y, evidence, kernel, noise, [0])
    lags = np.arange(P, dtype=float)[:, None]
    gain = (_dense_gaussian(op.matrix @ kernel(lags) @ op.matrix.T + Ny, y)
            - _dense_gaussian(op.matrix @ mode(lags) @ op.matrix.T + Ny, y))
    return kept, judged, gain


def _dense_gaussian(S, y):
    sign, logdet = np.linalg.slogdet(S)
    return -0.5 * (y @ np.linalg.solve(S, y) + logdet + y.shape[0] * np.log(2 * np.pi))


def test_a_base_kernel_the_terms_leave_idle_is_dropped_under_a_disturbance():
    from gpmultirate.resonances import EVIDENCE_THRESHOLD

    kept, judged, gain = _base_judged(0.0, 5)
    assert kept == [0]
    assert gain <= EVIDENCE_THRESHOLD
    assert isinstance(judged, PK) and judged.held()  # the term alone


def test_a_base_kernel_with_work_of_its_own_stays_under_a_disturbance():
    from gpmultirate.resonances import EVIDENCE_THRESHOLD

    kept, judged, gain = _base_judged(0.5, 5)
    assert kept == [0]
    assert gain > EVIDENCE_THRESHOLD
    assert not isinstance(judged, PK) and len(resonance_summands(judged)) == 1
