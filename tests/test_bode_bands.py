"""Bode bands as projections of the credible ellipse of ``(Re G, Im G)``.

The bands are checked against a dense sampling of the ellipse boundary and of
its interior, the "phase undefined" flag against the Mahalanobis distance of
the origin, and the coverage of true FRFs of two-mass systems against the
coverage of the two-dimensional region, computed here from the Gaussian
summaries alone.
"""

import warnings

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import scipy.stats  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate import simulation  # noqa: E402
from gpmultirate.plotting import plot_bode  # noqa: E402
from gpmultirate.responses import FrequencyResponse  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def random_gaussians(n, rng, degenerate=True):
    """Means and covariances of ``(Re, Im)``: general, and (optionally) rank-one,
    circular and point masses."""
    mean = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    root = rng.standard_normal((n, 2, 2)) * rng.uniform(0.02, 1.5, (n, 1, 1))
    if degenerate:
        k = n // 8
        root[:k, :, 1] = 0.0  # rank one: a segment
        root[k:2 * k] = np.eye(2) * rng.uniform(0.05, 1.0, (k, 1, 1))  # a circle
        root[2 * k:2 * k + 3] = 0.0  # a point
    cov = root @ root.transpose(0, 2, 1)
    return mean, cov


def ellipse_root(cov, level):
    """``sqrt(chi2_2(level))`` times a square root of each ``cov``, by eigendecomposition."""
    c = scipy.stats.chi2.ppf(level, df=2)
    values, vectors = np.linalg.eigh(cov)
    return np.sqrt(c) * vectors * np.sqrt(np.clip(values, 0.0, None))[:, None, :]


def on_boundary(mean, root, t):
    """Points ``mean + root (cos t, sin t)`` of the ellipse boundary, ``t`` of shape (n, k)."""
    xy = np.einsum("nij,njk->nik", root, np.stack([np.cos(t), np.sin(t)], axis=1))
    return mean[:, None] + xy[:, 0] + 1j * xy[:, 1]


def boundary_extreme(mean, root, value, largest, n_points=4000, rounds=3):
    """Brute force: the extreme of ``value(points)`` over a dense sampling of the
    boundary, resampled densely around the best sample a few times."""
    n = mean.shape[0]
    t = np.broadcast_to(np.linspace(0.0, 2 * np.pi, n_points, endpoint=False), (n, n_points))
    step = 2 * np.pi / n_points
    for _ in range(rounds):
        v = value(on_boundary(mean, root, t))
        best = np.argmax(v, axis=1) if largest else np.argmin(v, axis=1)
        centre = t[np.arange(n), best]
        t = centre[:, None] + np.linspace(-2 * step, 2 * step, 401)
        step = 4 * step / 400
    v = value(on_boundary(mean, root, t))
    return v.max(axis=1) if largest else v.min(axis=1)


def ellipse_points(mean, cov, level, n_points, interior_rng=None):
    """Points of the boundary (or, with ``interior_rng``, uniformly of the interior) of
    the ``level`` credible ellipse."""
    root = ellipse_root(cov, level)
    n = mean.shape[0]
    if interior_rng is None:
        t = np.broadcast_to(np.linspace(0.0, 2 * np.pi, n_points, endpoint=False),
                            (n, n_points))
        return on_boundary(mean, root, t)
    t = interior_rng.uniform(0, 2 * np.pi, (n, n_points))
    r = np.sqrt(interior_rng.uniform(0, 1, (n, n_points)))
    return mean[:, None] + (on_boundary(mean, root, t) - mean[:, None]) * r


def from_cov(mean, cov, level=0.95, **kwargs):
    return FrequencyResponse.from_gaussian(np.arange(mean.shape[0], dtype=float), mean,
                                           cov[:, 0, 0], cov[:, 1, 1], cov[:, 0, 1],
                                           level=level, **kwargs)


