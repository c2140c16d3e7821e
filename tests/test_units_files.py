"""Models whose hyperparameters stay in normalized units: files, fit report, default order.

Where an amplitude or the noise variance is beyond the float range in the
data's units (``u`` of size ``1e-300`` and ``y_slow`` of size 1: an amplitude
near ``1e600``), ``kernel_`` and ``noise_level_`` stay in the units of the
normalized data (``hyperparameter_units_ == "normalized"``).  Such a model
must save and load with the same predictions, and its fit report must give
the noise in the data's units.  The data-driven default order (records
longer than ``orders.SHORT_RECORD``) must not depend on the units either.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate import orders
from gpmultirate.exceptions import ModelFileError
from gpmultirate.report import fit_report

N, FACTOR, ORDER = 90, 3, 15
G = 0.8 ** np.arange(ORDER) * np.cos(0.6 * np.arange(ORDER))


def _data(n=N, noise=1e-2, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y_slow = np.convolve(u, G)[:n][::FACTOR] + noise * rng.standard_normal(len(range(0, n, FACTOR)))
    return u, y_slow


def _quiet(function):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function()


def _normalized_model(u, y, **fit_kwargs):
    model = _quiet(lambda: gm.FIRGaussianProcess(factor=FACTOR, order=ORDER).fit(
        u, y, **fit_kwargs))
    assert model.hyperparameter_units_ == "normalized"
    return model


@pytest.mark.parametrize("layout", ["downsampled", "records"])
def test_a_model_in_normalized_units_saves_and_loads(tmp_path, layout):
    u, y = _data()
    tiny = u * 1e-300
    kwargs = {} if layout == "downsampled" else {"sample_indices": np.arange(0, N, FACTOR)}
    model = _normalized_model(tiny, y, **kwargs)
    path = tmp_path / "model.npz"
    gm.save_model(model, path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning: the stored model had its units
        loaded = gm.load_model(path)
    assert loaded.hyperparameter_units_ == "normalized"
    np.testing.assert_array_equal(loaded.input_scale_, model.input_scale_)
    assert loaded.output_scale_ == model.output_scale_
    np.testing.assert_array_equal(loaded.kernel_.theta, model.kernel_.theta)
    assert loaded.noise_level_ == model.noise_level_
    assert loaded.noise_level_bounds_ == model.noise_level_bounds_
    assert loaded.log_marginal_likelihood_value_ == model.log_marginal_likelihood_value_
    np.testing.assert_array_equal(loaded.coef_, model.coef_)
    mean, std = model.predict(tiny, return_std=True)
    loaded_mean, loaded_std = loaded.predict(tiny, return_std=True)
    np.testing.assert_array_equal(loaded_mean, mean)
    np.testing.assert_array_equal(loaded_std, std)
    assert np.all(np.isfinite(std)) and np.all(std > 0)
    np.testing.assert_array_equal(loaded.impulse_response(np.linspace(0, 5, 11)),
                                  model.impulse_response(np.linspace(0, 5, 11)))
    # the parameters are the user's again: a refit is the model
    assert loaded.normalize is True and loaded.optimizer == "marginal_likelihood"
    refit = _normalized_model(tiny, y, **kwargs)
    np.testing.assert_array_equal(refit.coef_, model.coef_)


def test_a_multi_output_model_in_normalized_units_saves_and_loads(tmp_path):
    u, y = _data()
    tiny = u * 1e-300
    Y = np.column_stack([y, 2.0 * y])
    model = _quiet(lambda: gm.MultiOutputFIR(
        gm.FIRGaussianProcess(factor=FACTOR, order=ORDER)).fit(tiny, Y))
    assert all(e.hyperparameter_units_ == "normalized" for e in model.estimators_)
    path = tmp_path / "multi.npz"
    gm.save_model(model, path)
    loaded = _quiet(lambda: gm.load_model(path))
    np.testing.assert_array_equal(loaded.predict(tiny), model.predict(tiny))


def test_a_file_whose_data_are_not_in_the_stored_units_is_refused(tmp_path):
    from gpmultirate import persistence

    u, y = _data()
    model = _normalized_model(u * 1e-300, y)
    header, arrays = persistence._single_members(model)
    fitted = header["fitted"]
    assert fitted["hyperparameter_units_"] == "normalized"
    assert fitted["input_scale_exponents"] == [int(np.frexp(model.input_scale_[0])[1] - 1)]
    wrong = dict(fitted, output_scale_exponent=fitted["output_scale_exponent"] + 1)
    with pytest.raises(ModelFileError, match="not in the units of its normalized"):
        persistence._fit_stored(
            dict(model.get_params(), kernel=model.kernel_, noise_level=model.noise_level_,
                 noise_level_bounds=model.noise_level_bounds_, optimizer=None,
                 normalize=False),
            wrong, arrays["u"], arrays["y_slow"])
    with pytest.raises(ModelFileError, match="hyperparameter_units_"):
        persistence._fit_stored({}, dict(fitted, hyperparameter_units_="metres"), None, None)


def test_the_fit_report_gives_the_noise_in_the_data_units():
    u, y = _data()
    reference = _quiet(lambda: gm.FIRGaussianProcess(factor=FACTOR, order=ORDER).fit(u, y))
    # a power of two: the normalized problem is the reference's bit for bit, and
    # the noise of y_slow (unscaled) is the reference's noise
    model = _normalized_model(np.ldexp(u, -996), y)
    assert model.noise_level_ != reference.noise_level_  # stored in normalized units
    report = fit_report(model)
    assert report.model["hyperparameter_units"] == "normalized"
    assert report.model["noise_std"] == pytest.approx(math.sqrt(reference.noise_level_),
                                                      rel=1e-12)
    assert report.model["noise_level"] == pytest.approx(reference.noise_level_, rel=1e-12)
    assert "hyperparameter_units" not in fit_report(reference).model
    assert "noise_std" not in fit_report(reference).model
    assert fit_report(reference).model["noise_level"] == reference.noise_level_
    page = report.to_markdown()
    assert f"(std {math.sqrt(reference.noise_level_):.6g})" in page
    assert "normalized units" in page


def test_the_fit_report_gives_a_noise_std_whose_variance_overflows():
    u, y = _data()
    reference = _quiet(lambda: gm.FIRGaussianProcess(factor=FACTOR, order=ORDER).fit(u, y))
    # y of size 2**600: the noise variance (near 2**1200 * 1e-4) is no float, the
    # coefficients (near 2**600) are
    model = _normalized_model(u, np.ldexp(y, 600))
    report = fit_report(model)
    std = report.model["noise_std"]
    assert std == pytest.approx(math.ldexp(math.sqrt(reference.noise_level_), 600), rel=1e-12)
    summary = json.loads(report.to_json())
    assert summary["model"]["noise_level"] is None and summary["model"]["noise_std"] == std
    assert "beyond the float range" in report.to_markdown()
    assert f"(std {std:.6g})" in report.to_markdown()


@pytest.mark.slow
def test_the_command_line_prints_the_noise_std_in_the_data_units(tmp_path, capsys):
    from gpmultirate.cli import main

    u, y = _data()
    y_fast = np.full(N, np.nan)
    y_fast[::FACTOR] = y
    printed = {}
    for name, x in (("unit", u), ("tiny", np.ldexp(u, -996))):
        data = tmp_path / f"{name}.csv"
        lines = ["u,y"] + [f"{float(a)!r},{'' if np.isnan(b) else repr(float(b))}"
                           for a, b in zip(x, y_fast)]
        data.write_text("\n".join(lines) + "\n")
        out = tmp_path / name
        assert main(["fit", str(data), "--input", "u", "--output", "y", "--order", str(ORDER),
                     "--out", str(out), "--quiet"]) == 0
        printed[name] = capsys.readouterr().out
    # the same normalized problem: the same noise of y in its own units
    noise = [line for line in printed["unit"].strip().split(", ") if line.startswith("noise std")]
    assert noise and noise[0] in printed["tiny"]
    loaded = _quiet(lambda: gm.load_model(tmp_path / "tiny" / "model.npz"))
    assert loaded.hyperparameter_units_ == "normalized"
    unit = _quiet(lambda: gm.load_model(tmp_path / "unit" / "model.npz"))
    assert noise[0] == f"noise std {math.sqrt(unit.noise_level_):.4g}"


def _long_record():
    n = orders.SHORT_RECORD + 400
    rng = np.random.default_rng(3)
    u = rng.standard_normal(n)
    g = 0.9 ** np.arange(60) * np.cos(0.4 * np.arange(60))
    y_slow = np.convolve(u, g)[:n][::4] + 0.05 * rng.standard_normal(len(range(0, n, 4)))
    return u, y_slow


@pytest.mark.slow
def test_the_default_order_of_a_long_record_does_not_depend_on_the_units():
    u, y = _long_record()
    fit = lambda a, b: _quiet(lambda: gm.FIRGaussianProcess(factor=4).fit(a, b))  # noqa: E731
    reference = fit(u, y)
    assert reference.order_selection_["criterion"] == "prior_tail"
    assert reference.coef_.shape[-1] < u.shape[0]  # the rule chose a shorter order
    # powers of two: the same normalized problem, every result scaled bit for bit
    scaled = fit(np.ldexp(u, -300), np.ldexp(y, 400))
    assert scaled.coef_.shape == reference.coef_.shape
    np.testing.assert_array_equal(scaled.coef_, np.ldexp(reference.coef_, 700))
    np.testing.assert_array_equal(scaled.order_selection_["order"],
                                  reference.order_selection_["order"])
    np.testing.assert_array_equal(scaled.order_selection_["score"],
                                  reference.order_selection_["score"])
    # powers of ten: the same order, the coefficients to the tuning's tolerance
    tens = fit(u * 1e-200, y * 1e100)
    assert tens.coef_.shape == reference.coef_.shape
    np.testing.assert_allclose(tens.coef_ / 1e300, reference.coef_,
                               rtol=1e-3, atol=1e-3 * np.abs(reference.coef_).max())
