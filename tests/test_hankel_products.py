"""The state-space reduction by FFT products and values-only spectra, against the dense ERA."""

import numpy as np
import pytest
from scipy import linalg

from gpmultirate.realization import (
    _HankelProduct,
    block_hankel,
    era,
    hankel_singular_values,
    leading_era,
)


def dense_era(h, n):
    """The Ho-Kalman realization written plainly: full SVD of the dense Hankel matrices."""
    h = h[:, None, None] if h.ndim == 1 else h
    H, H1 = block_hankel(h), block_hankel(h, shift=1)
    U, s, Vt = np.linalg.svd(H)
    root = np.sqrt(s[:n])
    A = (U[:, :n] / root).T @ H1 @ (Vt[:n].T / root)
    B = (root[:, None] * Vt[:n])[:, : h.shape[2]]
    C = (U[:, :n] * root)[: h.shape[1], :]
    return A, B, C, s


def noisy_two_mode_response(n_lags, rng, noise=1e-3):
    k = np.arange(n_lags)
    g = 0.97 ** k * np.sin(0.3 * k) + 0.5 * 0.9 ** k * np.sin(1.9 * k)
    return np.r_[0.0, g[1:]] + noise * rng.standard_normal(n_lags)


def markov(A, B, C, D, n_lags):
    out, x = [D], B
    for _ in range(n_lags - 1):
        out.append(C @ x)
        x = A @ x
    return np.array(out)


@pytest.mark.parametrize("shape", [(1, 1), (1, 2), (2, 1), (2, 3)])
@pytest.mark.parametrize("shift", [0, 1])
def test_fft_products_equal_the_dense_block_hankel(shape, shift):
    rng = np.random.default_rng(3)
    h = rng.standard_normal((23, *shape))
    for rows, cols in [(22, 22), (7, 13), (15, 4)]:
        H = block_hankel(h, rows, cols, shift=shift)
        product = _HankelProduct(h, rows, cols, shift=shift)
        v = rng.standard_normal((H.shape[1], 3))
        x = rng.standard_normal((H.shape[0], 2))
        np.testing.assert_allclose(product.matmat(v), H @ v, atol=1e-12)
        np.testing.assert_allclose(product.rmatmat(x), H.T @ x, atol=1e-12)
        op = product.operator()
        np.testing.assert_allclose(op.matvec(v[:, 0]), H @ v[:, 0], atol=1e-12)
        np.testing.assert_allclose(op.rmatvec(x[:, 0]), H.T @ x[:, 0], atol=1e-12)


@pytest.mark.parametrize("shape", [(1, 1), (1, 2), (2, 1)])
def test_values_only_spectrum_equals_the_full_svd(shape):
    rng = np.random.default_rng(4)
    h = rng.standard_normal((40, *shape)) * 0.9 ** np.arange(40)[:, None, None]
    for rows, cols in [(None, None), (12, 20)]:
        expected = np.linalg.svd(block_hankel(h, rows, cols), compute_uv=False)
        found = hankel_singular_values(h, rows, cols)
        assert found.shape == expected.shape
        np.testing.assert_allclose(found, expected, rtol=1e-10, atol=1e-12 * expected[0])


@pytest.mark.parametrize("n_lags", [60, 400])
def test_era_equals_the_dense_realization_and_keeps_its_bound(n_lags):
    # 400 lags take the iterative route for the leading triplets, 60 the full SVD
    rng = np.random.default_rng(5)
    h = noisy_two_mode_response(n_lags, rng)
    r = era(h, 4)
    A, B, C, s = dense_era(h, 4)
    np.testing.assert_allclose(r.hankel_singular_values, s, rtol=1e-9, atol=1e-12 * s[0])
    # the same system up to the signs of the states: equal Markov parameters and poles
    np.testing.assert_allclose(r.markov_parameters(3 * n_lags)[:, 0, 0],
                               markov(A, B, C, h[:1, None], 3 * n_lags)[:, 0, 0],
                               atol=1e-9 * np.abs(h).max())
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(r.A)),
                               np.sort_complex(np.linalg.eigvals(A)), atol=1e-9)
    # the FRF of the reduced model is within the bound of the FIR's (dense DFT)
    freqs = np.linspace(0.0, 0.5, 301)
    fir = np.exp(-2j * np.pi * freqs[:, None] * np.arange(n_lags)) @ h
    gap = np.abs(r.frequency_response(freqs)[:, 0, 0] - fir).max()
    assert r.error_bound == pytest.approx(2 * s[4:].sum(), rel=1e-9)
    assert gap <= r.error_bound * (1 + 1e-9)