def mahalanobis_squared(delta, cov):
    """``delta^T cov^+ delta``, infinite when ``delta`` leaves the range of a singular ``cov``."""
    values, vectors = np.linalg.eigh(cov)
    parts = np.einsum("nij,ni->nj", vectors, np.stack([delta.real, delta.imag], axis=1))
    scale = np.max(values, axis=1, keepdims=True)
    null = values <= 1e-12 * scale
    in_null = np.where(null, parts ** 2, 0.0)
    outside = np.any(in_null > 1e-24 * (1.0 + np.abs(delta[:, None]) ** 2), axis=1)
    distance = np.sum(np.where(null, 0.0, parts ** 2 / np.where(null, 1.0, values)), axis=1)
    return np.where(outside, np.inf, distance)


def relative_angle(z, frf):
    """Angle of ``z`` relative to the mean's, in (-pi, pi]."""
    return np.angle(z * np.exp(-1j * frf.phase)[:, None])


# ------------------------------------------------------ ellipse projections
def assert_close(actual, expected, scale, rank_one):
    """Equal to 1e-9 relative; for rank-one covariances to 1e-7 of the scale, as the
    short axis of their ellipse is the square root of a rounding error (about 1e-8)."""
    tolerance = np.where(rank_one, 1e-7 * scale, 1e-9 * np.abs(expected) + 1e-12 * scale)
    error = np.abs(actual - expected)
    assert np.all(error <= tolerance), (np.max(error / tolerance), np.argmax(error / tolerance))


@pytest.mark.parametrize("level", [0.5, 0.95])
def test_bands_are_the_projections_of_the_ellipse_boundary(level):
    rng = np.random.default_rng(3)
    n = 400
    mean, cov = random_gaussians(n, rng)
    rank_one = np.arange(n) < n // 8
    frf = from_cov(mean, cov, level)
    root = ellipse_root(cov, level)
    scale = np.abs(mean) + np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])
    # the largest |z| over the ellipse lies on its boundary
    largest = boundary_extreme(mean, root, np.abs, largest=True)
    assert_close(frf.magnitude_upper, largest, scale, rank_one)
    defined = frf.phase_defined
    assert defined.sum() > 100 and (~defined).sum() > 50
    # outside the ellipse, the smallest |z| does too; inside it is 0
    smallest = boundary_extreme(mean, root, np.abs, largest=False)
    assert_close(frf.magnitude_lower[defined], smallest[defined], scale[defined],
                 rank_one[defined])
    np.testing.assert_array_equal(frf.magnitude_lower[~defined], 0.0)
    # the phase range: the angles of the boundary points, relative to the mean's
    m, r, phase = mean[defined], root[defined], frf.phase[defined]

    def angle(z):
        return np.angle(z * np.exp(-1j * phase)[:, None])

    ones = np.ones(m.shape[0])
    assert_close((frf.phase_lower - frf.phase)[defined],
                 boundary_extreme(m, r, angle, largest=False), ones, rank_one[defined])
    assert_close((frf.phase_upper - frf.phase)[defined],
                 boundary_extreme(m, r, angle, largest=True), ones, rank_one[defined])
    # undefined phase: the whole circle around the mean's phase
    np.testing.assert_allclose((frf.phase_upper - frf.phase)[~defined], np.pi)
    np.testing.assert_allclose((frf.phase_lower - frf.phase)[~defined], -np.pi)


def test_every_point_of_the_region_lies_in_both_bands():
    rng = np.random.default_rng(5)
    mean, cov = random_gaussians(300, rng)
    frf = from_cov(mean, cov, 0.9)
    inside = ellipse_points(mean, cov, 0.9, 2000, interior_rng=rng)
    magnitude = np.abs(inside)
    tol = 1e-9 * (1.0 + np.abs(mean))[:, None]
    assert np.all(magnitude >= frf.magnitude_lower[:, None] - tol)
    assert np.all(magnitude <= frf.magnitude_upper[:, None] + tol)
    angle = relative_angle(inside, frf)
    assert np.all(angle >= (frf.phase_lower - frf.phase)[:, None] - 1e-9)
    assert np.all(angle <= (frf.phase_upper - frf.phase)[:, None] + 1e-9)


