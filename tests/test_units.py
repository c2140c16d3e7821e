"""The tuned fit does not depend on the units of u and y, for the kernels the docs show.

With ``normalize=True`` (the default) a user kernel's amplitudes, the initial
noise level and explicit noise bounds are read in normalized units, so
scaling ``u`` by ``a`` and ``y`` by ``b`` must scale every result by
``b / a`` (impulse response, frequency response and its bands) and leave the
validation goodness of fit unchanged.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.kernels import DC, PK, SS, TC

T = 0.1
SCALES = (1e-8, 1e-3, 1.0, 1e3, 1e8)
KERNELS = {
    # README and user guide: lambda * DC, plus a PK resonance given in Hz
    "README": lambda: C(1.0) * DC(alpha=0.95, beta=0.99) + PK.from_hz(2.0, sample_time=T,
                                                                        alpha=0.95),
    "C*DC": lambda: C(1.0) * DC(alpha=0.95, beta=0.99),
    "C*DC beta fixed": lambda: C(1.0) * DC(alpha=0.95, beta=0.99, beta_bounds="fixed"),
    "C*TC": lambda: C(1.0) * TC(alpha=0.95),
    "C*SS": lambda: C(1.0) * SS(alpha=0.95),
    "bare DC": lambda: DC(alpha=0.95, beta=0.99),
}


@pytest.fixture(scope="module")
def data():
    system = sim.paper_system(T)
    u = sim.multisine(300, random_state=1)
    experiment = sim.simulate_experiment(system, u, 3, snr_db=50, random_state=2)
    u_val = sim.multisine(300, random_state=3)
    return experiment.u, experiment.y_slow, u_val, system.simulate(u_val)


def fit(kernel, u, y):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning in any units
        # the README's kernel cuts the paper system at order 150: a misspecified fit in
        # every unit, which the scaled fits must say alike (check_scaled)
        warnings.simplefilter("ignore", gm.MisspecificationWarning)
        return gm.FIRGaussianProcess(kernel, factor=3, order=150, noise_level=1e-4,
                                     sample_time=T).fit(u, y)


def check_scaled(name, data, u_scale, y_scale, reference=None):
    u, y, u_val, y_val = data
    reference = reference or fit(KERNELS[name](), u, y)
    scaled = fit(KERNELS[name](), u * u_scale, y * y_scale)
    ratio = y_scale / u_scale
    assert (scaled.misspecification_ is None) == (reference.misspecification_ is None)
    assert scaled.score(u_val * u_scale, y_val * y_scale) == pytest.approx(
        reference.score(u_val, y_val), abs=0.1)
    frf, frf_scaled = reference.frequency_response(), scaled.frequency_response()
    top = np.max(frf.magnitude_upper)
    for a, b in ((frf.magnitude_lower, frf_scaled.magnitude_lower),
                 (frf.magnitude_upper, frf_scaled.magnitude_upper)):
        np.testing.assert_allclose(b / ratio, a, rtol=2e-2, atol=1e-3 * top)
    mean, std = reference.impulse_response([0.5, 7.25], return_std=True)
    mean_s, std_s = scaled.impulse_response([0.5, 7.25], return_std=True)
    np.testing.assert_allclose(mean_s / ratio, mean, rtol=2e-2, atol=1e-3 * np.abs(mean).max())
    np.testing.assert_allclose(std_s / ratio, std, rtol=5e-2)
    return reference


@pytest.mark.parametrize("name", list(KERNELS))
def test_metres_and_micro_units(name, data):
    # a wafer stage in metres driven in millinewtons, and the reverse
    reference = check_scaled(name, data, 1e3, 1e-7)
    check_scaled(name, data, 1e-3, 1e6, reference)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(KERNELS))
def test_every_pair_of_scales(name, data):
    # the extreme and unit scales of u and y in every pair (ratios y / u from 1e-16 to
    # 1e16), and each interior scale of u with the reverse of y (11 of the 25 pairs; the
    # quick test above takes 1e3 with 1e-7 and 1e-3 with 1e6)
    reference = None
    ends = (SCALES[0], 1.0, SCALES[-1])
    for u_scale in SCALES:
        for y_scale in SCALES:
            if (u_scale in ends and y_scale in ends) or u_scale * y_scale == 1.0:
                reference = check_scaled(name, data, u_scale, y_scale, reference)


def test_data_units_are_the_documented_alternative(data):
    u, y, _, _ = data
    # in the data's units the README kernel is a prior of amplitude 1 in u -> y units
    given = gm.FIRGaussianProcess(KERNELS["C*DC"](), factor=3, order=150, optimizer=None)
    given.fit(u * 1e3, y * 1e-7)
    assert given.kernel_.k1.constant_value == 1.0
    normalized = gm.FIRGaussianProcess(KERNELS["C*DC"](), factor=3, order=150)
    normalized.fit(u * 1e3, y * 1e-7)
    assert normalized.kernel_.k1.constant_value < 1e-12  # (1e-7 / 1e3)^2 times the tuned value
