"""Tests of gpmultirate.persistence: portable model files and pickling.

The checksum of the file format is recomputed here from its documented
definition (hashlib on the canonical JSON and the array bytes), independently
of the module, to forge valid files that differ in one header entry.
"""

import hashlib
import io
import json
import os
import pickle
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import OptimizeResult
from sklearn.exceptions import NotFittedError
from sklearn.gaussian_process.kernels import RBF, DotProduct, Exponentiation, ExpSineSquared
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import Kernel, Matern, PairwiseKernel, RationalQuadratic
from sklearn.gaussian_process.kernels import WhiteKernel

import gpmultirate
from gpmultirate import FIRGaussianProcess, LeastSquaresFIR
from gpmultirate.covariance.posteriors import GaussianCoefficients
from gpmultirate.kernels import DC, PK, SS, TC
from gpmultirate.observations import DownsampledConvolution
from gpmultirate.persistence import (
    ModelFileError,
    describe_kernel,
    kernel_from_description,
    load_model,
    save_model,
)

FACTOR, ORDER = 3, 30


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(90)
    lags = np.arange(ORDER)
    g = 0.85**lags * np.cos(0.6 * lags)
    y_slow = np.convolve(u, g)[:90][::FACTOR] + 0.01 * rng.standard_normal(30)
    return u, y_slow


MODELS = {
    "C*DC tuned": lambda: FIRGaussianProcess(C(1.0) * DC(), factor=FACTOR, order=ORDER),
    "DC+PK sum": lambda: FIRGaussianProcess(
        C(1.0) * DC(alpha=0.8, beta=0.7) + PK(alpha=0.9, omega=0.6),
        factor=FACTOR, order=ORDER, noise_level=1e-4, optimizer=None,
    ),
    "TC tuned, fixed noise, offset": lambda: FIRGaussianProcess(
        C(0.5) * TC(0.85), factor=FACTOR, order=ORDER, offset=1,
        noise_level=1e-4, noise_level_bounds="fixed",
    ),
    "SS, RandomState": lambda: FIRGaussianProcess(
        C(1.0) * SS(0.9), factor=FACTOR, order=ORDER, noise_level_bounds=(1e-6, 1.0),
        n_restarts_optimizer=1, random_state=np.random.RandomState(3),
    ),
    "RBF inside, tuned": lambda: FIRGaussianProcess(
        C(1.0) * DC() * RBF(20.0, (1.0, 1e3)), factor=FACTOR, order=ORDER, random_state=7
    ),
    "sklearn kernels": lambda: FIRGaussianProcess(
        C(1.0) * DC() * RBF(np.array([15.0]))
        + Exponentiation(Matern(8.0, nu=2.5), 2.0) * C(0.01)
        + WhiteKernel(1e-6, "fixed"),
        factor=FACTOR, noise_level=1e-3, optimizer=None,
    ),
    "default kernel": lambda: FIRGaussianProcess(factor=FACTOR, order=ORDER),
    "least squares": lambda: LeastSquaresFIR(factor=FACTOR, order=10, offset=2),
}


@pytest.fixture(scope="module")
def fitted(data):
    u, y_slow = data
    return {name: make().fit(u, y_slow) for name, make in MODELS.items()}


