"""The resonance search under a disturbance: the whitened observation it runs on, the
runner-up candidate of a search step, and the drifting systems it was built for."""

from __future__ import annotations

import importlib.util
import logging
import sys
from pathlib import Path

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.inference import LogEvidence
from gpmultirate.kernels import DC
from gpmultirate.observations import DownsampledConvolution, WhitenedObservation
from gpmultirate.resonances import EVIDENCE_THRESHOLD, RUNNER_UP_SPAN, _scan_candidates


def drift_covariance(n, step=0.3, white=0.05):
    i = np.arange(1.0, n + 1.0)
    return step**2 * np.minimum.outer(i, i) + white**2 * np.eye(n)


@pytest.fixture
def problem():
    rng = np.random.default_rng(3)
    op = DownsampledConvolution(rng.standard_normal(240), factor=3, order=30)
    N = drift_covariance(op.n_outputs)
    y = rng.standard_normal(op.n_outputs)
    return op, N, y


def test_whitened_regressor_and_samples_are_the_cholesky_solves(problem):
    op, N, y = problem
    whitened = WhitenedObservation(op, N)
    L = np.linalg.cholesky(N)
    np.testing.assert_allclose(whitened.matrix, np.linalg.solve(L, op.matrix), rtol=1e-10,
                               atol=1e-12)
    np.testing.assert_allclose(whitened.whiten(y), np.linalg.solve(L, y), rtol=1e-10,
                               atol=1e-12)
    assert whitened.shape == op.shape and whitened.slow_factor == 3
    assert not whitened.matrix.flags.writeable


def test_white_noise_there_is_the_disturbance_here(problem):
    """The evidence of the whitened problem with noise ``g I`` is that of the data with the
    noise ``g N``, less ``log det L``: the dense Gaussian density, written out."""
    op, N, y = problem
    kernel = C(2.0) * DC(0.8, 0.7)
    whitened = WhitenedObservation(op, N)
    g = 0.7
    evidence = LogEvidence(whitened, whitened.whiten(y), kernel, g, "fixed")
    value = float(evidence(evidence.theta))
    lags = np.arange(op.order, dtype=float)[:, None]
    covariance = op.matrix @ kernel(lags) @ op.matrix.T + g * N
    sign, logdet = np.linalg.slogdet(covariance)
    dense = -0.5 * (y @ np.linalg.solve(covariance, y) + logdet
                    + y.shape[0] * np.log(2 * np.pi))
    log_det_l = np.sum(np.log(np.diag(np.linalg.cholesky(N))))
    assert sign > 0
    assert value - log_det_l == pytest.approx(dense, rel=1e-9)


def test_whitening_keeps_the_callers_arrays(problem):
    op, N, y = problem
    N0, y0 = N.copy(), y.copy()
    WhitenedObservation(op, N).whiten(y)
    np.testing.assert_array_equal(N, N0)
    np.testing.assert_array_equal(y, y0)


@pytest.mark.parametrize("change, message", [
    (lambda N: N[:-1, :-1], "shape"),
    (lambda N: np.where(np.eye(N.shape[0]) > 0, np.nan, N), "finite"),
    (lambda N: -N, "positive definite"),
])
def test_bad_noise_covariance_is_refused(problem, change, message):
    op, N, _ = problem
    with pytest.raises(ValueError, match=f"noise_covariance must .*{message}"):
        WhitenedObservation(op, change(N))


def test_readings_without_a_regressor_are_refused():
    u = np.random.default_rng(0).standard_normal(200)
    timed = gm.TimedConvolution(u, np.arange(5.5, 195.0, 3.0), order=20)
    with pytest.raises(ValueError, match="observation must have a regressor"):
        WhitenedObservation(timed, np.eye(timed.n_outputs))


def scans_of(peaks, n=200):
    """One input's scan: gains over a frequency grid with the given (omega, gain) peaks."""
    omegas = np.linspace(0.0, np.pi, n)
    gain = np.zeros((2, n))
    for omega, height in peaks:
        gain[0] += height * np.exp(-0.5 * ((omegas - omega) / 0.02) ** 2)
    sigma = np.ones((2, n))
    return gain, sigma, omegas, np.array([0.9, 0.99])


def test_the_runner_up_is_the_best_outside_the_span_of_the_best():
    candidates = _scan_candidates([scans_of([(1.0, 30.0), (1.2, 25.0), (2.5, 20.0)])])
    assert len(candidates) == 2
    best, runner = candidates
    assert best[3] == pytest.approx(1.0, abs=0.02)
    # 1.2 lies within RUNNER_UP_SPAN of 1.0: the next peak outside it is 2.5
    assert 1.2 < RUNNER_UP_SPAN * 1.0
    assert runner[3] == pytest.approx(2.5, abs=0.02) and runner[1] == 0


def test_no_runner_up_at_the_level_of_a_scan_without_a_resonance():
    # the best of a scan without a resonance is about log(n_candidates) ~ 7 nats
    candidates = _scan_candidates([scans_of([(1.0, 30.0), (2.5, EVIDENCE_THRESHOLD - 1.0)])])
    assert len(candidates) == 1


def test_the_runner_up_may_be_another_inputs_term_at_the_same_frequency():
    candidates = _scan_candidates([scans_of([(1.0, 30.0)]), scans_of([(1.0, 20.0)])])
    assert [c[1] for c in candidates] == [0, 1]


