"""The optimizer's coordinates: amplitudes measured against the correlation they scale.

The couplings are read from the kernel's structure; the transform is checked
by its round trip, its gradient against finite differences of the composed
function, and its invariance along ``c (1 - beta^2) = const``; tuning in the
coupled coordinates against tuning in plain ones (same optimum), also where
the amplitude's bound binds.
"""

import numpy as np
import pytest
from scipy import optimize
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import inference, tuning
from gpmultirate.kernels import DC, PK, TC, observe


@pytest.mark.parametrize(
    "kernel, expected",
    [
        (C(1.0) * DC(), [(2, 0)]),  # roles: c, alpha, beta
        (DC() * C(1.0), [(1, 2)]),  # roles: alpha, beta, c
        (C(1.0) * DC() + PK(), [(2, 0)]),
        (PK() + C(1.0) * DC(), [(6, 4)]),
        (C(1.0) * (DC() + PK()), [(2, 0)]),
        (C(1.0) * TC(), []),  # no correlation
        (DC(), []),  # no amplitude
        (C(1.0, "fixed") * DC(), []),  # the constant is not tuned
        (C(1.0) * (DC() + DC()), []),  # two correlations: no single partner
    ],
)
def test_couplings_follow_the_kernel_structure(kernel, expected):
    term = observe(kernel)
    found = term.amplitude_couplings()
    assert found == expected
    roles = term.roles()
    for j, a in found:
        assert roles[j].kind == "correlation" and roles[a].kind == "amplitude"


def test_couplings_of_several_inputs_are_offset_per_input():
    from gpmultirate.kernels import PerInputKernel

    kernel = PerInputKernel([C(1.0) * DC(), C(2.0) * TC(), DC() * C(3.0)])
    term = observe(kernel)
    roles = term.roles()  # (c, alpha, beta), (c, alpha), (alpha, beta, c)
    found = term.amplitude_couplings()
    assert len(found) == 2
    for j, a in found:
        assert roles[j].kind == "correlation" and roles[a].kind == "amplitude"
        assert roles[j].owner is not roles[a].owner
    first, second = found
    assert found == [(2, 0), (6, 7)]


def transform():
    # theta: log c, log alpha, artanh beta, log noise; a second amplitude of power 1/2
    return tuning.CorrelationScaleTransform([1], [(2, 0, 1.0), (2, 4, 0.5)])


def test_transform_round_trip():
    t = transform()
    theta = np.array([-3.0, -0.02, 2.5, -9.0, 1.5])
    z = t.to_z(theta)
    np.testing.assert_allclose(t.to_theta(z), theta, rtol=1e-13)
    # the amplitude coordinate: log c + log(1 - beta^2), with half of it for power 1/2
    beta = np.tanh(2.5)
    assert z[0] == pytest.approx(-3.0 + np.log(1.0 - beta**2), rel=1e-12)
    assert z[4] == pytest.approx(1.5 + 0.5 * np.log(1.0 - beta**2), rel=1e-12)
    assert z[1] == pytest.approx(np.log(0.02))  # the decay rate, as before
    # large artanh beta: no overflow in log cosh
    far = t.to_z(np.array([0.0, -0.02, 400.0, 0.0, 0.0]))
    assert np.all(np.isfinite(far))


def test_transform_is_constant_along_the_valley():
    t = transform()
    betas = np.array([0.5, 0.9, 0.99, 0.9999])
    zs = [t.to_z(np.array([-np.log(1 - b**2), -0.1, np.arctanh(b), 0.0, 0.0]))[0]
          for b in betas]
    np.testing.assert_allclose(zs, 0.0, atol=1e-10)


def test_transform_gradient_against_finite_differences():
    t = transform()
    weights = np.array([0.7, -1.3, 0.4, 2.0, -0.5])

    def f(theta):
        return float(np.sum(weights * np.sin(theta)) + theta[0] * theta[2])

    def grad(theta):
        g = weights * np.cos(theta)
        g[0] += theta[2]
        g[2] += theta[0]
        return g

    theta = np.array([-1.0, -0.3, 1.2, 0.5, 0.8])
    z = t.to_z(theta)
    analytic = t.gradient(grad(theta), theta)
    h = 1e-6
    numeric = [(f(t.to_theta(z + h * e)) - f(t.to_theta(z - h * e))) / (2 * h)
               for e in np.eye(z.size)]
    np.testing.assert_allclose(analytic, numeric, rtol=1e-6, atol=1e-8)


