"""The disturbance check of noise_kernel="auto" at any order: an AR(1) disturbance seen at an
order below the record's length and at it, white noise kept on white data (the cut tail is
not a disturbance), and the band's coverage under AR(1) disturbances by Monte Carlo."""

import warnings

import numpy as np
import pytest
from scipy import signal
from sklearn.base import clone

from gpmultirate import FIRGaussianProcess
from gpmultirate.simulation import multisine, paper_system

N, FACTOR = 600, 3


def _paper_record(seed, pole=None, snr_db=20.0):
    """A paper-like system (Section 5, parameters within 10 %), a multisine, and an AR(1)
    disturbance of ``pole`` at the fast rate (white noise when None) at ``snr_db``."""
    rng = np.random.default_rng(seed)
    system = paper_system(perturbation=0.1, random_state=rng)
    u = multisine(N, 0.1, random_state=rng)
    y = system.simulate(u)
    if pole is None:
        v = rng.standard_normal(N)
    else:
        e = rng.standard_normal(N) * np.sqrt(1.0 - pole**2)
        v, _ = signal.lfilter([1.0], [1.0, -pole], e, zi=[pole * rng.standard_normal()])
    y_slow = (y + v * np.sqrt(np.var(y) / 10 ** (snr_db / 10)))[::FACTOR]
    return system, u, y_slow


