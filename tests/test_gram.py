"""Gram matrices of long records by FFT, against the dense ``Phi^T Phi``.

The structured Gram (:mod:`gpmultirate.observations.gram`) is compared with
the product of the explicit regressor for several factors, offsets, orders
on both sides of ``N / F``, inputs, initial conditions, missing samples and
records; the reduction built from it with the QR reduction and with the
dense evidence.
"""

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.inference import log_marginal_likelihood
from gpmultirate.kernels import DC, TC
from gpmultirate.observations import RecordStack, ReducedObservation, SampledConvolution
from gpmultirate.observations.gram import extended_input, uniform_gram


def inputs(kind, n, rng):
    if kind == "white":
        return rng.standard_normal(n)
    if kind == "multisine":
        return sim.multisine(n, random_state=rng)
    if kind == "offset":  # a large mean: entries of the Gram far from zero
        return 5.0 + rng.standard_normal(n)
    raise ValueError(kind)


def plain_gram(Phi, y):
    """``Phi^T Phi`` and ``Phi^T y`` by loops over the rows (no BLAS)."""
    G = np.zeros((Phi.shape[1], Phi.shape[1]))
    b = np.zeros(Phi.shape[1])
    for row, value in zip(Phi, y):
        G += np.outer(row, row)
        b += row * value
    return G, b