def long_record(seed=3, n=3000, order=300):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    g = 0.97 ** np.arange(order) * np.cos(0.3 * np.arange(order))
    y = np.convolve(u, g)[:n:3] + 0.05 * rng.standard_normal(n // 3)
    return u, y


def fit_both(monkeypatch, kernel, order=300):
    u, y = long_record(order=order)

    def fit():
        return gm.FIRGaussianProcess(kernel, factor=3, order=order).fit(u, y)

    coupled = fit()
    assert "hess_inv" in coupled.optimizer_result_  # L-BFGS-B, where the couplings apply
    with monkeypatch.context() as m:
        m.setattr(inference.LogEvidence, "amplitude_couplings", lambda self: [])
        plain = fit()
    return coupled, plain


def test_coupled_coordinates_reach_the_plain_optimum(monkeypatch):
    coupled, plain = fit_both(monkeypatch, C(1.0) * DC(0.9, 0.99))
    assert coupled.log_marginal_likelihood_value_ == pytest.approx(
        plain.log_marginal_likelihood_value_, abs=1e-5)
    np.testing.assert_allclose(coupled.coef_, plain.coef_, rtol=1e-3,
                               atol=1e-4 * np.abs(plain.coef_).max())


@pytest.mark.slow
def test_an_amplitude_bound_that_binds_is_kept(monkeypatch):
    # the unbounded amplitude coordinate leaves the bound; the polish brings the
    # result back onto it, where the plain run also ends (the kernel is a prior
    # in normalized units: its bounds are read from the fitted kernel)
    free, _ = fit_both(monkeypatch, C(1.0, (1e-12, 1e12)) * DC(0.9, 0.99))
    value = free.kernel.k1.constant_value * free.kernel_.k1.constant_value / (
        free.kernel_.k1.hyperparameter_constant_value.bounds[0, 0] / 1e-12)
    bounds = (value * 10.0, value * 1e3)
    with pytest.warns(Warning, match="constant_value .* on its lower bound"):
        coupled, plain = fit_both(monkeypatch, C(value * 100, bounds) * DC(0.9, 0.99))
    lower = coupled.kernel_.k1.hyperparameter_constant_value.bounds[0, 0]
    assert coupled.kernel_.k1.constant_value == pytest.approx(lower, rel=1e-9)
    assert plain.kernel_.k1.constant_value == pytest.approx(lower, rel=1e-9)
    assert coupled.log_marginal_likelihood_value_ == pytest.approx(
        plain.log_marginal_likelihood_value_, abs=1e-5)
    assert coupled.log_marginal_likelihood_value_ < free.log_marginal_likelihood_value_


def test_cross_validation_keeps_plain_coordinates():
    # the valley is the evidence's; cross-validation is tuned in plain coordinates
    from gpmultirate.crossvalidation import CrossValidation

    u, y = long_record(n=300, order=30)
    operator = gm.DownsampledConvolution(u, 3, 30)
    kernel = C(1.0) * DC()
    evidence = inference.LogEvidence(operator, y, kernel, 1e-2, (1e-6, 1.0))
    assert evidence.amplitude_couplings() == [(2, 0, 1.0)]
    objective = CrossValidation(operator, y, kernel, 1e-2, (1e-6, 1.0), n_folds=5)
    assert objective.amplitude_couplings() == []


def test_the_prefit_scale_warning_is_kept_for_an_amplitude_the_tuning_leaves_on_its_bound():
    # at the start's shape (a fast decay) the slow response calls for a huge scale; the
    # tuned shape takes it back inside wide bounds (no warning), not inside tight ones
    import warnings

    from sklearn.exceptions import ConvergenceWarning

    rng = np.random.default_rng(0)
    op = gm.DownsampledConvolution(rng.standard_normal(600), factor=3, order=150)
    y = op.matvec(0.98 ** np.arange(150)) + 0.01 * rng.standard_normal(op.n_outputs)
    for bounds, binds in (((1e-3, 1e3), False), ((1e-4, 3e-3), True)):
        evidence = inference.LogEvidence(op, y, C(1e-3, bounds) * DC(0.2, 0.9), 1e-4,
                               (1e-8, 1.0))
        with pytest.warns(ConvergenceWarning, match="the data call for the kernel"):
            tuning.prefit_scale_and_noise(evidence)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = tuning.maximize(evidence)
        said = [w for w in caught if "the data call for the kernel" in str(w.message)]
        amplitude = np.exp(result.x[0])
        assert (amplitude == pytest.approx(bounds[1])) == binds
        assert len(said) == int(binds)


def _rosenbrock(theta):
    x, y = theta
    value = (1.0 - x) ** 2 + 100.0 * (y - x**2) ** 2
    grad = np.array([-2.0 * (1.0 - x) - 400.0 * x * (y - x**2), 200.0 * (y - x**2)])
    return value, grad


def _counted(function):
    calls = [0]

    def counted(theta):
        calls[0] += 1
        return function(theta)

    return counted, calls


def test_a_run_stopped_short_on_relative_reduction_starts_again(monkeypatch):
    # a loose ftol makes L-BFGS-B stop on a small relative reduction far from the
    # optimum (the camera log's stop on a broken curvature memory); the restarts go on
    bounds = np.array([[-5.0, 5.0], [-5.0, 5.0]])
    monkeypatch.setattr(tuning, "LBFGS_OPTIONS", dict(tuning.LBFGS_OPTIONS, ftol=0.2))
    monkeypatch.setattr(tuning, "LBFGS_RESTARTS", 0)
    once = tuning.minimize_lbfgs(_rosenbrock, np.array([-1.2, 1.0]), bounds)
    assert "REDUCTION" in str(once.message).upper() and once.fun > 1e-2
    assert tuning._promises_more(once)
    monkeypatch.setattr(tuning, "LBFGS_RESTARTS", 50)
    counted, calls = _counted(_rosenbrock)
    again = tuning.minimize_lbfgs(counted, np.array([-1.2, 1.0]), bounds)
    assert again.fun < 0.1 * once.fun
    assert again.nfev == calls[0]  # the evaluations of every run are counted
    # the budget covers the restarts too: none starts once it is spent
    counted, calls = _counted(_rosenbrock)
    capped = tuning.minimize_lbfgs(counted, np.array([-1.2, 1.0]), bounds,
                                   max_evaluations=once.nfev)
    assert calls[0] == capped.nfev == once.nfev
    counted, calls = _counted(_rosenbrock)
    capped = tuning.minimize_lbfgs(counted, np.array([-1.2, 1.0]), bounds,
                                   max_evaluations=once.nfev + 20)
    assert calls[0] == capped.nfev < again.nfev and capped.fun < once.fun


def test_a_converged_run_is_not_started_again():
    bounds = np.array([[-5.0, 5.0], [-5.0, 5.0]])
    counted, calls = _counted(_rosenbrock)
    result = tuning.minimize_lbfgs(counted, np.array([-1.2, 1.0]), bounds)
    plain = tuning._lbfgs_run(_rosenbrock, np.array([-1.2, 1.0]), bounds)
    # converged: the last iteration and the run's own model both gain under EXPECTED_GAIN
    # (Rosenbrock's minimum is 0: what is left to gain is the value)
    assert "EXPECTED GAIN" in tuning._message(result) and result.success
    assert result.fun < tuning.EXPECTED_GAIN and calls[0] == plain.nfev == result.nfev
    assert not tuning._promises_more(plain)


def test_the_expected_gain_stop_reads_what_is_left_from_the_runs_curvature():
    # a quadratic of condition 1e4 in 8 dimensions (its minimum 0: the value is what is
    # left to gain): the run stops with under EXPECTED_GAIN left, sooner than ftol alone
    scales = np.logspace(0.0, 4.0, 8)

    def quadratic(theta):
        return float(0.5 * np.sum(scales[:theta.size] * theta**2)), scales[:theta.size] * theta

    start, box = np.linspace(-3.0, 3.0, 8), np.tile([-5.0, 5.0], (8, 1))
    stopped = tuning._lbfgs_run(quadratic, start, box)
    full = tuning._lbfgs_run(quadratic, start, box, stop_gain=None)
    assert "EXPECTED GAIN" in tuning._message(stopped) and stopped.success
    assert full.fun < stopped.fun < tuning.EXPECTED_GAIN and stopped.nfev < full.nfev
    bounds = np.array([[-5.0, 5.0], [-5.0, 5.0]])
    # steps along the axes (the Hessian's eigenvectors): the two-loop model is the exact
    # inverse Hessian, and its promise the value left
    stop = tuning._ExpectedGainStop(quadratic, bounds)
    for x in ([3.0, -2.0], [2.0, -2.0], [2.0, -0.5], [1.0, -0.5]):
        x = np.array(x)
        stop.objective(x)
        stop(optimize.OptimizeResult(x=x, fun=quadratic(x)[0]))
    g = stop.gradient
    assert 0.5 * g @ stop._inverse_hessian_times(g) == pytest.approx(stop.value, rel=1e-12)
    # one short step along a steep direction: its pair alone promises under the limit
    # (its scale, 1e-4, extended to the flat directions) where 9 nats are left; the model
    # is trusted only with as many pairs as coordinates
    steep = np.array([1.0, 1.0, 1e4])

    def cliff(theta):
        return float(0.5 * np.sum(steep * theta**2)), steep * theta

    stop = tuning._ExpectedGainStop(cliff, np.tile([-5.0, 5.0], (3, 1)))
    for x in ([3.0, 3.0, 3e-4], [3.0, 3.0, 0.0]):
        x = np.array(x)
        stop.objective(x)
        stop(optimize.OptimizeResult(x=x, fun=cliff(x)[0]))
    g = stop.gradient
    assert stop.last_gain < tuning.EXPECTED_GAIN and stop.value == pytest.approx(9.0)
    assert 0.5 * g @ stop._inverse_hessian_times(g) < tuning.EXPECTED_GAIN
    assert not stop.stopped
    # a small gain on a flat stretch is not enough: the model still promises much
    stop = tuning._ExpectedGainStop(quadratic, bounds)
    for x in (np.array([3.0, -0.001]), np.array([3.0 - 1e-4, -0.001])):
        stop.objective(x)
        stop(optimize.OptimizeResult(x=x, fun=quadratic(x)[0]))
    assert stop.last_gain < tuning.EXPECTED_GAIN and not stop.stopped
    assert stop.promised > 1.0


def test_the_gain_floor_ends_a_run_alike_in_any_units_and_keeps_its_value():
    # the evidence of data in other units moves by a constant: the same iterates and
    # evaluations, whatever the constant; the value reported is the objective's own
    bounds = np.array([[-5.0, 5.0], [-5.0, 5.0]])
    runs = []
    for constant in (0.0, 1e4, -3e6):
        def shifted(theta, constant=constant):
            value, grad = _rosenbrock(theta)
            return value + constant, grad

        counted, calls = _counted(shifted)
        runs.append((tuning._lbfgs_run(counted, np.array([-1.2, 1.0]), bounds), calls[0]))
    for (result, calls), constant in zip(runs, (0.0, 1e4, -3e6)):
        assert result.nfev == calls == runs[0][0].nfev
        # the same iterates, to the rounding of the constant (3e6 eps: 7e-10 in the value)
        np.testing.assert_allclose(result.x, runs[0][0].x, rtol=0, atol=1e-8)
        assert result.fun - constant == pytest.approx(runs[0][0].fun, abs=1e-9)
    # the floor stops where an iteration gains under about STOP_GAIN, well short of the
    # relative ftol alone (which needs 1e-12 of the value: down to rounding here)
    full = tuning._lbfgs_run(_rosenbrock, np.array([-1.2, 1.0]), bounds, stop_gain=None)
    assert full.nfev > runs[0][0].nfev and full.fun < runs[0][0].fun < tuning.EXPECTED_GAIN


def test_a_gradient_against_its_bound_promises_nothing():
    # the minimum of (x + 3)^2 over [-1, 1] sits on the lower bound with gradient 4
    def pushed(theta):
        return float((theta[0] + 3.0) ** 2), np.array([2.0 * (theta[0] + 3.0)])

    result = tuning._lbfgs_run(pushed, np.array([0.5]), np.array([[-1.0, 1.0]]))
    assert result.x[0] == -1.0 and not result.free[0]
    result.message = "CONVERGENCE: RELATIVE REDUCTION OF F <= FACTR*EPSMCH"
    assert not tuning._promises_more(result)
    result.free = np.array([True])
    assert tuning._promises_more(result)  # the same gradient off the bound would


def test_a_resonance_part_on_a_negligible_lower_bound_is_not_a_bound_that_decided():
    """A PK amplitude on a lower bound below ``ABSENT_PART`` times the term's other amplitude
    is a part the data do not need (the term's phase set): not listed; a lower bound near
    the other amplitude, or an upper bound, is."""
    from gpmultirate import DownsampledConvolution
    from gpmultirate.inference import LogEvidence
    from gpmultirate.kernels import DC, PK
    from gpmultirate.tuning import ABSENT_PART, hyperparameters_at_bounds

    rng = np.random.default_rng(0)
    op = DownsampledConvolution(rng.standard_normal(300), factor=3, order=60)
    y = rng.standard_normal(op.n_outputs)

    def listed(sigma1, sigma1_bounds, sigma2=0.5, sigma2_bounds=(1e-5, 10.0)):
        kernel = C(1.0) * DC(0.9, 0.9) + PK(alpha=0.95, omega=1.0, sigma1=sigma1,
                                             sigma2=sigma2, sigma1_bounds=sigma1_bounds,
                                             sigma2_bounds=sigma2_bounds)
        evidence = LogEvidence(op, y, kernel, 0.1, (1e-4, 10.0))
        return [name for name, *_ in hyperparameters_at_bounds(evidence)]

    tiny = 0.5 * ABSENT_PART * 0.5
    assert listed(tiny, (tiny, 10.0)) == []
    assert listed(0.1, (0.1, 10.0)) == ["k2__sigma1"]  # the bound is near the other part
    assert listed(0.5, (1e-5, 10.0), sigma2=10.0) == ["k2__sigma2"]  # an upper bound
    # the same rule for the sine part
    assert listed(0.5, (1e-5, 10.0), sigma2=tiny, sigma2_bounds=(tiny, 10.0)) == []