def test_circle_has_the_textbook_bands():
    """Uncorrelated equal variances: ``|m| +- r`` and ``+- asin(r / |m|)``."""
    mean = np.array([2.0 * np.exp(1j * 0.3), -1.0j, 0.2 + 0.0j])
    var = np.array([0.04, 0.01, 0.09])
    frf = FrequencyResponse.from_gaussian([0.1, 0.2, 0.3], mean, var, var, np.zeros(3),
                                          level=0.9)
    r = np.sqrt(-2.0 * np.log(0.1) * var)  # chi-square(2) quantile is -2 log(1 - level)
    assert r[2] > 0.2  # the third circle contains 0
    np.testing.assert_array_equal(frf.phase_defined, [True, True, False])
    np.testing.assert_allclose(frf.magnitude_upper, np.abs(mean) + r, rtol=1e-12)
    np.testing.assert_allclose(frf.magnitude_lower, [2.0 - r[0], 1.0 - r[1], 0.0],
                               rtol=1e-12)
    half = np.arcsin(r[:2] / np.abs(mean[:2]))
    np.testing.assert_allclose((frf.phase_upper - frf.phase)[:2], half, rtol=1e-10)
    np.testing.assert_allclose((frf.phase_lower - frf.phase)[:2], -half, rtol=1e-10)


def test_phase_undefined_exactly_where_the_region_contains_zero():
    rng = np.random.default_rng(8)
    mean, cov = random_gaussians(2000, rng, degenerate=False)
    for level in (0.5, 0.95, 0.999):
        frf = from_cov(mean, cov, level)
        contains = mahalanobis_squared(-mean, cov) <= scipy.stats.chi2.ppf(level, df=2)
        np.testing.assert_array_equal(frf.phase_defined, ~contains)
        np.testing.assert_array_equal(frf.magnitude_lower == 0, contains)


def test_point_mass_and_segment():
    # no uncertainty: the bands collapse onto the mean
    frf = FrequencyResponse.from_gaussian([1.0], [3.0 - 4.0j], [0.0], [0.0], [0.0])
    assert frf.magnitude_lower[0] == pytest.approx(5.0) == frf.magnitude_upper[0]
    assert frf.phase_lower[0] == pytest.approx(frf.phase[0]) == frf.phase_upper[0]
    # a segment along the real axis through 0 (the zero frequency of a real FIR)
    frf = FrequencyResponse.from_gaussian([0.0, 0.0], [0.5 + 0j, 3.0 + 0j], [1.0, 1.0],
                                          [0.0, 0.0], [0.0, 0.0])
    half = np.sqrt(scipy.stats.chi2.ppf(0.95, df=2))
    assert 0.5 < half < 3.0
    np.testing.assert_array_equal(frf.phase_defined, [False, True])
    np.testing.assert_allclose(frf.magnitude_lower, [0.0, 3.0 - half])
    np.testing.assert_allclose(frf.magnitude_upper, [0.5 + half, 3.0 + half])
    np.testing.assert_allclose(frf.phase_upper[1] - frf.phase_lower[1], 0.0, atol=1e-12)


def test_caller_arrays_are_not_modified():
    rng = np.random.default_rng(1)
    mean, cov = random_gaussians(20, rng)
    var_r, var_i, cross = cov[:, 0, 0].copy(), cov[:, 1, 1].copy(), cov[:, 0, 1].copy()
    copies = [a.copy() for a in (mean, var_r, var_i, cross)]
    FrequencyResponse.from_gaussian(np.arange(20.0), mean, var_r, var_i, cross)
    for given, kept in zip((mean, var_r, var_i, cross), copies):
        np.testing.assert_array_equal(given, kept)