def test_era_chooses_the_order_the_dense_spectrum_gives():
    rng = np.random.default_rng(6)
    h = noisy_two_mode_response(300, rng, noise=1e-5)
    from gpmultirate.realization import select_order

    s = np.linalg.svd(block_hankel(h), compute_uv=False)
    assert era(h).n_states == select_order(s[s > 300 * np.finfo(float).eps * s[0]],
                                           zero_after=False)


def test_leading_era_equals_the_dense_realization_without_forming_the_hankel_matrix():
    rng = np.random.default_rng(7)
    h = noisy_two_mode_response(500, rng)
    r = leading_era(h, 4)
    A, B, C, s = dense_era(h, 4)
    np.testing.assert_allclose(r.hankel_singular_values, s[:4], rtol=1e-9)
    assert np.isnan(r.error_bound)
    np.testing.assert_allclose(r.markov_parameters(800)[:, 0, 0],
                               markov(A, B, C, h[:1, None], 800)[:, 0, 0],
                               atol=1e-9 * np.abs(h).max())


def test_values_of_a_symmetric_hankel_matrix_are_its_eigenvalue_magnitudes():
    # the cheap route for one input and one output rests on this: check it independently
    rng = np.random.default_rng(8)
    c = rng.standard_normal(19)
    H = linalg.hankel(c[:10], c[9:])
    np.testing.assert_allclose(np.sort(np.abs(np.linalg.eigvalsh(H)))[::-1],
                               np.linalg.svd(H, compute_uv=False), rtol=1e-12)


@pytest.mark.parametrize("n_states", [None, 4, 7])
def test_a_long_response_is_reduced_from_its_leading_values_with_a_true_bound(monkeypatch,
                                                                              n_states):
    from gpmultirate import realization

    monkeypatch.setattr(realization, "DENSE_SPECTRUM_SIZE", 200)
    rng = np.random.default_rng(9)
    h = noisy_two_mode_response(420, rng, noise=1e-4)
    r = era(h, n_states)
    assert r.complete and r.tail_bound > 0  # the leading values only
    s = np.linalg.svd(block_hankel(h), compute_uv=False)
    monkeypatch.setattr(realization, "DENSE_SPECTRUM_SIZE", 10**9)
    dense = era(h, n_states)
    assert r.n_states == dense.n_states
    k = r.hankel_singular_values.size
    assert k < s.size // 4
    np.testing.assert_allclose(r.hankel_singular_values, s[:k], rtol=1e-8, atol=1e-13 * s[0])
    # the bound holds the dense one, and the reduced FRF lies within it
    assert dense.error_bound <= r.error_bound
    assert r.tail_bound >= s[k:].sum() * (1 - 1e-9)
    np.testing.assert_allclose(r.markov_parameters(900)[:, 0, 0],
                               dense.markov_parameters(900)[:, 0, 0],
                               atol=1e-8 * np.abs(h).max())
    freqs = np.linspace(0.0, 0.5, 501)
    fir = np.exp(-2j * np.pi * freqs[:, None] * np.arange(h.size)) @ h
    assert np.abs(r.frequency_response(freqs)[:, 0, 0] - fir).max() <= r.error_bound


def test_an_exactly_low_order_long_response_takes_the_dense_route(monkeypatch):
    from gpmultirate import realization

    monkeypatch.setattr(realization, "DENSE_SPECTRUM_SIZE", 200)
    h = np.r_[0.0, 0.9 ** np.arange(419)]  # rank 1 (up to the cut tail)
    r = era(h, 1)
    assert r.n_states == 1 and r.tail_bound == 0.0
    assert r.hankel_singular_values.size == 419