def test_a_scan_without_amplitude_gives_no_candidate():
    gain, sigma, omegas, alphas = scans_of([(1.0, 30.0)])
    assert _scan_candidates([(gain, np.zeros_like(sigma), omegas, alphas)]) == []


def drifting_record(seed=1):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(900)
    lags = np.arange(100)
    g = 0.9 ** lags + 0.97 ** lags * np.sin(2.4 * lags)
    y = np.convolve(u, g)[:900:3]
    return u, y + np.cumsum(0.05 * rng.standard_normal(300)) + 0.02 * rng.standard_normal(300)


@pytest.mark.parametrize("options", [
    {"noise_kernel": "white"},
    pytest.param({"tuning": "cross_validation"}, marks=pytest.mark.slow),
])
def test_white_noise_and_cross_validation_search_with_white_noise(options, caplog):
    u, y = drifting_record()
    with caplog.at_level(logging.INFO, logger="gpmultirate.fit"):
        gm.FIRGaussianProcess("auto", factor=3, order=100, max_resonances=1,
                              **options).fit(u, y)
    assert "resonance search: order 100" in caplog.text
    assert "under the disturbance" not in caplog.text


@pytest.mark.slow
def test_a_drift_the_data_call_for_is_searched_under(caplog):
    u, y = drifting_record()
    with caplog.at_level(logging.INFO, logger="gpmultirate.fit"):
        model = gm.FIRGaussianProcess("auto", factor=3, order=100).fit(u, y)
    assert "resonance search: under the disturbance" in caplog.text
    assert [round(2 * np.pi * r.frequency_hz, 1) for r in model.resonances_] == [2.4]
    assert model.noise_kernel_ != "white"


# drifting two-mass systems of benchmarks/automatic.py on which the search with white
# noise lost a mode: a mode the held-out check dropped (the drift took the plain
# held-out fit to 11.7 %), and a strong mode behind a weak one in the scan
BENCHMARK = Path(__file__).resolve().parent.parent / "benchmarks" / "automatic.py"


@pytest.fixture(scope="module")
def benchmark():
    spec = importlib.util.spec_from_file_location("benchmark_automatic", BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1887576524, 3590804131])
def test_drifting_systems_keep_both_modes(benchmark, seed):
    system = benchmark.draw_system("drift", seed, quick=True)
    scored = benchmark.fit_and_score(system, kernel="auto")
    oracle = benchmark.fit_and_score(system, kernel=benchmark.oracle_kernel(system),
                                     noise_kernel=benchmark.oracle_noise_kernel(system))
    assert scored["resonances"]["found"] == 2 and scored["resonances"]["false"] == 0
    # the search with white noise: 88.5 % and 99.26 % (the oracle 99.99 % and 99.96 %)
    assert scored["gof"] > oracle["gof"] - 0.1


@pytest.mark.slow
def test_terms_that_explain_the_colour_bring_the_search_with_white_noise_back(
        monkeypatch, caplog):
    from gpmultirate.fitting import auto_kernel

    # with the margin out of reach, white noise tuned from the disturbance's prior
    # always comes within it: the fit goes on with the search under white noise
    monkeypatch.setattr(auto_kernel, "AUTO_NOISE_MARGIN", 1e9)
    u, y = drifting_record()
    with caplog.at_level(logging.INFO, logger="gpmultirate.fit"):
        model = gm.FIRGaussianProcess("auto", factor=3, order=100).fit(u, y)
    assert "searched again with white noise" in caplog.text
    assert caplog.text.count("resonance search: order 100") == 2
    assert [round(2 * np.pi * r.frequency_hz, 1) for r in model.resonances_] == [2.4]


@pytest.mark.slow
def test_a_named_disturbance_is_searched_under_and_kept(monkeypatch, caplog):
    from gpmultirate.fitting import auto_kernel

    monkeypatch.setattr(auto_kernel, "AUTO_NOISE_MARGIN", 1e9)  # not asked for a name
    u, y = drifting_record()
    with caplog.at_level(logging.INFO, logger="gpmultirate.fit"):
        model = gm.FIRGaussianProcess("auto", factor=3, order=100,
                                      noise_kernel="ar1").fit(u, y)
    assert "resonance search: under the disturbance" in caplog.text
    assert "searched again" not in caplog.text
    assert [round(2 * np.pi * r.frequency_hz, 1) for r in model.resonances_] == [2.4]
    assert "Matern" in repr(model.noise_kernel_)


def test_without_terms_or_colour_the_disturbance_is_checked_once(caplog):
    rng = np.random.default_rng(2)
    u = rng.standard_normal(600)
    y = np.convolve(u, 0.8 ** np.arange(60))[:600:3] + 0.01 * rng.standard_normal(200)
    with caplog.at_level(logging.INFO, logger="gpmultirate.fit"):
        model = gm.FIRGaussianProcess("auto", factor=3, order=60).fit(u, y)
    assert model.resonances_ == [] and model.noise_kernel_ == "white"
    assert caplog.text.count("noise: a fixed disturbance gains") == 1


def test_a_best_candidate_at_zero_frequency_leaves_every_other_one_distinct():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division by zero
        candidates = _scan_candidates([scans_of([(0.0, 30.0), (1.0, 20.0)])])
    assert [round(c[3], 1) for c in candidates] == [0.0, 1.0]