def assert_gram(observation, y):
    G, b = observation.gram(y)
    Phi = np.array(observation.matrix)
    G_dense, b_dense = plain_gram(Phi, y)
    np.testing.assert_array_equal(G, G.T)
    scale = np.abs(G_dense).max()
    np.testing.assert_allclose(G, G_dense, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(b, b_dense, rtol=0, atol=1e-10 * np.abs(b_dense).max())


@pytest.mark.parametrize("kind", ["white", "multisine", "offset"])
@pytest.mark.parametrize("factor, offset", [(1, 0), (2, 1), (3, 0), (3, 2), (7, 4), (10, 9)])
@pytest.mark.parametrize("order", [4, 25, 60, 150])
def test_downsampled_convolution_gram_is_the_dense_product(kind, factor, offset, order):
    # orders below the factor, below and above the slow samples N / F
    rng = np.random.default_rng(factor * 100 + order)
    n = 300
    op = gm.DownsampledConvolution(inputs(kind, n, rng), factor, order, offset)
    assert op.structured_gram() is not None
    assert_gram(op, rng.standard_normal(op.n_outputs))


@pytest.mark.parametrize("initial_conditions", ["zero", "discard", "periodic"])
@pytest.mark.parametrize("n_inputs", [1, 2])
@pytest.mark.parametrize("factor, first, order", [(3, 2, 40), (4, 0, 7), (1, 5, 30), (5, 61, 90)])
def test_sampled_convolution_gram_on_a_uniform_grid(initial_conditions, n_inputs, factor, first,
                                                    order):
    rng = np.random.default_rng(order + n_inputs)
    n = 250
    u = np.column_stack([inputs(k, n, rng) for k in ("white", "multisine")[:n_inputs]])
    op = SampledConvolution(u, np.arange(first, n, factor), order, initial_conditions)
    assert op.structured_gram() is not None
    assert_gram(op, rng.standard_normal(op.n_outputs))


@pytest.mark.parametrize("initial_conditions", ["zero", "periodic"])
@pytest.mark.parametrize("missing", [1, 10, 40])
def test_samples_missing_from_a_grid_are_subtracted(initial_conditions, missing):
    rng = np.random.default_rng(missing)
    n, factor = 400, 3
    grid = np.arange(1, n, factor)
    kept = np.sort(rng.choice(grid.shape[0], grid.shape[0] - missing, replace=False))
    u = np.column_stack([rng.standard_normal(n), sim.multisine(n, random_state=rng)])
    op = SampledConvolution(u, grid[kept], 50, initial_conditions)
    assert op.structured_gram() is not None
    assert_gram(op, rng.standard_normal(op.n_outputs))


def test_irregular_instants_take_the_dense_product():
    rng = np.random.default_rng(3)
    steps = 3 + rng.integers(-1, 2, size=200)
    index = np.cumsum(steps)
    index = index[index < 500]
    op = SampledConvolution(rng.standard_normal(500), index, 30)
    assert op.structured_gram() is None  # the grid of step 1 is mostly unobserved
    assert_gram(op, rng.standard_normal(op.n_outputs))
    y = rng.standard_normal(op.n_outputs)
    np.testing.assert_allclose(op.gram(y, block_rows=7)[0], op.gram(y)[0], rtol=1e-12)


def test_records_add_their_grams():
    rng = np.random.default_rng(5)
    first = gm.DownsampledConvolution(rng.standard_normal(200), 3, 20, 1)
    second = SampledConvolution(rng.standard_normal(150), np.arange(0, 150, 3), 20, "periodic")
    stack = RecordStack([first, second])
    assert stack.structured_gram() is not None
    assert_gram(stack, rng.standard_normal(stack.n_outputs))
    steps = np.cumsum(2 + rng.integers(0, 3, size=40))
    irregular = RecordStack([first, SampledConvolution(rng.standard_normal(150), steps[steps < 150], 20)])
    assert irregular.structured_gram() is None
    assert_gram(irregular, rng.standard_normal(irregular.n_outputs))


def test_gram_without_y_and_bad_y():
    rng = np.random.default_rng(0)
    op = gm.DownsampledConvolution(rng.standard_normal(100), 2, 10)
    G, b = op.gram()
    assert b is None
    np.testing.assert_allclose(G, op.matrix.T @ op.matrix, atol=1e-10 * np.abs(G).max())
    y = rng.standard_normal(op.n_outputs)
    before = y.copy()
    op.gram(y)
    np.testing.assert_array_equal(y, before)
    with pytest.raises(ValueError, match="y"):
        op.gram(np.ones(7))
    with pytest.raises(ValueError, match="one-dimensional"):
        op.gram(np.ones((op.n_outputs, 2)))


def test_extended_input_examples_are_the_regressor_rows():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(20)
    for periodic in (False, True):
        e = extended_input(u, 8, periodic)
        op = SampledConvolution(u, np.arange(20), 8, "periodic" if periodic else "zero")
        rows = np.array([e[n + 7 - np.arange(8)] for n in range(20)])
        np.testing.assert_array_equal(rows, op.matrix)


def test_uniform_gram_accepts_a_single_input_as_a_vector():
    rng = np.random.default_rng(2)
    u = rng.standard_normal(60)
    G1, _ = uniform_gram(extended_input(u, 9), 1, 2, 30, 9)
    G2, _ = uniform_gram(extended_input(u, 9)[None], 1, 2, 30, 9)
    np.testing.assert_array_equal(G1, G2)


# ------------------------------------------------------------------ reduction
def noisy_problem(seed=0, n=3000, factor=3, order=80, snr_db=40.0, offset=1):
    rng = np.random.default_rng(seed)
    u = sim.multisine(n, random_state=rng)
    op = gm.DownsampledConvolution(u, factor, order, offset)
    y = op.matvec(0.9 ** np.arange(order) * np.cos(0.3 * np.arange(order)))
    y = y + 10 ** (-snr_db / 20) * np.std(y) * rng.standard_normal(y.shape[0])
    return op, y


@pytest.mark.parametrize("snr_db", [20.0, 40.0, 60.0])
def test_gram_reduction_equals_the_qr_reduction(snr_db):
    op, y = noisy_problem(snr_db=snr_db)
    gram = ReducedObservation(op, y)
    qr = ReducedObservation(op, y, method="qr")
    assert (gram.route, qr.route) == ("gram", "qr")
    Phi = op.matrix
    G = Phi.T @ Phi
    R = gram.matrix
    assert np.allclose(np.tril(R, -1), 0.0)
    np.testing.assert_allclose(R.T @ R, G, rtol=0, atol=1e-10 * np.abs(G).max())
    np.testing.assert_allclose(R.T @ gram.z, Phi.T @ y, rtol=0, atol=1e-10 * np.abs(Phi.T @ y).max())
    # the same factor up to the signs of its rows
    signs = np.sign(np.diag(R)) * np.sign(np.diag(qr.matrix))
    np.testing.assert_allclose(signs[:, None] * R, qr.matrix, rtol=0, atol=1e-8 * np.abs(R).max())
    np.testing.assert_allclose(signs * gram.z, qr.z, rtol=0, atol=1e-8 * np.abs(qr.z).max())
    coef = np.linalg.lstsq(Phi, y, rcond=None)[0]
    assert gram.residual == pytest.approx(np.sum((y - Phi @ coef) ** 2), rel=1e-7)
    assert gram.residual == pytest.approx(qr.residual, rel=1e-7)


@pytest.mark.parametrize("kernel", [C(1.3) * DC(0.8, 0.9), TC(0.9)])
def test_evidence_from_the_gram_reduction_is_the_dense_evidence(kernel):
    op, y = noisy_problem(seed=2, n=600, order=30, snr_db=30.0)
    gram = ReducedObservation(op, y)
    qr = ReducedObservation(op, y, method="qr")
    assert gram.route == "gram"
    noise = 0.05 * np.var(y)
    dense = multivariate_normal(np.zeros(op.n_outputs), op.covariance(kernel) + noise * np.eye(op.n_outputs))
    value, grad = log_marginal_likelihood(gram, kernel, noise, gram.z, True, True)
    value_qr, grad_qr = log_marginal_likelihood(qr, kernel, noise, qr.z, True, True)
    _, grad_full = log_marginal_likelihood(op, kernel, noise, y, True, True)
    assert value == pytest.approx(dense.logpdf(y), rel=1e-10)
    assert value == pytest.approx(value_qr, rel=1e-10)
    np.testing.assert_allclose(grad, grad_full, rtol=1e-7, atol=1e-9 * np.abs(grad_full).max())
    np.testing.assert_allclose(grad, grad_qr, rtol=1e-7, atol=1e-9 * np.abs(grad_qr).max())


def test_the_reduction_falls_back_to_qr_where_the_gram_loses_accuracy():
    rng = np.random.default_rng(4)
    # zero-order hold: Phi is rank deficient, its Gram singular
    u = np.repeat(rng.standard_normal(200), 3)
    op = gm.DownsampledConvolution(u, 3, 30, 2)
    y = rng.standard_normal(op.n_outputs)
    assert ReducedObservation(op, y).route == "qr"
    # noise-free data: the residual would be all cancellation
    op, _ = noisy_problem(n=600, order=30)
    y = op.matvec(0.8 ** np.arange(30))
    reduced = ReducedObservation(op, y)
    assert reduced.route == "qr"
    assert reduced.residual < 1e-20 * (y @ y)
    # irregular instants: no structure
    index = np.cumsum(2 + rng.integers(0, 3, size=200))
    op = SampledConvolution(rng.standard_normal(700), index[index < 700], 20)
    assert ReducedObservation(op, rng.standard_normal(op.n_outputs)).route == "qr"


def test_reduction_rejects_an_unknown_method():
    op, y = noisy_problem(n=300, order=10)
    with pytest.raises(ValueError, match="method must be 'auto' or 'qr'"):
        ReducedObservation(op, y, method="fft")


def test_a_long_record_fit_is_the_same_by_either_reduction(monkeypatch):
    # the fitted model from the Gram reduction and from the QR reduction
    from gpmultirate.observations import reduced

    rng = np.random.default_rng(7)
    u = sim.multisine(4000, random_state=rng)
    y = np.convolve(u, 0.95 ** np.arange(200))[:4000:4]
    y = y + 0.01 * np.std(y) * rng.standard_normal(y.shape[0])
    fast = gm.FIRGaussianProcess(C(1.0) * DC(0.9, 0.9), factor=4, order=200).fit(u, y)
    original = reduced.ReducedObservation.__init__

    def qr_only(self, observation, y, block_rows=None, method="auto"):
        original(self, observation, y, block_rows, "qr")

    monkeypatch.setattr(reduced.ReducedObservation, "__init__", qr_only)
    slow = gm.FIRGaussianProcess(C(1.0) * DC(0.9, 0.9), factor=4, order=200).fit(u, y)
    np.testing.assert_allclose(fast.kernel_.theta, slow.kernel_.theta, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(fast.coef_, slow.coef_, rtol=1e-6, atol=1e-8 * np.abs(slow.coef_).max())


@pytest.mark.slow
def test_a_million_samples_stay_small():
    # N = 1,000,000, F = 10, P = 2000: the Gram by FFT within a few hundred MB
    import tracemalloc

    rng = np.random.default_rng(0)
    u = rng.standard_normal(1_000_000)
    op = gm.DownsampledConvolution(u, 10, 2000)
    y = rng.standard_normal(op.n_outputs)
    tracemalloc.start()
    try:
        reduced = ReducedObservation(op, y)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert reduced.route == "gram"
    assert peak < 400e6
    # spot-check blocks of the Gram against columns of the regressor
    G, b = op.gram(y)

    def columns(start):
        lags = op.sample_indices[:, None] - np.arange(start, start + 10)[None, :]
        return np.where(lags >= 0, u[np.maximum(lags, 0)], 0.0)

    for i, j in [(0, 0), (0, 1990), (7, 1003), (1000, 995), (1990, 1990)]:
        np.testing.assert_allclose(G[i : i + 10, j : j + 10], columns(i).T @ columns(j),
                                   rtol=0, atol=1e-10 * np.abs(G).max())
        np.testing.assert_allclose(b[i : i + 10], columns(i).T @ y, rtol=0,
                                   atol=1e-10 * np.abs(b).max())


def test_an_input_block_does_not_inherit_the_gram_of_all_inputs():
    rng = np.random.default_rng(8)
    u = rng.standard_normal((200, 2))
    op = SampledConvolution(u, np.arange(0, 200, 2), 15)
    op.gram()  # kept on the observation
    block = op.input_block(1)
    Phi = np.array(block.matrix)
    np.testing.assert_allclose(block.gram()[0], Phi.T @ Phi, atol=1e-10 * np.abs(Phi.T @ Phi).max())
