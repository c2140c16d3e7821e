"""Units invariance, hard numerics and determinism."""

import warnings

import numpy as np
import pytest
from scipy import linalg
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import Matern, WhiteKernel

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.kernels import DC, PK, TC


@pytest.fixture(scope="module")
def experiment():
    system = sim.paper_system(0.1)
    u = sim.multisine(300, random_state=1)
    u_val = sim.multisine(300, random_state=2)
    data = sim.simulate_experiment(system, u, 3, snr_db=50, random_state=3)
    return data, u_val, system.simulate(u_val)


@pytest.mark.parametrize("u_scale, y_scale", [(1e3, 1e-7), (1e-4, 1e5)])
def test_units_do_not_change_the_default_fit(experiment, u_scale, y_scale):
    data, u_val, y_val = experiment
    reference = gm.FIRGaussianProcess(factor=3, order=300).fit(data.u, data.y_slow)
    scaled = gm.FIRGaussianProcess(factor=3, order=300).fit(
        data.u * u_scale, data.y_slow * y_scale
    )
    gof = reference.score(u_val, y_val)
    assert scaled.score(u_val * u_scale, y_val * y_scale) == pytest.approx(gof, abs=0.1)
    band = reference.frequency_response(sample_time=0.1)
    band_scaled = scaled.frequency_response(sample_time=0.1)
    ratio = y_scale / u_scale
    np.testing.assert_allclose(band_scaled.magnitude_upper, band.magnitude_upper * ratio, rtol=1e-3)
    np.testing.assert_allclose(band_scaled.magnitude_lower, band.magnitude_lower * ratio, rtol=1e-3)
    lags = np.array([0.5, 10.25])
    _, std = reference.impulse_response(lags, return_std=True)
    _, std_scaled = scaled.impulse_response(lags, return_std=True)
    np.testing.assert_allclose(std_scaled, std * ratio, rtol=1e-3)


# with the amplitude held at its bound far above the data, the covariance of the
# data is close to singular and gets jitter: expected here, not what is tested
@pytest.mark.filterwarnings("ignore:the data covariance is not numerically positive definite")
def test_amplitude_bounds_that_exclude_the_data_scale_warn(experiment):
    data, _, _ = experiment
    # read in the data's units, scikit-learn's default bounds exclude the scale
    with pytest.warns(ConvergenceWarning, match="constant_value"):
        gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300, normalize=False).fit(
            data.u * 1e3, data.y_slow * 1e-7
        )


def test_normalized_units_need_no_warning_and_fit_in_any_units(experiment):
    data, u_val, y_val = experiment
    reference = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300).fit(
        data.u, data.y_slow)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        scaled = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300).fit(
            data.u * 1e3, data.y_slow * 1e-7)
    assert scaled.score(u_val * 1e3, y_val * 1e-7) == pytest.approx(
        reference.score(u_val, y_val), abs=0.1)


def _assert_sound(model, u):
    lags = np.linspace(0, model.coef_.size + 5, 57)
    mean, std = model.impulse_response(lags, return_std=True)
    y, y_std = model.predict(u, return_std=True)
    frf = model.frequency_response(sample_time=1.0)
    for values in (model.coef_, mean, std, y, y_std, frf.magnitude_upper, frf.phase_upper):
        assert np.all(np.isfinite(values))
    assert np.all(std >= 0) and np.all(y_std >= 0)
    assert np.isfinite(model.log_marginal_likelihood_value_)


HARD_KERNELS = {
    "alpha close to 1": C(1.0) * DC(alpha=1 - 1e-9, beta=1 - 1e-9),
    "TC alpha = 1": C(1.0) * TC(alpha=1.0),
    "resonance near 0": PK(alpha=0.99, omega=1e-3),
    "resonance at Nyquist": PK(alpha=0.99, omega=np.pi),
    "two identical poles": PK(alpha=0.95, omega=0.8) + PK(alpha=0.95, omega=0.8),
    "rank-2 prior only": PK(alpha=0.9, omega=0.5, alpha_bounds="fixed"),
}