def reference_checksum(header, arrays):
    """SHA-256 exactly as the module docstring defines it."""
    digest = hashlib.sha256()
    content = {key: value for key, value in header.items() if key != "sha256"}
    digest.update(json.dumps(content, sort_keys=True, separators=(",", ":")).encode() + b"\n")
    for name in sorted(arrays):
        a = arrays[name]
        digest.update(f"{name}:{a.dtype.str}:{','.join(map(str, a.shape))}\n".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


def read_members(path):
    with np.load(path, allow_pickle=False) as archive:
        members = {key: archive[key] for key in archive.files}
    return json.loads(bytes(members.pop("header")).decode("utf-8")), members


def write_members(path, header, members):
    encoded = np.frombuffer(json.dumps(header).encode("utf-8"), dtype=np.uint8)
    with open(path, "wb") as file:
        np.savez(file, header=encoded, **members)


def rewrite(path, edit, rehash=True):
    """Apply ``edit(header, members)`` to a model file, with a valid checksum if ``rehash``."""
    header, members = read_members(path)
    edit(header, members)
    if rehash:
        header["sha256"] = reference_checksum(header, members)
    write_members(path, header, members)


@pytest.fixture
def saved(fitted, tmp_path):
    path = tmp_path / "model.npz"
    save_model(fitted["C*DC tuned"], path)
    return path


# ------------------------------------------------------------ comparisons
def assert_same(a, b, where):
    """Recursive bitwise comparison of fitted state."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype, where
        np.testing.assert_array_equal(a, b, err_msg=where, strict=True)
    elif isinstance(a, Kernel):
        assert a == b and repr(a) == repr(b), where
    elif isinstance(a, DownsampledConvolution):
        assert a == b, where
        np.testing.assert_array_equal(a.matrix, b.matrix, err_msg=where)
        assert not b.u.flags.writeable, where
    elif isinstance(a, OptimizeResult):
        # a file keeps the plain-data fields; a pickle keeps everything
        assert set(b) <= set(a) and {"x", "fun", "success", "message"} <= set(b), where
        for key in set(b) - {"hess_inv"}:
            assert_same(a[key], b[key], f"{where}[{key}]")
    elif isinstance(a, np.random.RandomState):
        for x, y in zip(a.get_state(), b.get_state()):
            assert_same(np.asarray(x), np.asarray(y), where)
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif hasattr(a, "__dict__") and not isinstance(a, type):
        assert type(a) is type(b), where
        if isinstance(a, GaussianCoefficients):  # the prior's K, made when first asked for
            a.K, b.K
        assert sorted(vars(a)) == sorted(vars(b)), where
        for key in vars(a):
            assert_same(vars(a)[key], vars(b)[key], f"{where}.{key}")
    else:
        assert a == b or (a != a and b != b), f"{where}: {a!r} != {b!r}"


def assert_same_model(original, loaded, u):
    assert type(loaded) is type(original)
    assert_same(original, loaded, "model")  # every attribute fit sets, bitwise
    params = original.get_params(deep=True)
    assert sorted(loaded.get_params(deep=True)) == sorted(params)
    for key, value in params.items():
        assert_same(value, loaded.get_params(deep=True)[key], f"get_params()[{key!r}]")
    u_new = np.sin(0.3 * np.arange(70)) + np.cos(1.7 * np.arange(70))
    for signal in (u, u_new):
        np.testing.assert_array_equal(loaded.predict(signal), original.predict(signal))
        for x, y in zip(loaded.predict(signal, return_std=True), original.predict(signal, True)):
            np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(loaded.coef_, original.coef_)
    freqs = [0.02, 0.2, 0.45]
    frf_a, frf_b = original.frequency_response(freqs), loaded.frequency_response(freqs)
    np.testing.assert_array_equal(frf_a.mean, frf_b.mean)
    np.testing.assert_array_equal(frf_a.magnitude_upper, frf_b.magnitude_upper)
    if isinstance(original, FIRGaussianProcess):
        assert loaded.log_marginal_likelihood_value_ == original.log_marginal_likelihood_value_
        lags = np.array([0.0, 0.25, 1.5, 7.3, 29.9])
        np.testing.assert_array_equal(
            loaded.impulse_response(lags), original.impulse_response(lags)
        )
        for kw in ({"return_std": True}, {"return_cov": True}):
            pairs = zip(loaded.impulse_response(lags, **kw), original.impulse_response(lags, **kw))
            for x, y in pairs:
                np.testing.assert_array_equal(x, y)
        theta = original.kernel_.theta * 1.01
        if not isinstance(original.noise_level_bounds_, str):
            theta = np.append(theta, np.log(original.noise_level_))
        assert loaded.log_marginal_likelihood(theta) == original.log_marginal_likelihood(theta)


# -------------------------------------------------------------- round trips
@pytest.mark.parametrize("name", MODELS)
def test_file_round_trip_is_bitwise_identical(name, fitted, data, tmp_path):
    path = tmp_path / "model.npz"
    save_model(fitted[name], path)
    loaded = load_model(path)
    assert_same_model(fitted[name], loaded, data[0])


@pytest.mark.parametrize("name", MODELS)
def test_pickle_round_trip_is_bitwise_identical(name, fitted, data):
    loaded = pickle.loads(pickle.dumps(fitted[name]))
    assert_same_model(fitted[name], loaded, data[0])


def test_loaded_model_refits_like_the_original(fitted, data, tmp_path):
    """The restored constructor parameters (kernel as given, optimizer) drive a refit."""
    save_model(fitted["C*DC tuned"], tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz")
    assert loaded.optimizer == "marginal_likelihood" and loaded.kernel == C(1.0) * DC()
    refit = loaded.fit(*data)
    np.testing.assert_array_equal(refit.coef_, fitted["C*DC tuned"].coef_)


def test_loaded_file_survives_pickle_and_resave(fitted, data, tmp_path):
    original = fitted["DC+PK sum"]
    save_model(original, tmp_path / "a.npz")
    again = pickle.loads(pickle.dumps(load_model(tmp_path / "a.npz")))
    save_model(again, tmp_path / "b.npz")
    assert_same_model(original, load_model(tmp_path / "b.npz"), data[0])


def test_path_is_used_as_given_and_file_objects_work(fitted, data, tmp_path):
    path = tmp_path / "model.gpm"
    save_model(fitted["TC tuned, fixed noise, offset"], str(path))
    assert os.listdir(tmp_path) == ["model.gpm"]
    buffer = io.BytesIO()
    save_model(fitted["least squares"], buffer)
    buffer.seek(0)
    assert_same_model(fitted["least squares"], load_model(buffer), data[0])
    assert_same_model(fitted["TC tuned, fixed noise, offset"], load_model(path), data[0])


def test_header_holds_plain_metadata(saved, fitted):
    header, members = read_members(saved)
    model = fitted["C*DC tuned"]
    assert header["format"] == "gpmultirate-model" and header["format_version"] == 1
    assert header["library_version"] == gpmultirate.__version__
    assert header["estimator"] == "FIRGaussianProcess"
    assert header["fitted"]["noise_level_"] == model.noise_level_
    assert header["fitted"]["kernel_"]["class"] == "Product"
    assert header["fitted"]["kernel_"]["k2"]["params"]["alpha"] == model.kernel_.k2.alpha
    assert (header["fitted"]["factor"], header["fitted"]["order"]) == (FACTOR, ORDER)
    assert sorted(members) == ["coef", "u", "y_slow"]
    assert all(a.dtype == np.dtype("<f8") for a in members.values())
    assert header["sha256"] == reference_checksum(header, members)


def test_caller_arrays_and_model_untouched(data, tmp_path):
    u, y_slow = (a.copy() for a in data)
    model = FIRGaussianProcess(C(1.0) * DC(), factor=FACTOR, order=ORDER, optimizer=None)
    model.fit(u, y_slow)
    before = pickle.dumps(model)
    save_model(model, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz")
    np.testing.assert_array_equal(u, data[0])
    np.testing.assert_array_equal(y_slow, data[1])
    assert u.flags.writeable and y_slow.flags.writeable
    assert pickle.dumps(model) == before
    assert not np.shares_memory(loaded.coef_, model.coef_)


# ------------------------------------------------------------- kernels
ALL_KERNELS = [
    C(2.0, "fixed") * TC(0.7) + SS(0.95, alpha_bounds="fixed"),
    PK.from_hz(2.0, 0.1, alpha=0.9, sigma2=0.5) + DC(0.6, 0.4) ** 2,
    RationalQuadratic(3.0, 0.5) * ExpSineSquared(2.0, 9.0) + DotProduct(0.3),
    Matern(np.array([4.0]), nu=1.5) + WhiteKernel(0.01),
]


@pytest.mark.parametrize("kernel", ALL_KERNELS, ids=repr)
def test_every_whitelisted_kernel_round_trips(kernel):
    tree = json.loads(json.dumps(describe_kernel(kernel), allow_nan=False))
    rebuilt = kernel_from_description(tree)
    assert rebuilt == kernel
    lags = np.array([[0.0], [0.5], [3.0], [10.25]])
    np.testing.assert_array_equal(rebuilt(lags), kernel(lags))
    np.testing.assert_array_equal(rebuilt.bounds, kernel.bounds)


@settings(max_examples=30, deadline=None)
@given(
    alpha=st.floats(1e-4, 1.0, exclude_min=True),
    beta=st.floats(1e-4, 1.0, exclude_min=True),
    scale=st.floats(1e-300, 1e300),
)
def test_hyperparameters_are_stored_exactly(alpha, beta, scale):
    kernel = C(scale, (scale / 10, np.inf)) * DC(alpha, beta)
    rebuilt = kernel_from_description(json.loads(json.dumps(describe_kernel(kernel))))
    assert rebuilt.k1.constant_value == scale and rebuilt.k1.constant_value_bounds[1] == np.inf
    assert (rebuilt.k2.alpha, rebuilt.k2.beta) == (alpha, beta)


class CustomDC(DC):
    pass


# a kernel class of one's own that takes the name of one of the library's
ShadowDC = type("DC", (DC,), {})


def test_unsupported_kernel_or_parameter_refused_at_save(data, tmp_path):
    # a kernel of one's own is stored by name (see the user-kernel tests below),
    # unless its name is that of a library kernel, which a file could not tell apart
    model = FIRGaussianProcess(ShadowDC(), factor=FACTOR, order=ORDER, optimizer=None).fit(*data)
    with pytest.raises(ValueError, match="DC.*name of its own"):
        save_model(model, tmp_path / "m.npz")
    assert not os.listdir(tmp_path)
    with pytest.raises(ValueError, match="PairwiseKernel.metric"):
        describe_kernel(PairwiseKernel(metric=lambda a, b: float(a @ b)))
    model = FIRGaussianProcess(
        DC(), factor=FACTOR, order=ORDER, optimizer=None, random_state=np.random.default_rng(0)
    ).fit(*data)
    with pytest.raises(ValueError, match="random_state"):
        save_model(model, tmp_path / "m.npz")


@pytest.mark.parametrize("make", [FIRGaussianProcess, lambda: LeastSquaresFIR(order=5)])
def test_unfitted_model_refused(make, tmp_path):
    model = make()
    with pytest.raises(NotFittedError):
        save_model(model, tmp_path / "m.npz")
    assert issubclass(NotFittedError, ValueError)


def test_other_objects_refused(tmp_path):
    with pytest.raises(TypeError, match="FIRGaussianProcess"):
        save_model(object(), tmp_path / "m.npz")


# ------------------------------------------------------------- bad files
def test_flipped_byte_in_array_refused(saved, fitted):
    raw = bytearray(saved.read_bytes())
    start = raw.find(fitted["C*DC tuned"].observation_.u.tobytes())
    assert start > 0
    raw[start + 17] ^= 0x01
    saved.write_bytes(bytes(raw))
    with pytest.raises(ModelFileError):
        load_model(saved)


def test_changed_array_in_valid_archive_refused_by_checksum(saved):
    def edit(header, members):
        members["u"] = members["u"].copy()
        members["u"][5] = np.nextafter(members["u"][5], np.inf)

    rewrite(saved, edit, rehash=False)
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(saved)


@pytest.mark.parametrize("fraction", [0.0, 0.1, 0.5, 0.99])
def test_truncated_file_refused(saved, fraction):
    raw = saved.read_bytes()
    saved.write_bytes(raw[: int(len(raw) * fraction)])
    with pytest.raises(ModelFileError):
        load_model(saved)


def test_edited_header_refused(saved):
    rewrite(saved, lambda h, m: h["fitted"].update(noise_level_=0.5), rehash=False)
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(saved)


def test_header_that_is_not_json_refused(saved):
    header, members = read_members(saved)
    with open(saved, "wb") as file:
        np.savez(file, header=np.frombuffer(b"{not json", dtype=np.uint8), **members)
    with pytest.raises(ModelFileError, match="JSON"):
        load_model(saved)


def test_other_major_version_refused(saved):
    rewrite(saved, lambda h, m: h.update(library_version="1.0.0"))
    with pytest.raises(ModelFileError) as info:
        load_model(saved)
    assert "1.0.0" in str(info.value) and gpmultirate.__version__ in str(info.value)


def test_same_major_version_accepted(saved, fitted, data):
    major = gpmultirate.__version__.split(".")[0]
    rewrite(saved, lambda h, m: h.update(library_version=f"{major}.999.3"))
    assert_same_model(fitted["C*DC tuned"], load_model(saved), data[0])


def test_newer_format_version_refused(saved):
    newer = gpmultirate.persistence.FORMAT_VERSION + 1
    rewrite(saved, lambda h, m: h.update(format_version=newer))
    with pytest.raises(ModelFileError, match=f"format version {newer}"):
        load_model(saved)


@pytest.mark.parametrize("name", ["Evil", "Kernel", "GaussianProcessRegressor", "os.system"])
def test_unknown_kernel_class_refused(saved, name):
    rewrite(saved, lambda h, m: h["fitted"]["kernel_"]["k2"].update({"class": name}))
    with pytest.raises(ModelFileError, match="unknown kernel class"):
        load_model(saved)


def test_unknown_parameter_refused(saved):
    rewrite(saved, lambda h, m: h["params"].update(callback="print"))
    with pytest.raises(ModelFileError, match="callback"):
        load_model(saved)


def test_malformed_tagged_value_refused(saved):
    rewrite(saved, lambda h, m: h["params"].update(noise_level_bounds={"type": "tuple"}))
    with pytest.raises(ModelFileError):
        load_model(saved)


def test_files_that_are_not_model_files_refused(tmp_path):
    with open(tmp_path / "plain.npz", "wb") as file:
        np.savez(file, x=np.arange(3.0))
    np.save(tmp_path / "array.npy", np.arange(3.0))
    (tmp_path / "text.txt").write_text("hello")
    (tmp_path / "empty").write_bytes(b"")
    write_members(tmp_path / "other.npz", {"format": "something-else"}, {})
    for name in ("plain.npz", "array.npy", "text.txt", "empty", "other.npz"):
        with pytest.raises(ModelFileError, match="not a"):
            load_model(tmp_path / name)
    with pytest.raises(FileNotFoundError):
        load_model(tmp_path / "missing.npz")


class Payload:
    """Unpickling this would create a directory: evidence that code ran."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (os.makedirs, (self.marker,))


def test_loading_never_unpickles(saved, tmp_path):
    marker = str(tmp_path / "code-ran")
    header, members = read_members(saved)
    members["u"] = np.array([Payload(marker)], dtype=object)
    write_members(saved, header, members)
    with pytest.raises(ModelFileError):
        load_model(saved)
    (tmp_path / "model.pkl").write_bytes(pickle.dumps(Payload(marker)))
    with pytest.raises(ModelFileError):
        load_model(tmp_path / "model.pkl")
    assert not os.path.exists(marker)


# ------------------------------------------------------ kernels of one's own
class MyTC(TC):
    """A user's kernel: TC under a name of its own, defined in the user's script."""


class Elsewhere(DC):
    pass


@pytest.fixture(scope="module")
def user_model(data):
    return FIRGaussianProcess(C(1.0) * MyTC(0.8), factor=FACTOR, order=ORDER).fit(*data)


def test_a_kernel_of_ones_own_round_trips_with_the_kernels_argument(user_model, data, tmp_path):
    path = tmp_path / "model.npz"
    save_model(user_model, path)
    header, _ = read_members(path)
    assert header["fitted"]["kernel_"]["k2"]["class"] == "MyTC"
    loaded = load_model(path, kernels=[MyTC])
    assert type(loaded.kernel_.k2) is MyTC
    assert_same_model(user_model, loaded, data[0])  # bitwise: predictions, bands, evidence


def test_without_the_kernels_argument_the_error_names_the_class_and_the_argument(
        user_model, tmp_path):
    path = tmp_path / "model.npz"
    save_model(user_model, path)
    for kernels in (None, [], [Elsewhere]):
        with pytest.raises(ModelFileError, match=r"'MyTC'.*kernels=\[MyTC\]"):
            load_model(path, kernels=kernels)


def test_only_the_classes_passed_are_instantiated(saved):
    rewrite(saved, lambda h, m: h["fitted"]["kernel_"]["k2"].update({"class": "os.system"}))
    with pytest.raises(ModelFileError, match="unknown kernel class 'os.system'") as info:
        load_model(saved, kernels=[MyTC])
    assert "kernels=" not in str(info.value)  # no hint for a name no class can have
    rewrite(saved, lambda h, m: h["fitted"]["kernel_"]["k2"].update({"class": "Elsewhere"}))
    with pytest.raises(ModelFileError, match="Elsewhere"):
        load_model(saved, kernels=[MyTC])
    loaded = load_model(saved, kernels=[MyTC, Elsewhere])  # DC's parameters, Elsewhere's class
    assert type(loaded.kernel_.k2) is Elsewhere


@pytest.mark.parametrize("kernels, words", [
    (MyTC, r"list of kernel classes.*kernels=\[MyKernel\]"),
    ("MyTC", "list of kernel classes"),
    ([MyTC()], r"kernels\[0\] must be a kernel class.*an instance"),
    ([MyTC, int], r"kernels\[1\] must be a kernel class"),
    ([ShadowDC], r"kernels\[0\].*'DC' is gpmultirate's"),
    ([MyTC, type("MyTC", (TC,), {})], r"kernels\[1\].*'MyTC' is another entry's"),
])
def test_bad_kernels_argument_refused(saved, kernels, words):
    with pytest.raises(ValueError, match=words):
        load_model(saved, kernels=kernels)


def test_the_library_kernels_may_be_passed_again(saved, fitted, data):
    assert_same_model(fitted["C*DC tuned"], load_model(saved, kernels=[DC, TC, MyTC]), data[0])


def test_a_kernel_of_ones_own_in_the_parameters_and_in_a_multi_output_file(data, tmp_path):
    from gpmultirate import MultiOutputFIR

    u, y_slow = data
    ys = np.column_stack([y_slow, 0.5 * y_slow + 0.01 * np.cos(np.arange(y_slow.size))])
    model = MultiOutputFIR(FIRGaussianProcess(
        MyTC(0.8) + C(0.1) * Elsewhere(0.6), factor=FACTOR, order=ORDER)).fit(u, ys)
    path = tmp_path / "multi.npz"
    save_model(model, path)
    with pytest.raises(ModelFileError, match="kernels="):
        load_model(path, kernels=[MyTC])
    loaded = load_model(path, kernels=[MyTC, Elsewhere])
    assert type(loaded.estimator.kernel.k1) is MyTC  # the template's parameter
    u_new = np.sin(0.3 * np.arange(70))
    np.testing.assert_array_equal(loaded.predict(u_new), model.predict(u_new))
    for a, b in zip(loaded.estimators_, model.estimators_):
        assert repr(a.kernel_) == repr(b.kernel_)
        np.testing.assert_array_equal(a.impulse_response([0.5, 3.25]),
                                      b.impulse_response([0.5, 3.25]))


# ------------------------------------------------------------ atomic files
def _only_the_model_file(folder, name="model.npz"):
    assert sorted(os.listdir(folder)) == [name]


def test_saving_over_a_file_replaces_it_whole_and_keeps_its_permissions(fitted, saved, data):
    os.chmod(saved, 0o640)
    save_model(fitted["least squares"], saved)
    assert os.stat(saved).st_mode & 0o777 == 0o640
    _only_the_model_file(saved.parent)
    assert type(load_model(saved)) is LeastSquaresFIR


def test_a_symbolic_link_is_written_through(fitted, tmp_path):
    (tmp_path / "store").mkdir()
    real = tmp_path / "store" / "model.npz"
    real.write_bytes(b"old")
    link = tmp_path / "link.npz"
    link.symlink_to(real)
    save_model(fitted["least squares"], link)
    assert link.is_symlink() and type(load_model(real)) is LeastSquaresFIR
    _only_the_model_file(tmp_path / "store")


@pytest.mark.parametrize("where", ["write", "fsync", "replace", "interrupt"])
def test_a_failure_at_any_step_keeps_the_old_file_and_leaves_no_temporary(
        where, fitted, saved, monkeypatch):
    before = saved.read_bytes()
    model = fitted["DC+PK sum"]

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    if where == "write":
        real_savez = np.savez

        def savez(file, **members):  # a few bytes reach the file, then the disk is full
            file.write(b"PK\x03\x04 partial")
            fail()
        monkeypatch.setattr(np, "savez", savez)
        assert real_savez is not np.savez
    elif where == "interrupt":
        def savez(file, **members):
            file.write(b"PK\x03\x04 partial")
            raise KeyboardInterrupt
        monkeypatch.setattr(np, "savez", savez)
    else:
        monkeypatch.setattr(os, where, fail)
    expected = KeyboardInterrupt if where == "interrupt" else OSError
    with pytest.raises(expected) as info:
        save_model(model, saved)
    monkeypatch.undo()
    if expected is OSError:
        message = str(info.value)
        assert str(saved) in message and "unchanged" in message and "No space" in message
        assert info.value.errno == 28
    assert saved.read_bytes() == before
    _only_the_model_file(saved.parent)


CHILD = """
import hashlib, json, os, resource, sys
import numpy as np
import gpmultirate as gm

path, limit = sys.argv[1], int(sys.argv[2])
rng = np.random.default_rng(1)
u = rng.standard_normal(300)
y_slow = np.convolve(u, 0.8 ** np.arange(40))[:300][::3]
model = gm.LeastSquaresFIR(factor=3, order=40).fit(u, y_slow)
soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
if limit:
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
try:
    gm.save_model(model, path)
except BaseException as error:
    with open(path, "rb") as file:  # what the failed save left, before the save below
        digest = hashlib.sha256(file.read()).hexdigest()
    print(json.dumps({"type": type(error).__name__, "errno": getattr(error, "errno", None),
                      "message": str(error), "os_error": isinstance(error, OSError),
                      "sha256": digest, "listing": sorted(os.listdir(os.path.dirname(path)))}))
else:
    print(json.dumps({"type": None}))
if limit:  # the same save without the limit
    resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    gm.save_model(model, path)
    print(json.dumps({"type": None}))
"""


def _run_child(path, limit=0, drop_capabilities=False):
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [os.path.dirname(os.path.dirname(gpmultirate.__file__)), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", CHILD, str(path), str(limit)], env=env,
                          capture_output=True, text=True, timeout=300,
                          preexec_fn=_drop_capabilities if drop_capabilities else None)
    assert done.returncode == 0, done.stderr
    return [json.loads(line) for line in done.stdout.strip().splitlines()]


def _drop_capabilities():
    """In the child before exec: root without capabilities obeys file permissions."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    for capability in range(64):  # PR_CAPBSET_DROP; EINVAL past the last capability
        if libc.prctl(24, capability, 0, 0, 0) != 0 and ctypes.get_errno() != 22:
            raise OSError(ctypes.get_errno(), "cannot drop capabilities")


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "fork"), reason="resource limits are POSIX")
def test_a_file_size_limit_keeps_the_old_file(saved, tmp_path):
    before = saved.read_bytes()
    # part of the new file is written, then EFBIG
    found, again = _run_child(saved, limit=4096)
    assert found["type"] == "OSError" and found["os_error"] and found["errno"] == 27  # EFBIG
    assert str(saved) in found["message"] and "unchanged" in found["message"]
    assert found["sha256"] == hashlib.sha256(before).hexdigest()  # byte-identical
    assert found["listing"] == ["model.npz"]  # no temporary left
    # then, without the limit, the same save replaces the file by a complete one
    assert again["type"] is None
    assert type(load_model(saved)) is LeastSquaresFIR
    assert os.path.getsize(saved) > 3 * 4096  # the limit did cut the first attempt
    _only_the_model_file(tmp_path)


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "fork"), reason="permissions are POSIX")
def test_an_unwritable_folder_keeps_the_old_file(saved, tmp_path):
    before = saved.read_bytes()
    os.chmod(tmp_path, 0o555)
    try:
        found, = _run_child(saved, drop_capabilities=os.geteuid() == 0)
    finally:
        os.chmod(tmp_path, 0o755)
    assert found["type"] == "PermissionError" and found["errno"] == 13
    assert str(saved) in found["message"] and "unchanged" in found["message"]
    assert saved.read_bytes() == before
    _only_the_model_file(tmp_path)


# ------------------------------------------------- files read defensively
def _forged_member(path, name, header_shape, payload=b""):
    """Add a member whose .npy header declares ``header_shape`` of float64."""
    import io as _io
    import zipfile

    header = _io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": header_shape})
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr(name, header.getvalue() + payload)


def test_forged_shape_refused_before_reading(saved):
    _forged_member(saved, "big.npy", (10**12,))
    with pytest.raises(ModelFileError, match=r"big\.npy.*declares shape"):
        load_model(saved)


def test_oversized_archive_refused_in_bounded_memory(saved):
    """A compressed bomb: 400 MB of zeros in a few hundred kB, refused from the
    archive's directory (``max_bytes``) before any member is inflated."""
    import tracemalloc
    import zipfile

    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (50_000_000,)
    buffer = __import__("io").BytesIO()
    np.lib.format.write_array_header_1_0(buffer, header)
    with zipfile.ZipFile(saved, "a", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("bomb.npy", "w", force_zip64=True) as member:
            member.write(buffer.getvalue())
            chunk = bytes(2**22)
            for _ in range(95):  # 95 x 4 MiB + the rest = 400,000,000 bytes
                member.write(chunk)
            member.write(bytes(400_000_000 - 95 * 2**22))
    tracemalloc.start()
    try:
        with pytest.raises(ModelFileError, match="max_bytes"):
            load_model(saved, max_bytes=100_000_000)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6


def test_unexpected_member_name_refused(saved):
    import zipfile

    with zipfile.ZipFile(saved, "a") as archive:
        archive.writestr("../escape.npy", b"")
    with pytest.raises(ModelFileError, match="unexpected archive member"):
        load_model(saved)


@pytest.mark.parametrize("max_bytes", [0, -1, 1.5, "big", True])
def test_max_bytes_checked(saved, max_bytes):
    with pytest.raises(ValueError, match="max_bytes"):
        load_model(saved, max_bytes=max_bytes)


@pytest.mark.parametrize("version", [None, "x.y", 3, "none"])
def test_library_version_that_is_not_a_version_refused(saved, version):
    rewrite(saved, lambda h, m: h.update(library_version=version))
    with pytest.raises(ModelFileError, match="invalid library_version") as info:
        load_model(saved)
    assert "None.x" not in str(info.value)


def test_a_model_reproduced_to_rounding_loads_without_a_warning():
    # another number of BLAS threads sums in another order: 4.2e-12 relative on a camera
    # log's model saved by the command line; a real difference still warns
    from gpmultirate.persistence import _warn_if_not_reproduced

    saved = np.array([1.0, -0.5, 0.25])
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        _warn_if_not_reproduced(saved * (1 + 4e-12), saved, 2519.179277519015,
                                2519.1792775213817)
    with pytest.warns(UserWarning, match="differs from the saved one"):
        _warn_if_not_reproduced(saved + 1e-6, saved, 2519.18, 2519.18)
    with pytest.warns(UserWarning, match="log marginal likelihood"):
        _warn_if_not_reproduced(saved, saved, 2519.18, 2519.19)
