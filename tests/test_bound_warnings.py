"""A hyperparameter tuned onto a finite bound is reported, as scikit-learn does."""

import warnings

import numpy as np
import pytest
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.kernels import DC


@pytest.fixture(scope="module")
def data():
    system = sim.paper_system(0.1)
    u = sim.multisine(300, random_state=1)
    return sim.simulate_experiment(system, u, 3, snr_db=30, random_state=3)


def fit_recording(model, data):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.fit(data.u, data.y_slow)
    return model, [w for w in caught if issubclass(w.category, ConvergenceWarning)]


def test_interior_optimum_is_silent(data):
    model, caught = fit_recording(gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300), data)
    assert caught == [], [str(w.message) for w in caught]
    theta, bounds = model.optimizer_result_.x, model._evidence.bounds
    # the check that stays silent here does see the distance to each bound
    assert np.all(np.minimum(theta - bounds[:, 0], bounds[:, 1] - theta) > 1e-3)


def test_noise_level_on_its_upper_bound_is_named(data):
    # far below the noise of the data (30 dB): the noise level must end on the bound
    power = float(np.mean(data.y_slow**2))
    model, caught = fit_recording(
        gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300,
                              noise_level=1e-9, noise_level_bounds=(1e-12, 1e-8)),
        data,
    )
    assert model.noise_level_ == pytest.approx(1e-8 * power, rel=1e-3)
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "noise_level" in message and "upper bound" in message
    assert f"{1e-8 * power:.4g}" in message


def test_kernel_hyperparameter_on_its_lower_bound_is_named(data):
    # the system decays far faster than alpha = 0.999 allows
    kernel = C(1.0) * DC(alpha=0.9995, alpha_bounds=(0.999, 1.0))
    model, caught = fit_recording(gm.FIRGaussianProcess(kernel, factor=3, order=300), data)
    assert model.kernel_.k2.alpha == pytest.approx(0.999, rel=1e-6)
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "k2__alpha = 0.999 is on its lower bound 0.999" in message
    assert "noise_level =" not in message


def test_nothing_tuned_nothing_reported(data):
    kernel = C(1.0) * DC(alpha=0.999, alpha_bounds=(0.999, 1.0))
    _, caught = fit_recording(
        gm.FIRGaussianProcess(kernel, factor=3, order=300, optimizer=None), data
    )
    assert caught == []