def _fit(u, y_slow, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return FIRGaussianProcess(factor=FACTOR, sample_time=0.1, **options).fit(u, y_slow)


@pytest.mark.parametrize("order, seed", [(100, 0), (300, 1), (None, 2)])
def test_auto_keeps_white_noise_on_white_data_at_a_cut_order_and_by_default(order, seed):
    _, u, y_slow = _paper_record(seed, snr_db=50.0)
    assert _fit(u, y_slow, order=order).noise_kernel_ == "white"


@pytest.mark.slow
def test_the_cut_tail_alone_would_win_a_disturbance_the_check_looks_past_it():
    """At order 50 the paper system's tail colours the residuals: tuned, a disturbance wins
    by the evidence; the check, which looks at all the record's lags, keeps white noise."""
    _, u, y_slow = _paper_record(3, snr_db=50.0)
    coloured = _fit(u, y_slow, order=50, noise_kernel="matern32")
    white = _fit(u, y_slow, order=50, noise_kernel="white")
    assert coloured.log_marginal_likelihood_value_ > white.log_marginal_likelihood_value_ + 10
    assert _fit(u, y_slow, order=50).noise_kernel_ == "white"


@pytest.mark.slow
@pytest.mark.parametrize("order", [300, N])
def test_impulse_band_coverage_under_ar1_disturbances_by_monte_carlo(order):
    """Paper-like systems, AR(1) at the fast rate (pole 0.99, 20 dB): a disturbance is chosen
    on each of eight records below and at the record's length, and the 95 % band of the
    default fit holds 0.92-0.98 of the true impulse response on average over them."""
    coverage, chosen = [], 0
    for seed in range(8):
        system, u, y_slow = _paper_record(seed, pole=0.99)
        model = _fit(u, y_slow, order=order)
        chosen += model.noise_kernel_ != "white"
        mean, std = model.impulse_response(return_std=True)
        truth = system.impulse_response(order)
        coverage.append(np.mean(np.abs(truth - mean) <= 1.959964 * std))
    assert chosen == 8
    assert 0.92 <= np.mean(coverage) <= 0.98


def test_held_out_loss_against_a_dense_refit_of_each_block():
    """The held-out simulation of each block from the others, by the posterior mean of the
    coefficients given the other blocks (a dense solve), under white noise and a disturbance."""
    from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern, WhiteKernel

    from gpmultirate import DownsampledConvolution
    from gpmultirate.crossvalidation import contiguous_folds
    from gpmultirate.fitting.disturbance import DisturbanceFit, held_out_loss
    from gpmultirate.kernels import TC
    from gpmultirate.noise import KernelNoise, noise_instants

    rng = np.random.default_rng(5)
    u = rng.standard_normal(300)
    observation = DownsampledConvolution(u, 3, 25)
    y = observation.matvec(0.8 ** np.arange(25)) + 0.1 * rng.standard_normal(100)
    white_kernel, disturbed_kernel = C(1.0) * TC(alpha=0.8), C(0.5) * TC(alpha=0.7)
    noise = KernelNoise(WhiteKernel(0.005) + C(0.02) * Matern(15.0, nu=0.5),
                        noise_instants(observation))
    fit = DisturbanceFit(None, disturbed_kernel, noise, None, None, 0.0)
    Phi, lags = observation.matrix, np.arange(25.0)[:, None]

    def error(kernel, N):
        K = kernel(lags)
        out = np.empty(100)
        for B in contiguous_folds([100], 5):
            R = np.setdiff1d(np.arange(100), B)
            coef = K @ Phi[R].T @ np.linalg.solve(Phi[R] @ K @ Phi[R].T + N[np.ix_(R, R)], y[R])
            out[B] = y[B] - Phi[B] @ coef
            out[B] -= out[B].mean()
        return np.linalg.norm(out)

    expected = 100 * (error(disturbed_kernel, noise.matrix())
                      - error(white_kernel, 0.01 * np.eye(100))) / np.linalg.norm(y - y.mean())
    assert held_out_loss(observation, y, white_kernel, 0.01, fit) == pytest.approx(expected,
                                                                                   rel=1e-8)


@pytest.mark.slow
def test_a_disturbance_that_absorbs_model_error_is_refused_by_the_held_out_blocks():
    """A white-noise two-mass system (benchmark draw) whose default fit a tuned Matérn 3/2
    'improves' by 182 nats of evidence while its validation fit falls from 95 to 2 %: the
    held-out blocks see the loss."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
    import automatic

    from gpmultirate.fitting.disturbance import (
        AUTO_NOISE_HELD_OUT,
        DisturbanceFit,
        held_out_loss,
    )

    system = automatic.draw_system("two_mass", 9105, quick=True)
    white = _fit(system.u, system.y_slow, noise_kernel="white")
    order = white.coef_.shape[-1]
    coloured = _fit(system.u, system.y_slow, order=order, noise_kernel="matern32")
    assert coloured.log_marginal_likelihood_value_ > white.log_marginal_likelihood_value_ + 10
    assert coloured.score(system.u_val, system.y_val) < white.score(system.u_val,
                                                                     system.y_val) - 10
    fit = DisturbanceFit(None, coloured.kernel_, coloured._noise_model, None, None, 0.0)
    assert held_out_loss(white.observation_, white.y_slow_, white.kernel_, white.noise_level_,
                         fit) > AUTO_NOISE_HELD_OUT


@pytest.mark.slow
def test_readings_between_the_ticks_an_ar1_disturbance_seen_below_the_record_length():
    """Readings at their own instants (jittered stamps, the fast output interpolated): the
    AR(1) disturbance is seen at order 300; white readings keep white noise."""
    _, u, _ = _paper_record(1)
    rng = np.random.default_rng(11)
    system = paper_system(perturbation=0.1, random_state=np.random.default_rng(1))
    y = system.simulate(u)
    e = rng.standard_normal(N) * np.sqrt(1.0 - 0.99**2)
    v, _ = signal.lfilter([1.0], [1.0, -0.99], e, zi=[0.99 * rng.standard_normal()])
    ticks = np.arange(1, N - 2, FACTOR)
    stamps = ticks + rng.uniform(-0.4, 0.4, ticks.shape[0])
    coloured = np.interp(stamps, np.arange(N), y + v * np.std(y) / 10.0)
    white = np.interp(stamps, np.arange(N), y + rng.standard_normal(N) * np.std(y) / 100.0)
    for readings, expected in ((coloured, True), (white, False)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = FIRGaussianProcess(factor=FACTOR, order=300).fit(u, readings,
                                                                     sample_times=stamps)
        assert (model.noise_kernel_ != "white") == expected


def test_discarded_initial_conditions_keep_the_check_within_the_record():
    # at the record's length every reading would be discarded: the check keeps to the
    # tail rule there instead of failing (measured on the CD-player arm's example)
    rng = np.random.default_rng(4)
    u = rng.standard_normal(600)
    y = np.convolve(u, 0.9 ** np.arange(80))[:600]
    y_slow = (y + 0.05 * signal.lfilter([1.0], [1.0, -0.99], rng.standard_normal(600)))[::3]
    model = FIRGaussianProcess(factor=3, order=120, initial_conditions="discard").fit(u, y_slow)
    assert model.coef_.shape == (120,)


def test_evidence_gain_grid_against_dense_log_densities():
    """disturbance_evidence_gain, white noise tuned to nearly nothing: the largest gain of its
    grid, the disturbance sharing the white noise's variance or added on top of it at
    variances relative to the output's power, each log density by slogdet and solve."""
    from gpmultirate.noise import (
        GAIN_ADDED_LEVELS,
        GAIN_LENGTH_SCALES,
        GAIN_SCALES,
        GAIN_SHARES,
        disturbance_evidence_gain,
    )

    rng = np.random.default_rng(5)
    M = 60
    t = 3.0 * np.arange(M)
    A = rng.standard_normal((M, 20))
    S = A @ A.T / 20  # the response's part: rank 20 of 60
    y = A @ rng.standard_normal(20) / np.sqrt(20)
    e = rng.standard_normal(M)
    y += 0.05 * signal.lfilter([1.0], [1.0, -0.8], e)
    gamma = 1e-6 * np.mean(y**2)

    def log_density(C):
        sign, logdet = np.linalg.slogdet(C)
        return -0.5 * (y @ np.linalg.solve(C, y) + logdet + M * np.log(2 * np.pi))

    white = log_density(S + gamma * np.eye(M))
    d = np.abs(t[:, None] - t[None, :])
    gains, shares = [], []
    for length in 3.0 * np.asarray(GAIN_LENGTH_SCALES):
        for R in (np.exp(-d / length),
                  (1 + np.sqrt(3) * d / length) * np.exp(-np.sqrt(3) * d / length)):
            for w in GAIN_SHARES:
                for s in GAIN_SCALES:
                    shares.append(log_density(S + s * gamma * ((1 - w) * np.eye(M) + w * R)))
            for level in GAIN_ADDED_LEVELS:
                gains.append(log_density(S + gamma * np.eye(M) + level * np.mean(y**2) * R))
    expected = max(gains + shares) - white
    # the best point is a disturbance added on top: shares of the tiny white noise fall short
    assert expected > 10.0 and max(gains) > max(shares)
    assert disturbance_evidence_gain(S, y, gamma, t) == pytest.approx(expected, rel=1e-8)


@pytest.mark.slow  # four fits with kernel="auto" and a disturbance tuned: about 15 s of CPU
def test_auto_sees_an_ar1_disturbance_at_50_db_that_the_resonance_prior_took_in():
    """Paper-like systems, AR(1) at the fast rate (pole 0.95) 50 dB below the output,
    ``kernel="auto"``: the tuned resonances take the disturbance into the response and the
    white noise falls to its lower bound on two of these four records, where only a
    disturbance added on top of it is seen.  A disturbance is chosen on all four (two
    before the added check), and the impulse band holds 0.87 of the truth on average (1.00,
    0.93, 0.58, 0.99), where ``noise_kernel="white"`` holds 0.77 (0.65, 0.93, 0.98, 0.54).
    The third record's band is too narrow at long lags: its terms alone carry the response
    (the base kernel earns no place beside them), and their frequencies' spread, conditioned
    on the data a second time, keeps a third of its first-order effect on the posterior
    mean (0.28-0.32 of the variance); with all of it the band holds 1.00."""
    coverage, chosen = [], 0
    for seed in range(4):
        system, u, y_slow = _paper_record(seed, pole=0.95, snr_db=50.0)
        model = _fit(u, y_slow, kernel="auto")
        chosen += model.noise_kernel_ != "white"
        mean, std = model.impulse_response(return_std=True)
        truth = system.impulse_response(mean.shape[0])
        coverage.append(np.mean(np.abs(truth - mean) <= 1.959964 * std))
    assert chosen == 4
    assert np.mean(coverage) >= 0.85


def _counting_candidates(monkeypatch):
    """Record what ``noise_kernel="auto"`` tunes: per candidate its white fit (observation,
    slow samples, prior, noise level, in the fit's units), score and optimizer evaluations,
    and the white fit's score it is judged against."""
    from gpmultirate.fitting import disturbance, one_order

    record = {"tuned": []}
    tune, choose = disturbance.fit_disturbance, one_order.choose_disturbance

    def counted(observation, y, kernel, noise_level, *args, **kwargs):
        fitted = tune(observation, y, kernel, noise_level, *args, **kwargs)
        record["tuned"].append({"white_fit": (observation, y, kernel, noise_level),
                                "score": fitted.score,
                                "nfev": fitted.optimizer_result.nfev})
        return fitted

    def chosen(experiment, kernel, noise_level, noise_bounds, white_score, *args, **kwargs):
        record["white_score"] = white_score
        return choose(experiment, kernel, noise_level, noise_bounds, white_score, *args,
                      **kwargs)

    monkeypatch.setattr(disturbance, "fit_disturbance", counted)
    monkeypatch.setattr(one_order, "choose_disturbance", chosen)
    return record


def _just_past_the_margin(monkeypatch):
    """Pole 0.99 at 20 dB (the issue's case, seed 3), default order: the fit and what it
    tuned; a disturbance is kept, gaining 10.6 nats over white noise."""
    from gpmultirate.fitting.disturbance import AUTO_NOISE_MARGIN

    record = _counting_candidates(monkeypatch)
    _, u, y_slow = _paper_record(3, pole=0.99)
    assert _fit(u, y_slow).noise_kernel_ != "white" and len(record["tuned"]) == 2
    gain = max(t["score"] for t in record["tuned"]) - record["white_score"]
    assert AUTO_NOISE_MARGIN < gain < AUTO_NOISE_MARGIN + 2.0
    return record


def test_auto_keeps_a_disturbance_just_past_the_margin(monkeypatch):
    """Tuned with everything else, the Matérn 1/2 disturbance of the issue's case (pole 0.99,
    20 dB) gains 10.6 nats over white noise, just past the margin, and is kept."""
    _just_past_the_margin(monkeypatch)


@pytest.mark.slow  # the held-prior optimum by Nelder-Mead from twelve starts: about 12 s
def test_a_disturbance_kept_past_the_margin_that_a_fixed_prior_would_miss(monkeypatch):
    """With the white fit's prior held, no Matérn disturbance of either shape gains more
    than 7.0 nats on the case above (tuned by scipy on the dense evidence; 5.8 and 6.9),
    where the full tuning gains 10.6: a cheaper rejection from the held prior (or from the
    gate's grid, 4.6 nats) would keep white noise here (docs/disturbances.rst)."""
    from scipy import optimize
    from sklearn.gaussian_process.kernels import Matern, WhiteKernel

    from gpmultirate.fitting.disturbance import AUTO_NOISE_MARGIN
    from gpmultirate.kernels import observe

    record = _just_past_the_margin(monkeypatch)
    # the prior held at the white fit's: the best Matern disturbance by the dense evidence
    observation, y, kernel, gamma = record["tuned"][0]["white_fit"]
    S = np.asarray(observe(kernel, observation).covariance(), dtype=float)
    t = observation.records[0].sample_indices.astype(float)[:, None]

    def log_evidence(Ky):
        L = np.linalg.cholesky(Ky)
        z = np.linalg.solve(L, y)
        return -0.5 * z @ z - np.log(np.diag(L)).sum() - 0.5 * y.shape[0] * np.log(2 * np.pi)

    assert log_evidence(S + gamma * np.eye(y.shape[0])) == pytest.approx(
        record["white_score"], rel=1e-9)
    held = []
    for nu in (0.5, 1.5):
        def negative(theta, nu=nu):
            w, c, length = np.exp(theta)
            N = WhiteKernel(w)(t) + c * Matern(length, nu=nu)(t)
            try:
                return -log_evidence(S + N)
            except np.linalg.LinAlgError:
                return np.inf
        starts = [np.log([gamma * (1 - share), gamma * share, length])
                  for share in (0.5, 0.9) for length in (3.0, 30.0, 300.0)]
        held.append(max(-optimize.minimize(negative, x0, method="Nelder-Mead",
                                           options={"xatol": 1e-6, "fatol": 1e-8}).fun
                        for x0 in starts) - record["white_score"])
    assert max(held) < AUTO_NOISE_MARGIN - 3.0


def test_auto_tunes_both_disturbances_and_keeps_white_below_the_margin(monkeypatch):
    """A two-mass system with an AR(1) disturbance at 31.7 dB (``benchmarks/automatic.py``'s
    ``ar1`` family, seed 803410186), the default kernel: the fixed disturbance passes the
    gate, both candidates are tuned in full and gain about 5 nats, below the margin: white
    noise is kept.  Every shortcut before the full tuning must keep this decision."""
    import importlib.util
    import sys
    from pathlib import Path

    from gpmultirate.fitting.disturbance import AUTO_NOISE_MARGIN

    path = Path(__file__).resolve().parent.parent / "benchmarks" / "automatic.py"
    spec = importlib.util.spec_from_file_location("benchmark_automatic", path)
    benchmark = sys.modules.get(spec.name)
    if benchmark is None:
        benchmark = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = benchmark  # dataclasses look their module up by name
        spec.loader.exec_module(benchmark)
    system = benchmark.draw_system("ar1", 803410186, quick=True)
    record = _counting_candidates(monkeypatch)
    auto = FIRGaussianProcess(factor=system.factor, sample_time=system.sample_time)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        auto.fit(system.u, system.y_slow)
    assert auto.noise_kernel_ == "white" and len(record["tuned"]) == 2
    gains = [t["score"] - record["white_score"] for t in record["tuned"]]
    assert all(3.0 < g < AUTO_NOISE_MARGIN for g in gains)
    assert all(t["nfev"] > 10 for t in record["tuned"])


@pytest.mark.slow  # four fits with kernel="auto", a white tuning and a cross-validated one: 4 s
def test_white_tuned_again_from_a_disturbance_that_found_a_better_prior(monkeypatch):
    """``choose_disturbance`` from a white fit at a poorer prior: the disturbance tuned from
    there gains more than the margin over it, white noise tuned again from the
    disturbance's prior comes within the margin of it, and white noise is kept, at the
    better prior (the gates, ``calls_for_disturbance`` and ``held_out_loss``, passed)."""
    import sys
    import types
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
    import automatic

    from gpmultirate.fitting import disturbance as chooser
    from gpmultirate.fitting.settings import check_settings
    from gpmultirate.inference import LogEvidence
    from gpmultirate.kernels.spread import conditioning_kernel

    system = automatic.draw_system("two_mass", 535214420, quick=True)
    auto = _fit(system.u, system.y_slow, kernel="auto")
    kernel = conditioning_kernel(auto.kernel_)
    amplitudes = {k: 0.1 * v for k, v in kernel.get_params().items() if k.endswith("sigma2")}
    poor = clone(kernel).set_params(**amplitudes)
    evidence = LogEvidence(auto.observation_, auto.y_slow_, poor, auto.noise_level_,
                           auto.noise_level_bounds_)
    poor_score = float(evidence(evidence.theta))
    assert poor_score < auto.log_marginal_likelihood_value_ - 50.0
    monkeypatch.setattr(chooser, "calls_for_disturbance", lambda *a, **k: True)
    monkeypatch.setattr(chooser, "held_out_loss", lambda *a, **k: 0.0)
    experiment = types.SimpleNamespace(observation=auto.observation_, y=auto.y_slow_)
    chosen = chooser.choose_disturbance(experiment, poor, auto.noise_level_,
                                        auto.noise_level_bounds_, poor_score,
                                        check_settings(auto))
    assert chosen is not None and chosen.noise_model is None
    # white noise at the better prior: the evidence of the white fit, and above the poorer
    assert chosen.score > poor_score + chooser.AUTO_NOISE_MARGIN
    assert chosen.score >= auto.log_marginal_likelihood_value_ - 1.0
    assert chosen.score == pytest.approx(
        chosen.evidence.posterior(chosen.kernel, chosen.noise_level).log_marginal_likelihood,
        rel=1e-12)


def test_a_disturbance_that_only_found_a_better_prior_leaves_white_noise():
    """kernel="auto" on a two-mass system with white noise: the Matérn disturbance, tuned
    with the prior from the white fit, gains more than AUTO_NOISE_MARGIN over it with a
    disturbance of 1e-4 of the noise's std; white noise tuned again from the disturbance's
    prior comes within the margin, and is kept, with the better prior."""
    import sys
    from pathlib import Path

    from sklearn.gaussian_process.kernels import WhiteKernel

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
    import automatic

    from gpmultirate.fitting.disturbance import AUTO_NOISE_MARGIN, DisturbanceFit, white_from
    from gpmultirate.fitting.settings import check_settings

    system = automatic.draw_system("two_mass", 535214420, quick=True)
    auto = _fit(system.u, system.y_slow, kernel="auto")
    assert auto.noise_kernel_ == "white"
    forced = _fit(system.u, system.y_slow, kernel="auto", noise_kernel="matern32")
    white = forced.noise_kernel_.k1 if isinstance(forced.noise_kernel_.k1, WhiteKernel) else (
        forced.noise_kernel_.k2)
    disturbance = forced.noise_kernel_.k2 if white is forced.noise_kernel_.k1 else (
        forced.noise_kernel_.k1)
    share = disturbance.diag(np.zeros((1, 1)))[0] / white.noise_level
    assert share < 1e-3  # the disturbance is nothing against the white noise
    # white_from against the dense evidence of the data at its tuned point
    settings = check_settings(auto)
    disturbed = DisturbanceFit(None, forced.kernel_, forced._noise_model, None, None,
                               forced.log_marginal_likelihood_value_)
    again = white_from(disturbed, forced.observation_, forced.y_slow_,
                       auto.noise_level_bounds_, settings)
    assert again.noise_model is None
    Phi = forced.observation_.matrix
    K = again.kernel(np.arange(Phi.shape[1])[:, None].astype(float))
    C = Phi @ K @ Phi.T + again.noise_level * np.eye(Phi.shape[0])
    sign, logdet = np.linalg.slogdet(C)
    y = forced.y_slow_
    dense = -0.5 * (y @ np.linalg.solve(C, y) + logdet + y.shape[0] * np.log(2 * np.pi))
    assert again.score == pytest.approx(dense, abs=1e-6 * abs(dense) + 1e-6)
    # the auto white fit reaches that prior itself: the search tunes its kept terms, the
    # base kernel's scale and the noise once more at the end (before, the white fit ended
    # 7.3 nats below the disturbed one, the search's scale held within a factor of 1,000)
    first = _fit(system.u, system.y_slow, kernel="auto", noise_kernel="white")
    assert abs(disturbed.score - first.log_marginal_likelihood_value_) < 1.0
    assert disturbed.score <= again.score + AUTO_NOISE_MARGIN
    # by cross-validation: tuned from the disturbed fit's point, the criterion does not fall
    from gpmultirate.crossvalidation import CrossValidation

    judged = white_from(disturbed, forced.observation_, forced.y_slow_,
                        auto.noise_level_bounds_, settings, cross_validated=True)
    level = float(forced._noise_model.sample_variance())
    start = CrossValidation(forced.observation_, forced.y_slow_, forced.kernel_, level,
                            auto.noise_level_bounds_, settings.n_folds)
    assert judged.noise_model is None and judged.score >= start(start.theta) - 1e-9
    low, high = auto.noise_level_bounds_
    assert low <= judged.noise_level <= high