# ----------------------------------------------------------------- the phase
def test_phase_unwraps_only_where_defined():
    freqs = np.arange(12.0)
    truth = -0.9 * freqs  # a steadily falling phase
    angle = truth.copy()
    angle[4:7] = [2.5, -2.9, 3.0]  # a stretch lost in noise
    mean = np.exp(1j * angle)
    var = np.full(12, 1e-4)
    var[4:7] = 4.0  # the region contains 0 there
    frf = FrequencyResponse.from_gaussian(freqs, mean, var, var, np.zeros(12))
    np.testing.assert_array_equal(frf.phase_defined, ~np.isin(np.arange(12), [4, 5, 6]))
    # the same angle modulo a full turn everywhere
    np.testing.assert_allclose(np.exp(1j * frf.phase), mean, atol=1e-12)
    # before the stretch: unwrapped from the principal value
    np.testing.assert_allclose(frf.phase[:4], truth[:4], atol=1e-12)
    # after it: restarted on the branch nearest the last defined value, not carried
    # along the wraps of the noise
    restart = truth[7] + 2 * np.pi * np.round((truth[3] - truth[7]) / (2 * np.pi))
    np.testing.assert_allclose(frf.phase[7:], restart + (truth[7:] - truth[7]), atol=1e-12)
    assert abs(frf.phase[7] - frf.phase[3]) <= np.pi


def test_repr_is_short_and_constructor_defaults_the_flag():
    n = 50000
    frf = FrequencyResponse.from_gaussian(np.linspace(0, 5, n), np.ones(n, dtype=complex),
                                          np.full(n, 0.01), np.full(n, 0.01), np.zeros(n),
                                          sample_time=0.1, factor=3)
    text = repr(frf)
    assert len(text) < 200
    assert text == ("FrequencyResponse(50000 frequencies in [0, 5] Hz, level=0.95, factor=3, "
                    "sample_time=0.1, phase defined at 50000 of 50000)")
    rebuilt = FrequencyResponse(**{name: getattr(frf, name) for name in (
        "freqs", "mean", "magnitude_lower", "magnitude_upper", "phase_lower", "phase_upper",
        "real_std", "imag_std", "real_imag_corr", "level", "sample_time", "factor")})
    np.testing.assert_array_equal(rebuilt.phase_defined, frf.phase_defined)


def test_frequency_unit():
    one = FrequencyResponse.from_gaussian([0.1], [1.0 + 0j], [0.1], [0.1], [0.0])
    assert one.frequency_unit == "cycles/sample"
    assert "cycles/sample" in repr(one)
    hz = FrequencyResponse.from_gaussian([0.1], [1.0 + 0j], [0.1], [0.1], [0.0],
                                         sample_time=0.01)
    assert hz.frequency_unit == "Hz"