@pytest.mark.parametrize("name", sorted(HARD_KERNELS))
@pytest.mark.parametrize("optimizer", [None, "marginal_likelihood"])
def test_hard_kernels_fit_soundly_or_refuse_clearly(experiment, name, optimizer):
    data, _, _ = experiment
    model = gm.FIRGaussianProcess(
        HARD_KERNELS[name], factor=3, order=120, noise_level=1e-10, optimizer=optimizer
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", (gm.NumericalWarning, ConvergenceWarning))
        try:
            model.fit(data.u, data.y_slow)
        except linalg.LinAlgError:  # pragma: no cover - the failure this test guards against
            pytest.fail("LinAlgError escaped to the user")
        except ValueError as exc:
            assert str(exc)
            return
    _assert_sound(model, data.u)


@pytest.mark.parametrize("noise", [1e-14, 1e-300])
@pytest.mark.parametrize("order", [60, 300])
def test_tiny_noise_levels(experiment, noise, order):
    data, _, _ = experiment
    model = gm.FIRGaussianProcess(
        C(1.0) * DC(alpha=0.95, beta=0.9), factor=3, order=order, noise_level=noise, optimizer=None
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gm.NumericalWarning)
        model.fit(data.u, data.y_slow)
    _assert_sound(model, data.u)


@pytest.mark.parametrize(
    "make_input",
    [
        lambda rng: sim.zoh_input(300, 3, random_state=rng),
        lambda rng: sim.zoh_input(300, 3, random_state=rng) + 1e-9 * rng.standard_normal(300),
        lambda rng: np.cumsum(np.cumsum(rng.standard_normal(300))),  # strongly coloured
        lambda rng: np.r_[1.0, np.zeros(299)],  # impulse
    ],
    ids=["zoh", "nearly-zoh", "coloured", "impulse"],
)
def test_hard_inputs(make_input):
    rng = np.random.default_rng(0)
    u = make_input(rng)
    y = sim.paper_system(0.1).simulate(u)[::3]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", (gm.NumericalWarning, ConvergenceWarning))
        model = gm.FIRGaussianProcess(factor=3, order=150).fit(u, y)
    _assert_sound(model, u)


@pytest.mark.slow
def test_identical_inputs_give_bit_identical_results(experiment):
    data, _, _ = experiment
    kernel = C(1.0) * DC(alpha=0.9, beta=0.9) + PK.from_hz(2.0, 0.1, alpha=0.95)

    def run():
        model = gm.FIRGaussianProcess(
            kernel, factor=3, order=200, n_restarts_optimizer=2, random_state=7
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            model.fit(data.u, data.y_slow)
        draws = model.sample_impulse_responses([0.5, 3.5], n_samples=4, random_state=3)
        return model.coef_, model.kernel_.theta, model.noise_level_, draws

    first, second = run(), run()
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a, b)


@pytest.fixture(scope="module")
def short_record():
    rng = np.random.default_rng(1)
    n = 150
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.8 ** np.arange(20))[:n] + 0.05 * rng.standard_normal(n)
    return u, y[::3]


@pytest.mark.parametrize("noise_kernel", [
    None, "white", "matern32", "ar1",
    WhiteKernel(1e-2, "fixed") + C(0.1, "fixed") * Matern(5.0, "fixed", nu=1.5),
])
def test_noise_inclusive_std_does_not_overflow_near_the_float_range(short_record, noise_kernel):
    u, y_slow = short_record
    params = {} if noise_kernel is None else {"noise_kernel": noise_kernel}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        plain = gm.FIRGaussianProcess(order=20, factor=3, **params).fit(u, y_slow)
        huge = gm.FIRGaussianProcess(order=20, factor=3, **params).fit(u, y_slow * 1e300)
    _, std = plain.predict(u, return_std=True, include_noise=True)
    _, std_huge = huge.predict(u, return_std=True, include_noise=True)
    assert np.all(np.isfinite(std_huge))
    np.testing.assert_allclose(std_huge, std * 1e300, rtol=1e-6)
    # independently: the noise-free band and the noise's std, added in quadrature
    _, free = plain.predict(u, return_std=True)
    assert np.all(std > free) and np.all(std < free + np.sqrt(std.max() ** 2))
    [(_, listed)] = huge.predict([u], return_std=True, include_noise=True)
    np.testing.assert_array_equal(listed, std_huge)


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_resonance_search_on_zero_data_finds_no_term():
    # nothing to find: no term (the scan's amplitude is zero, so are its bounds)
    u = np.random.default_rng(0).standard_normal(300)
    model = gm.FIRGaussianProcess(kernel="auto", factor=3).fit(u, np.zeros(100))
    assert model.resonances_ == []
    np.testing.assert_array_equal(model.coef_, 0.0)
    default = gm.FIRGaussianProcess(factor=3).fit(u, np.zeros(100))
    np.testing.assert_array_equal(default.coef_, 0.0)


@pytest.mark.parametrize("estimator", [
    lambda: gm.FIRGaussianProcess(order=20, factor=3),
    lambda: gm.LeastSquaresFIR(order=20, factor=3),
])
def test_coefficients_beyond_the_float_range_are_a_clear_error(short_record, estimator):
    u, y_slow = short_record
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        warnings.simplefilter("ignore", ConvergenceWarning)
        with pytest.raises(ValueError, match="beyond the float range .*near 1e32"):
            estimator().fit(u * 1e-160, y_slow * 1e160)
        # just inside the range: finite coefficients, the scaled ones of the plain fit
        model = estimator().fit(u * 1e-150, y_slow * 1e150)
    plain = estimator().fit(u, y_slow)
    assert np.all(np.isfinite(model.coef_))
    np.testing.assert_allclose(model.coef_, plain.coef_ * 1e300, rtol=1e-6,
                               atol=1e-6 * np.abs(plain.coef_).max() * 1e300)