# ------------------------------------------------------------------ coverage
def region_covers(frf, true_frf):
    """Whether the 2-D credible region holds the true FRF, from the Gaussian summaries."""
    cross = frf.real_imag_corr * frf.real_std * frf.imag_std
    cov = np.empty((frf.freqs.shape[0], 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = frf.real_std ** 2, frf.imag_std ** 2
    cov[:, 0, 1] = cov[:, 1, 0] = cross
    distance = mahalanobis_squared(true_frf - frf.mean, cov)
    contains_zero = mahalanobis_squared(-frf.mean, cov)
    c = scipy.stats.chi2.ppf(frf.level, df=2)
    return distance <= c, contains_zero <= c


SYSTEMS = {
    "paper": lambda: simulation.paper_system(0.1),
    "two-mass A": lambda: simulation.paper_system(0.1, perturbation=0.1, random_state=1),
    "two-mass B": lambda: simulation.paper_system(0.1, perturbation=0.1, random_state=2),
}


@pytest.fixture(scope="module")
def fits():
    """FIRGaussianProcess fits, N = 600, F = 3, 5 % output noise, two seeds per system."""
    results = []
    for name, make in SYSTEMS.items():
        system = make()
        for seed in (0, 1):
            rng = np.random.default_rng(seed)
            u = rng.standard_normal(600)
            y = system.simulate(u)
            y_slow = y[::3] + 0.05 * np.std(y) * rng.standard_normal(200)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                model = gm.FIRGaussianProcess(factor=3, order=600, sample_time=0.1)
                model.fit(u, y_slow)
            frf = model.frequency_response()
            results.append((name, seed, frf, system.frequency_response(frf.freqs)))
    return results


@pytest.mark.slow
def test_bands_cover_the_truth_wherever_the_region_does(fits):
    totals = {"below": np.zeros(3), "above": np.zeros(3)}
    for name, seed, frf, true_frf in fits:
        region, contains_zero = region_covers(frf, true_frf)
        np.testing.assert_array_equal(frf.phase_defined, ~contains_zero, err_msg=name)
        magnitude = np.abs(true_frf)
        in_magnitude = ((frf.magnitude_lower <= magnitude * (1 + 1e-9))
                        & (magnitude <= frf.magnitude_upper * (1 + 1e-9)))
        angle = np.angle(true_frf * np.exp(-1j * frf.phase))
        in_phase = ~frf.phase_defined | (
            (frf.phase_lower - frf.phase - 1e-9 <= angle)
            & (angle <= frf.phase_upper - frf.phase + 1e-9))
        # frequency by frequency: region holds the truth => both bands hold it
        assert np.all(in_magnitude[region]), (name, seed)
        assert np.all(in_phase[region]), (name, seed)
        below = frf.freqs < frf.slow_nyquist
        for side, where in (("below", below), ("above", ~below)):
            assert in_magnitude[where].mean() >= region[where].mean(), (name, seed, side)
            assert in_phase[where].mean() >= region[where].mean(), (name, seed, side)
            totals[side] += [region[where].sum(), in_magnitude[where].sum(), where.sum()]
    for side, (region_hits, magnitude_hits, n) in totals.items():
        # the region is calibrated roughly (empirical Bayes), the bands at least as well
        assert region_hits / n > 0.85, (side, region_hits / n)
        assert magnitude_hits >= region_hits


# ------------------------------------------------------------------ the plot
@pytest.fixture
def patchy():
    """An FRF whose region contains 0 at frequencies 3..5 and 9."""
    freqs = np.linspace(0.0, 5.0, 11)
    mean = np.exp(-1j * 0.6 * freqs) * np.linspace(1.0, 0.3, 11)
    var = np.full(11, 1e-3)
    var[[3, 4, 5, 9]] = 1.0
    return FrequencyResponse.from_gaussian(freqs, mean, var, var, np.zeros(11), level=0.9,
                                           sample_time=0.1, factor=3)


def test_plot_shades_undefined_phase_and_labels_every_band(patchy):
    bode = plot_bode(patchy, label="PK")
    ax_mag, ax_phase = bode.axes
    labels = [t.get_text() for t in ax_mag.get_legend().get_texts()]
    assert labels == ["PK", "PK, 90 % band", "PK: phase undefined"]
    # one hatched span per undefined stretch, from mid-bin to mid-bin
    spans = bode.phase_undefined_spans
    assert len(spans) == 2 and all(span in ax_phase.patches for span in spans)
    extents = [tuple(np.round(span.get_x() + np.array([0.0, span.get_width()]), 12))
               for span in spans]
    assert extents == [(1.25, 2.75), (4.25, 4.75)]
    assert all(span.get_hatch() for span in spans)
    # no phase line where the phase is undefined, and no phase band there
    ydata = bode.phase_line.get_ydata()
    np.testing.assert_array_equal(np.isnan(ydata), ~patchy.phase_defined)
    x_band = np.concatenate([p.vertices[:, 0] for p in bode.phase_band.get_paths()])
    assert not np.any(np.isin(np.round(x_band, 9), patchy.freqs[~patchy.phase_defined]))
    # where the band reaches 0 its lower edge is 20 dB below the magnitude at that
    # frequency (not a floor shared by all frequencies: no comb of spikes)
    mag_db = 20 * np.log10(patchy.magnitude)
    mag_vertices = np.concatenate([p.vertices for p in bode.magnitude_band.get_paths()])
    for f, m in zip(patchy.freqs, mag_db):
        lowest = mag_vertices[np.isclose(mag_vertices[:, 0], f), 1].min()
        assert lowest >= m - 20 - 1e-9
    for f, m in zip(patchy.freqs[~patchy.phase_defined], mag_db[~patchy.phase_defined]):
        assert np.isclose(mag_vertices[np.isclose(mag_vertices[:, 0], f), 1].min(), m - 20)
    assert not bode.magnitude_band.sticky_edges.y
    assert ax_phase.get_xlabel() == "frequency [Hz]"


def test_overlays_get_distinct_colours_and_hatches(patchy):
    first = plot_bode(patchy, label="DC")
    second = plot_bode(patchy, axes=first.axes, label="PK")
    assert first.magnitude_line.get_color() != second.magnitude_line.get_color()
    assert (first.magnitude_band.get_facecolor()[0][:3].tolist()
            != second.magnitude_band.get_facecolor()[0][:3].tolist())
    hatches = [drawn.phase_undefined_spans[0].get_hatch() for drawn in (first, second)]
    assert hatches[0] != hatches[1]
    labels = [t.get_text() for t in first.axes[0].get_legend().get_texts()]
    assert labels == ["DC", "DC, 90 % band", "PK", "PK, 90 % band",
                      "DC: phase undefined", "PK: phase undefined"]
    # neither band pins the axes to a floor
    assert not second.magnitude_band.sticky_edges.y and not first.magnitude_band.sticky_edges.y


def test_unlabelled_estimate_and_default_unit():
    frf = FrequencyResponse.from_gaussian(np.linspace(0, 0.5, 6), np.ones(6, dtype=complex),
                                          np.full(6, 1e-3), np.full(6, 1e-3), np.zeros(6))
    bode = plot_bode(frf)
    labels = [t.get_text() for t in bode.axes[0].get_legend().get_texts()]
    assert labels == ["estimate", "estimate, 95 % band"]
    assert bode.phase_undefined_spans == []
    assert bode.axes[1].get_xlabel() == "frequency [cycles/sample]"
    with pytest.raises(ValueError, match="label"):
        plot_bode(frf, label=3)


def test_true_phase_is_aligned_per_defined_stretch(patchy):
    # a true FRF that winds one extra turn across the first undefined stretch (3..5)
    extra = np.clip(np.arange(11) - 2, 0, 4) * (np.pi / 2)
    true_frf = patchy.mean * np.exp(-1j * extra)
    bode = plot_bode(patchy, true_frf=true_frf)
    x, y = bode.true_phase_line.get_xdata(), bode.true_phase_line.get_ydata()
    unwrapped = np.degrees(np.unwrap(np.angle(true_frf)))
    estimate = np.degrees(patchy.phase)
    defined = patchy.phase_defined
    # each defined stretch of the truth is drawn on the estimate's branch
    drawn = np.array([y[np.isfinite(y) & (x == f)][0] for f in patchy.freqs])
    np.testing.assert_allclose(drawn[defined], estimate[defined] - np.degrees(extra)[defined]
                               + np.where(np.arange(11) >= 6, 360.0, 0.0)[defined],
                               atol=1e-9)
    # shifted by whole turns only, with the line broken where the shift changes
    shift = drawn - unwrapped
    np.testing.assert_allclose(shift, 360.0 * np.round(shift / 360.0), atol=1e-9)
    assert np.isnan(y).sum() == np.count_nonzero(np.diff(shift))
