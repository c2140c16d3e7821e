"""Saving fitted FIR models to portable files and loading them back.

:func:`save_model` writes a fitted :class:`~gpmultirate.FIRGaussianProcess`,
:class:`~gpmultirate.LeastSquaresFIR` or :class:`~gpmultirate.MultiOutputFIR`
to an ``.npz`` archive of plain numbers; :func:`load_model` reads it back
without unpickling anything and without importing any name found in the
file, so loading a file from an untrusted source cannot run code: a kernel
class of your own is rebuilt only from the classes passed as
``load_model(path, kernels=[MyKernel])``.  A file name is written
atomically.  (Fitted models also round-trip through :mod:`pickle`, but a
pickle must only be loaded from a trusted source.)

File format, version 1
----------------------
An uncompressed ``.npz`` archive (:func:`numpy.savez`) with the members

``header``
    ``uint8`` array of UTF-8 JSON: ``format`` (``"gpmultirate-model"``),
    ``format_version``, ``library_version``, ``estimator`` (class name),
    ``params`` (constructor parameters), ``fitted`` (``factor``, ``order``,
    ``offset``, the fitted hyperparameters, ...) and ``sha256``.
``u``, ``coef``
    Training input and fitted coefficients (little-endian float64).
``y_slow``
    Slow training output (FIRGaussianProcess): loading conditions the
    stored kernel on it again, which reproduces the fitted model exactly.
``coef_covariance``
    Coefficient covariance (LeastSquaresFIR).

File format, version 2
----------------------
Written for the data that version 1 cannot describe: several inputs,
several records, slow samples at given instants or missing, and initial
conditions other than ``"zero"``.  ``fitted`` holds ``layout`` (``"records"``),
``n_records``, ``several_records`` and ``order``, and the arrays are, for
every record ``r``, ``u_<r>`` (``(N,)`` or ``(N, n_inputs)``),
``sample_indices_<r>`` (the used fast-sample instants, as float64) and
``y_slow_<r>`` (the used slow samples), with ``coef`` (the input-major
coefficient vector) and, for LeastSquaresFIR, ``coef_covariance``.  Both
estimators are rebuilt by fitting the stored data again (least squares is
deterministic; a Gaussian process is conditioned at the stored
hyperparameters), and the coefficients are checked against ``coef``.

File format, version 3
----------------------
A :class:`~gpmultirate.MultiOutputFIR`: ``estimator`` is ``"MultiOutputFIR"``,
``params`` holds ``n_jobs``, ``template`` the class name (``estimator``) and
the ``params`` of the unfitted estimator that is cloned for every output,
and ``fitted`` holds ``n_outputs`` and ``outputs``, one object per output
with the ``format_version`` (1 or 2), ``estimator``, ``params`` and
``fitted`` entries of that output's model as a file of its own would hold
them, and ``arrays``, which maps that file's array names to members
``array_<k>`` of the archive.  An array that several outputs share (the
input) is stored once.  Each output's model is loaded as its own file would
be, under the one BLAS thread it was fitted with.

File format, versions 4 and 5
-----------------------------
A :class:`~gpmultirate.FIRGaussianProcess` fitted to readings at their own
instants (``fit(..., sample_times=t)`` with readings between the fast
ticks, or with an exposure): the layout of version 2 with ``layout``
``"timed"`` and ``quadrature_nodes`` (the Gauss-Legendre nodes of an
exposure window, :data:`~gpmultirate.observations.timed.QUADRATURE_NODES`)
in ``fitted``, and ``sample_times_<r>`` (the stamps of the used readings,
in fast sample periods) in place of ``sample_indices_<r>``.  The exposure
and the latency are constructor parameters (``params``).  Loading fits the
stored readings again at their stamps, at the stored hyperparameters.  A
:class:`~gpmultirate.MultiOutputFIR` whose outputs include such a model is
written as version 4 (otherwise as version 3), with the layout of version 3.
Version 5 is version 4 with the exposure and the latency of ``params`` in
the units of ``sample_time`` (seconds), as the estimator takes them since
gpmultirate 0.2.0 (version 4: in fast sample periods; such files load with
them multiplied by ``sample_time``); the stamps stay in fast sample periods.

A kernel is a JSON tree such as ``{"class": "Sum", "k1": {...}, "k2": {...}}``
or ``{"class": "DC", "params": {"alpha": 0.9, ...}}`` whose classes must be
in :data:`KERNEL_CLASSES`.  Values JSON cannot hold exactly are tagged
objects ``{"type": "tuple" | "ndarray" | "float" | "kernel" | "RandomState", ...}``.

``sha256`` is the hex digest of the header without its ``sha256`` entry,
serialised as ``json.dumps(header, sort_keys=True, separators=(",", ":"))``
plus a newline, followed for every other member, in name order, by the line
``"{name}:{dtype.str}:{comma-separated shape}\\n"`` and the array's bytes, so
any change to the file is detected.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import secrets
import stat
import types
import warnings
import zipfile
from typing import Any, BinaryIO, Union

import numpy as np
from scipy.optimize import OptimizeResult
from sklearn.gaussian_process.kernels import (
    RBF,
    ConstantKernel,
    DotProduct,
    Exponentiation,
    ExpSineSquared,
    Kernel,
    Matern,
    Product,
    RationalQuadratic,
    Sum,
    WhiteKernel,
)
from sklearn.utils.validation import check_is_fitted

from gpmultirate.exceptions import ModelFileError, NumericalWarning
from gpmultirate.inference import GaussianCoefficients, one_blas_thread
from gpmultirate.version import __version__
from gpmultirate.estimators import FIRGaussianProcess, LeastSquaresFIR
from gpmultirate.kernels import DC, PK, SS, TC, PerInputKernel
from gpmultirate.multioutput import MultiOutputFIR, stacked_coefficients
from gpmultirate.observations import (
    DownsampledConvolution,
    build_experiment,
)
from gpmultirate.observations.timed import QUADRATURE_NODES
from gpmultirate.resonances import Resonance
from gpmultirate.units import duration_in_fast_periods
from gpmultirate.validation import check_n_jobs

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "KERNEL_CLASSES",
    "MAX_MODEL_BYTES",
    "ModelFileError",
    "describe_kernel",
    "kernel_classes",
    "kernel_from_description",
    "load_model",
    "save_model",
]

PathOrFile = Union[str, os.PathLike, BinaryIO]

FORMAT_NAME = "gpmultirate-model"
FORMAT_VERSION = 5

MAX_MODEL_BYTES = 2**31
"""The largest total size of the arrays a model file may declare (2 GiB).

A model holds its coefficients, its data and a few vectors: a record of ten
million fast samples takes some 160 MB.  Files declaring more are refused
before any array is read (``load_model(..., max_bytes=)`` raises the bound).
"""

#: The kernel classes a model file may name, by class name; :func:`load_model`
#: takes further classes of your own as ``kernels=[...]``.
KERNEL_CLASSES = types.MappingProxyType(
    {
        cls.__name__: cls
        for cls in (
            ConstantKernel, WhiteKernel, RBF, Matern, RationalQuadratic, ExpSineSquared,
            DotProduct, Sum, Product, Exponentiation, TC, DC, SS, PK, PerInputKernel,
        )
    }
)
# constructor arguments of the composite kernels that are kernels themselves
_KERNEL_SLOTS = {"Sum": ("k1", "k2"), "Product": ("k1", "k2"), "Exponentiation": ("kernel",)}
# constructor arguments that are lists of kernels
_KERNEL_LISTS = {"PerInputKernel": "kernels"}
_ESTIMATORS = {cls.__name__: cls for cls in (FIRGaussianProcess, LeastSquaresFIR)}
# the entries of a single model's header that a MultiOutputFIR file keeps per output
_OUTPUT_ENTRIES = ("format_version", "estimator", "params", "fitted")
_ARRAYS = {
    "FIRGaussianProcess": ("u", "y_slow", "coef"),
    "LeastSquaresFIR": ("u", "coef", "coef_covariance"),
}
# the plain-data part of scipy's L-BFGS-B result (hess_inv is an operator object)
_RESONANCE_FIELDS = ("frequency_hz", "damping", "evidence_gain", "input")
_OPTIMIZER_FIELDS = ("x", "fun", "jac", "nit", "nfev", "njev", "status", "success", "message")
_SELECTION_FIELDS = ("order", "score", "criterion", "best_order")
_ARRAY_DTYPES = frozenset(
    ["bool", "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64",
     "float16", "float32", "float64"]
)
_NON_FINITE = {"inf": np.inf, "-inf": -np.inf, "nan": np.nan}


# ----------------------------------------------------------------- saving
def save_model(
    model: FIRGaussianProcess | LeastSquaresFIR | MultiOutputFIR, path: PathOrFile
) -> None:
    """Write a fitted model to a portable ``.npz`` file.

    The file holds the training data, the fitted hyperparameters and the
    constructor parameters as plain numbers and JSON, never pickled
    objects; see the module documentation for the format.

    Parameters
    ----------
    model : FIRGaussianProcess, LeastSquaresFIR or MultiOutputFIR
        A fitted model (a MultiOutputFIR of one of the two others).  Its
        parameters, and those of its kernels, must be numbers, strings,
        tuples, arrays, kernels or a ``numpy.random.RandomState``.  A
        kernel class of your own is stored by name: load the file with
        ``load_model(path, kernels=[MyKernel])``.
    path : str, path-like or binary file object
        Destination, written exactly as named (no ``.npz`` is appended).
        A file name is written atomically: the model goes to a temporary
        file in the same folder, which is synced to disk and then renamed
        onto ``path`` in one step.  Whatever fails (a full disk, a file
        size limit, an interruption), ``path`` keeps its former content and
        no temporary file is left.

    Raises
    ------
    sklearn.exceptions.NotFittedError
        If ``model`` is not fitted.
    ValueError
        If a kernel or parameter cannot be stored; the message names it.
    TypeError
        If ``model`` is not one of the three estimators.
    OSError
        If the file cannot be written (the folder is not writable, the disk
        is full, ...); the message names the file, which is unchanged.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import FIRGaussianProcess
    >>> from gpmultirate.kernels import DC
    >>> from gpmultirate.persistence import load_model, save_model
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(90)
    >>> y_slow = np.convolve(u, 0.8 ** np.arange(30))[:90][::3]
    >>> model = FIRGaussianProcess(C(1.0) * DC(), factor=3, order=30, optimizer=None)
    >>> model = model.fit(u, y_slow)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "model.npz")
    ...     save_model(model, path)
    ...     loaded = load_model(path)
    >>> bool(np.array_equal(loaded.predict(u), model.predict(u)))
    True
    """
    if type(model) is MultiOutputFIR:
        header, arrays = _multi_output_members(model)
    else:
        header, arrays = _single_members(model)
    header["sha256"] = _checksum(header, arrays)
    encoded = json.dumps(header, sort_keys=True, allow_nan=False).encode("utf-8")
    members = {"header": np.frombuffer(encoded, dtype=np.uint8), **arrays}
    if hasattr(path, "write"):
        if isinstance(path, io.TextIOBase):
            raise TypeError("path must be a file name or a binary file object; got a text file")
        np.savez(path, **members)
    else:
        _write_atomically(_check_path(path), lambda file: np.savez(file, **members))


# a new file for writing bytes (O_BINARY: no newline translation on Windows)
_NEW_FILE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)


def _write_atomically(path, write) -> None:
    """``write(file)`` to a new file in the folder of ``path``, then renamed onto ``path``.

    The new file is flushed and synced to disk before :func:`os.replace`
    puts it in place in one step, so ``path`` holds either its former
    content or the complete new one, whatever fails (a full disk, a file
    size limit, an interruption); on failure the temporary file is removed.
    A symbolic link is written through, as ``open(path, "wb")`` would.
    """
    target = os.fsdecode(os.path.realpath(path) if os.path.islink(path) else path)
    folder, name = os.path.split(target)
    folder = folder or os.curdir
    temporary = None
    try:
        descriptor = None
        while descriptor is None:
            candidate = os.path.join(folder, f".{name}.{secrets.token_hex(4)}.tmp")
            try:  # created with the permissions open() would give (0o666 less the umask)
                descriptor = os.open(candidate, _NEW_FILE, 0o666)
            except FileExistsError:
                continue
            temporary = candidate
        with os.fdopen(descriptor, "wb") as file:
            write(file)
            file.flush()
            os.fsync(file.fileno())
        _keep_mode(target, temporary)
        os.replace(temporary, target)
        temporary = None
    except OSError as error:
        message = (f"cannot write the model file {target!r}: {error.strerror or error}; "
                   "any file that was there is unchanged")
        # OSError(errno, ...) is the subclass of that errno (PermissionError, ...)
        raise (OSError(message) if error.errno is None else OSError(error.errno, message)) from error
    finally:
        if temporary is not None:
            try:
                os.unlink(temporary)
            except OSError:
                pass


def _keep_mode(target: str, temporary: str) -> None:
    """The permissions of the file being replaced, where it exists and they can be set."""
    try:
        os.chmod(temporary, stat.S_IMODE(os.stat(target).st_mode))
    except OSError:
        pass


def _single_members(model) -> tuple[dict, dict[str, np.ndarray]]:
    """The header (without checksum) and the arrays of a single-output model file."""
    name = type(model).__name__
    if _ESTIMATORS.get(name) is not type(model):
        raise TypeError(
            "model must be a FIRGaussianProcess, LeastSquaresFIR or MultiOutputFIR (not a "
            f"subclass); got {type(model).__qualname__}"
        )
    check_is_fitted(model, "coef_")
    observation = model.observation_
    if observation.file_layout == "timed":  # readings at their own instants (or interpolated)
        version = 5
        fitted = {
            "layout": "timed",
            "n_records": len(observation.records),
            "several_records": _several(model),
            "order": int(observation.order),
            "quadrature_nodes": int(observation.records[0].nodes),
        }
        arrays = {"coef": model.posterior_.coef}
        start = 0
        for r, record in enumerate(observation.records):
            stop = start + record.n_outputs
            arrays[f"u_{r}"] = record.u
            arrays[f"sample_times_{r}"] = record.sample_times
            arrays[f"y_slow_{r}"] = model.y_slow_[start:stop]
            start = stop
    elif observation.file_layout == "downsampled":  # the layout of version 1
        version = 1
        fitted: dict[str, Any] = {
            "factor": int(observation.factor),
            "order": int(observation.order),
            "offset": int(observation.offset),
        }
        arrays = {"u": observation.u, "coef": model.coef_}
        if isinstance(model, FIRGaussianProcess):
            arrays["y_slow"] = model.y_slow_
    else:
        version = 2
        records = observation.records
        fitted = {
            "layout": "records",
            "n_records": len(records),
            "several_records": _several(model),
            "order": int(observation.order),
        }
        arrays = {"coef": model.posterior_.coef}
        start = 0
        for r, record in enumerate(records):
            stop = start + record.n_outputs
            arrays[f"u_{r}"] = record.u
            arrays[f"sample_indices_{r}"] = record.sample_indices
            if isinstance(model, FIRGaussianProcess):
                arrays[f"y_slow_{r}"] = model.y_slow_[start:stop]
            start = stop
    if isinstance(model, FIRGaussianProcess):
        result = getattr(model, "optimizer_result_", None)
        fitted.update(
            kernel_=describe_kernel(model.kernel_),
            noise_level_=_encode(model.noise_level_, "noise_level_"),
            noise_level_bounds_=_encode(model.noise_level_bounds_, "noise_level_bounds_"),
            log_marginal_likelihood_value_=_encode(
                model.log_marginal_likelihood_value_, "log_marginal_likelihood_value_"
            ),
            optimizer_result_=None if result is None else _encode_optimizer_result(result),
        )
        if getattr(model, "hyperparameter_units_", "data") == "normalized":
            # kernel_, noise_level_ and its bounds are in the units of the data divided by
            # these powers of two (beyond the float range in the data's units)
            fitted.update(
                hyperparameter_units_="normalized",
                input_scale_exponents=[int(e) for e in np.frexp(model.input_scale_)[1] - 1],
                output_scale_exponent=int(np.frexp(model.output_scale_)[1] - 1),
            )
        if not _is_white(getattr(model, "noise_kernel_", "white")):
            # the tuned disturbance: the load conditions on it again
            fitted["noise_kernel_"] = describe_kernel(model.noise_kernel_)
        if hasattr(model, "cv_log_predictive_likelihood_"):
            fitted["cv_log_predictive_likelihood_"] = _encode(
                model.cv_log_predictive_likelihood_, "cv_log_predictive_likelihood_")
        if hasattr(model, "order_selection_"):
            fitted["order_selection_"] = {
                key: _encode(model.order_selection_[key], "order_selection_")
                for key in _SELECTION_FIELDS
            }
        if hasattr(model, "resonances_"):
            fitted["resonances_"] = [
                {key: _encode(getattr(r, key), "resonances_") for key in _RESONANCE_FIELDS}
                for r in model.resonances_
            ]
    else:
        arrays["coef_covariance"] = model.coef_covariance_
        fitted["noise_variance_"] = _encode(model.noise_variance_, "noise_variance_")
    header = {
        "format": FORMAT_NAME,
        "format_version": version,
        "library_version": __version__,
        "estimator": name,
        "params": {
            key: _encode(value, f"parameter {key!r}")
            for key, value in model.get_params(deep=False).items()
        },
        "fitted": fitted,
    }
    # little-endian float64 everywhere, whatever the machine
    arrays = {key: np.ascontiguousarray(value, dtype="<f8") for key, value in arrays.items()}
    return header, arrays


def _multi_output_members(model) -> tuple[dict, dict[str, np.ndarray]]:
    """Version 3: each output's model as in versions 1 and 2, arrays stored once by content."""
    check_is_fitted(model, "estimators_")
    template = model.estimator
    if _ESTIMATORS.get(type(template).__name__) is not type(template):
        raise TypeError(
            "the estimator of a MultiOutputFIR must be a FIRGaussianProcess or "
            f"LeastSquaresFIR to be saved; got {type(template).__qualname__}"
        )
    outputs, arrays, names = [], {}, {}
    for estimator in model.estimators_:
        header, own = _single_members(estimator)
        members = {}
        for key, array in own.items():
            # identical arrays (the inputs every output shares) are stored once
            content = (array.shape, hashlib.sha256(array.tobytes()).hexdigest())
            if content not in names:
                names[content] = f"array_{len(names)}"
                arrays[names[content]] = array
            members[key] = names[content]
        outputs.append({**{key: header[key] for key in _OUTPUT_ENTRIES}, "arrays": members})
    header = {
        "format": FORMAT_NAME,
        # an output at its readings' own instants needs a reader of version 5
        "format_version": 5 if any(o["format_version"] == 5 for o in outputs) else 3,
        "library_version": __version__,
        "estimator": "MultiOutputFIR",
        "params": {"n_jobs": _encode(model.n_jobs, "parameter 'n_jobs'")},
        "template": {
            "estimator": type(template).__name__,
            "params": {
                key: _encode(value, f"estimator parameter {key!r}")
                for key, value in template.get_params(deep=False).items()
            },
        },
        "fitted": {"n_outputs": len(outputs), "outputs": outputs},
    }
    return header, arrays


def describe_kernel(kernel: Kernel) -> dict:
    """JSON-ready description of a kernel.

    Parameters
    ----------
    kernel : sklearn Kernel

    Returns
    -------
    dict
        ``{"class": name, "params": {...}}`` for a single kernel, with the
        kernel-valued arguments (``k1``, ``k2`` or ``kernel``) as nested
        descriptions for composite ones.

    A kernel class outside :data:`KERNEL_CLASSES` (a kernel of your own) is
    described by its class name and constructor parameters, as scikit-learn's
    ``get_params`` gives them; :func:`load_model` rebuilds it only when the
    class is passed as ``kernels=[MyKernel]``.

    Raises
    ------
    ValueError
        For a class that is not a scikit-learn kernel, a kernel class of
        your own with the name of one of :data:`KERNEL_CLASSES`, or a
        parameter that cannot be stored; the message names it.

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel
    >>> from gpmultirate.kernels import TC
    >>> from gpmultirate.persistence import describe_kernel, kernel_from_description
    >>> tree = describe_kernel(ConstantKernel(2.0) * TC(alpha=0.8))
    >>> tree["class"], tree["k2"]["params"]["alpha"]
    ('Product', 0.8)
    >>> kernel_from_description(tree)
    1.41**2 * TC(alpha=0.8)
    """
    name = type(kernel).__name__
    if not isinstance(kernel, Kernel):
        raise ValueError(f"cannot save {name} as a kernel: it is not a scikit-learn Kernel")
    if name in KERNEL_CLASSES and KERNEL_CLASSES[name] is not type(kernel):
        raise ValueError(
            f"cannot save kernel class {type(kernel).__module__}.{type(kernel).__qualname__}: "
            f"its name is that of gpmultirate's {name}; give your kernel class a name of its own"
        )
    params = kernel.get_params(deep=False)
    tree: dict[str, Any] = {"class": name}
    for slot in _KERNEL_SLOTS.get(name, ()):
        tree[slot] = describe_kernel(params.pop(slot))
    if name in _KERNEL_LISTS:
        slot = _KERNEL_LISTS[name]
        tree[slot] = [describe_kernel(k) for k in params.pop(slot)]
    if params:
        tree["params"] = {key: _encode(value, f"{name}.{key}") for key, value in params.items()}
    return tree


def kernel_from_description(tree: dict, kernels=None) -> Kernel:
    """Rebuild a kernel from :func:`describe_kernel`'s description.

    Only classes of :data:`KERNEL_CLASSES` and of ``kernels`` are
    instantiated; nothing is imported by name.

    Parameters
    ----------
    tree : dict
    kernels : list of kernel classes, optional
        Kernel classes of your own that the description may name, besides
        :data:`KERNEL_CLASSES`.

    Returns
    -------
    sklearn Kernel

    Raises
    ------
    ModelFileError
        For an unknown class or a malformed description.
    ValueError
        If ``kernels`` is not a list of kernel classes with names of their own.

    Examples
    --------
    >>> from gpmultirate.persistence import kernel_from_description
    >>> kernel_from_description({"class": "DC", "params": {"alpha": 0.5, "beta": 0.7}})
    DC(alpha=0.5, beta=0.7)
    """
    return _kernel_from_tree(tree, kernel_classes(kernels))


def kernel_classes(kernels=None) -> types.MappingProxyType:
    """The kernel classes a model file may name: :data:`KERNEL_CLASSES` and ``kernels``.

    Parameters
    ----------
    kernels : list of kernel classes, optional
        Subclasses of scikit-learn's ``Kernel``, each with a class name that
        none of :data:`KERNEL_CLASSES` and no other entry has.

    Returns
    -------
    mapping of str to class

    Raises
    ------
    ValueError
        If ``kernels`` is not such a list; the message names the entry.

    Examples
    --------
    >>> from gpmultirate.kernels import TC
    >>> class SlowTC(TC):
    ...     pass
    >>> classes = kernel_classes([SlowTC])
    >>> classes["SlowTC"] is SlowTC, classes["TC"] is TC
    (True, True)
    """
    if kernels is None:
        return KERNEL_CLASSES
    if isinstance(kernels, (str, bytes, type, dict)) or not hasattr(kernels, "__iter__"):
        raise ValueError(
            f"kernels must be a list of kernel classes, such as kernels=[MyKernel]; got {kernels!r}"
        )
    classes = dict(KERNEL_CLASSES)
    for i, cls in enumerate(kernels):
        if not (isinstance(cls, type) and issubclass(cls, Kernel)):
            what = "an instance" if isinstance(cls, Kernel) else repr(cls)
            raise ValueError(
                f"kernels[{i}] must be a kernel class (a subclass of scikit-learn's Kernel); "
                f"got {what}"
            )
        known = classes.get(cls.__name__)
        if known is not None and known is not cls:
            whose = "gpmultirate's" if cls.__name__ in KERNEL_CLASSES else "another entry's"
            raise ValueError(
                f"kernels[{i}]: the class name {cls.__name__!r} is {whose}; a model file names "
                "kernel classes by name, so each needs a name of its own"
            )
        classes[cls.__name__] = cls
    return types.MappingProxyType(classes)


def _kernel_from_tree(tree: dict, classes) -> Kernel:
    """:func:`kernel_from_description` with the allowed classes resolved."""
    if not isinstance(tree, dict) or not isinstance(tree.get("class"), str):
        raise ModelFileError(
            f"a kernel description must be an object with a 'class'; got {tree!r}"
        )
    name = tree["class"]
    if name not in classes:
        hint = (f"; if {name} is a kernel class of your own, pass it: "
                f"load_model(path, kernels=[{name}])" if name.isidentifier() else "")
        raise ModelFileError(
            f"unknown kernel class {name!r} in the model file: only "
            f"{', '.join(classes)} can be loaded{hint}"
        )
    slots = _KERNEL_SLOTS.get(name, ())
    lists = (_KERNEL_LISTS[name],) if name in _KERNEL_LISTS else ()
    unexpected = set(tree) - {"class", "params", *slots, *lists}
    missing = [slot for slot in (*slots, *lists) if slot not in tree]
    if unexpected or missing:
        raise ModelFileError(
            f"malformed {name} kernel description: unexpected entries {sorted(unexpected)}, "
            f"missing {missing}"
        )
    params = tree.get("params", {})
    if not isinstance(params, dict):
        raise ModelFileError(f"the params of a {name} kernel must be an object; got {params!r}")
    arguments = {key: _decode(value, classes) for key, value in params.items()}
    arguments.update({slot: _kernel_from_tree(tree[slot], classes) for slot in slots})
    for slot in lists:
        if not isinstance(tree[slot], list) or not tree[slot]:
            raise ModelFileError(f"the {slot} of a {name} kernel must be a non-empty list")
        arguments[slot] = [_kernel_from_tree(item, classes) for item in tree[slot]]
    try:
        return classes[name](**arguments)
    except TypeError as exc:
        raise ModelFileError(f"invalid arguments for kernel {name}: {exc}") from exc


# ---------------------------------------------------------------- loading
def _check_path(path):
    """A file name: str or path-like (an int file descriptor is refused on purpose)."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(
            f"path must be a file name (str or path-like) or a binary file object; "
            f"got {type(path).__name__}"
        )
    if "\x00" in os.fspath(path) if isinstance(os.fspath(path), str) else b"\x00" in os.fspath(path):
        raise ValueError("path must not contain a NUL character")
    return path


def load_model(
    path: PathOrFile, kernels=None, max_bytes: int = MAX_MODEL_BYTES
) -> FIRGaussianProcess | LeastSquaresFIR | MultiOutputFIR:
    """Load a model written by :func:`save_model`.

    The archive is read with ``allow_pickle=False`` and kernels are
    rebuilt from a fixed list of classes, so loading runs no code from the
    file.  A :class:`FIRGaussianProcess` is rebuilt by conditioning the
    stored kernel on the stored data, with the stored noise level; this
    repeats the last step of ``fit`` and reproduces its predictions bit for
    bit on the same platform (a warning reports any difference, which can
    only come from different numerical libraries).  The loaded model has the
    original constructor parameters, so ``get_params`` and refitting behave
    as for the saved model.  A :class:`MultiOutputFIR` is loaded output by
    output in the same way.

    Parameters
    ----------
    path : str, path-like or binary file object
    kernels : list of kernel classes, optional
        Kernel classes of your own that the file may name, besides
        :data:`KERNEL_CLASSES` (see :func:`kernel_classes`).  Only these
        classes are instantiated: nothing is imported by the names the
        file holds.
    max_bytes : int, default 2**31
        The largest total size of the arrays the file may declare
        (:data:`MAX_MODEL_BYTES`).  Member names, array headers and sizes
        are checked from the archive's directory before any array is read,
        so a forged or oversized file is refused in bounded memory.

    Returns
    -------
    FIRGaussianProcess, LeastSquaresFIR or MultiOutputFIR
        The fitted model.

    Raises
    ------
    ModelFileError
        If the file is not a gpmultirate model file, is corrupted, was
        written by a different major version of gpmultirate or a newer file
        format, or names a kernel class that is neither one of
        :data:`KERNEL_CLASSES` nor passed in ``kernels`` (the message names
        the class and the ``kernels=`` argument), or declares more than
        ``max_bytes`` of arrays.
    ValueError
        If ``max_bytes`` is not a positive integer, or ``kernels`` is not a list of kernel classes with names of their own.
    FileNotFoundError
        If ``path`` does not exist.

    Examples
    --------
    >>> import io
    >>> import numpy as np
    >>> from gpmultirate import LeastSquaresFIR
    >>> from gpmultirate.persistence import load_model, save_model
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(90)
    >>> y_slow = np.convolve(u, 0.5 ** np.arange(8))[:90][::3]
    >>> buffer = io.BytesIO()
    >>> save_model(LeastSquaresFIR(factor=3, order=8).fit(u, y_slow), buffer)
    >>> _ = buffer.seek(0)
    >>> load_model(buffer).coef_[:3].round(6)
    array([1.  , 0.5 , 0.25])
    """
    classes = kernel_classes(kernels)
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, (int, np.integer)) or max_bytes < 1:
        raise ValueError(f"max_bytes must be a positive integer; got {max_bytes!r}")
    if hasattr(path, "read"):
        members = _read_archive(path, int(max_bytes))
    else:
        with open(_check_path(path), "rb") as file:
            members = _read_archive(file, int(max_bytes))
    header = _parse_header(members.pop("header", None))
    _check_versions(header)
    if header.get("sha256") != _checksum(header, members):
        raise ModelFileError(
            "the model file is corrupted: its SHA-256 checksum does not match its contents"
        )
    name = header.get("estimator")
    try:
        if name == "MultiOutputFIR" and header["format_version"] in (3, 4, 5):
            return _load_multi_output(header, members, classes)
        return _load_single(header, members, classes)
    except ModelFileError:
        raise
    except (KeyError, TypeError, ValueError, OverflowError, RecursionError) as exc:
        raise ModelFileError(f"the {name} model file is invalid: {exc}") from exc


def _load_single(header: dict, members: dict[str, np.ndarray], classes):
    """A FIRGaussianProcess or LeastSquaresFIR from its header and arrays (versions 1, 2, 4)."""
    name = header.get("estimator")
    version = header.get("format_version")
    if name not in _ESTIMATORS:
        raise ModelFileError(f"unknown estimator {name!r} in the model file")
    versions = (1, 2, 4, 5) if name == "FIRGaussianProcess" else (1, 2)
    if version not in versions:
        raise ModelFileError(
            f"a {name} is stored in format version {' or '.join(map(str, versions))}; "
            f"got {version!r}")
    expected = _ARRAYS[name] if version == 1 else _record_arrays(header, name, version)
    if sorted(members) != sorted(expected):
        raise ModelFileError(
            f"a {name} file must hold the arrays {sorted(expected)}; got {sorted(members)}"
        )
    arrays = {key: _float_vector_or_matrix(key, value) for key, value in members.items()}
    if version in (2, 4, 5):
        return _load_records(header, arrays, _ESTIMATORS[name], classes,
                             timed=version in (4, 5), durations_in_periods=version == 4)
    if name == "FIRGaussianProcess":
        return _load_gaussian_process(header, arrays, classes)
    return _load_least_squares(header, arrays)


def _load_multi_output(header: dict, members: dict[str, np.ndarray], classes) -> MultiOutputFIR:
    """Version 3: every output's model loaded as a single model, under fit's BLAS limit."""
    template = _section(header, "template")
    estimator = _ESTIMATORS.get(template.get("estimator"))
    if estimator is None:
        raise ModelFileError(
            f"unknown estimator {template.get('estimator')!r} in the MultiOutputFIR file"
        )
    params = _decode_params(template, estimator, classes)
    params_of_model = _section(header, "params")
    if set(params_of_model) != {"n_jobs"}:
        raise ModelFileError(
            f"a MultiOutputFIR file must hold the parameter n_jobs only; got "
            f"{sorted(params_of_model)}"
        )
    n_jobs = _decode(params_of_model["n_jobs"])
    fitted = _section(header, "fitted")
    outputs = fitted.get("outputs")
    n_outputs = _integer(fitted, "n_outputs")
    if not isinstance(outputs, list) or not 1 <= n_outputs == len(outputs):
        raise ModelFileError(
            f"a MultiOutputFIR file must describe n_outputs >= 1 outputs; got n_outputs="
            f"{n_outputs!r} and {len(outputs) if isinstance(outputs, list) else outputs!r}"
        )
    used = set()
    estimators = []
    for j, output in enumerate(outputs):
        if not isinstance(output, dict) or set(output) != {*_OUTPUT_ENTRIES, "arrays"}:
            raise ModelFileError(
                f"output {j} of the MultiOutputFIR file must hold exactly the entries "
                f"{sorted({*_OUTPUT_ENTRIES, 'arrays'})}"
            )
        names = output["arrays"]
        if not isinstance(names, dict) or any(
            not isinstance(stored, str) or stored not in members for stored in names.values()
        ):
            raise ModelFileError(f"output {j} of the MultiOutputFIR file names missing arrays")
        used.update(names.values())
        with one_blas_thread():  # as in MultiOutputFIR.fit, so that the fit is reproduced
            estimators.append(_load_single(
                {key: output[key] for key in _OUTPUT_ENTRIES},
                {key: members[stored] for key, stored in names.items()},
                classes,
            ))
    if used != set(members):
        raise ModelFileError(
            f"the MultiOutputFIR file holds arrays no output uses: {sorted(set(members) - used)}"
        )
    model = MultiOutputFIR(estimator(**params), n_jobs=n_jobs)
    check_n_jobs(n_jobs)
    model.estimators_ = estimators
    model.n_outputs_ = len(estimators)
    model.n_inputs_ = int(estimators[0].n_inputs_)
    model.coef_ = stacked_coefficients([e.coef_ for e in estimators])
    return model


_MEMBER_NAME = re.compile(r"[A-Za-z0-9_]{1,200}\.npy")


def _read_archive(file: BinaryIO, max_bytes: int = MAX_MODEL_BYTES) -> dict[str, np.ndarray]:
    """Read the archive's arrays, checking names and declared sizes first.

    Every member's name, its array header (dtype and shape) and its size in
    the archive's directory are checked before any member is read in full,
    so a forged shape or a compressed bomb is refused in bounded memory.
    """
    try:
        archive = zipfile.ZipFile(file)
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:
        raise ModelFileError(
            f"not a gpmultirate model file: not an .npz archive, or a truncated one ({exc})"
        ) from exc
    with archive:
        infos = archive.infolist()
        declared = {}
        for info in infos:
            if not _MEMBER_NAME.fullmatch(info.filename):
                raise ModelFileError(
                    f"not a gpmultirate model file: unexpected archive member {info.filename!r}"
                )
            declared[info.filename] = _member_header(archive, info)
        total = sum(nbytes for _, _, nbytes in declared.values())
        if total > max_bytes:
            raise ModelFileError(
                f"the model file declares {total} bytes of arrays, more than max_bytes="
                f"{max_bytes}; pass a larger max_bytes to load_model if the file is trusted"
            )
        arrays = {}
        for info in infos:
            dtype, shape, _ = declared[info.filename]
            arrays[info.filename[:-4]] = _read_member(archive, info, dtype, shape)
        return arrays


def _member_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo):
    name = info.filename
    try:
        with archive.open(info) as stream:
            version = np.lib.format.read_magic(stream)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(stream)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(stream)
            else:
                raise ValueError(f"unsupported .npy format version {version}")
            offset = stream.tell()
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, RuntimeError) as exc:
        raise ModelFileError(f"the model file's member {name!r} is not a readable array: {exc}") from exc
    if dtype.hasobject:
        raise ModelFileError(f"the model file's member {name!r} holds objects, not numbers")
    nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
    if offset + nbytes != info.file_size:
        raise ModelFileError(
            f"the model file is corrupted: member {name!r} declares shape {shape} of "
            f"{dtype} ({nbytes} bytes) but holds {info.file_size - offset} bytes"
        )
    return dtype, shape, nbytes


def _read_member(archive, info, dtype, shape) -> np.ndarray:
    try:
        with archive.open(info) as stream:
            array = np.lib.format.read_array(stream, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, RuntimeError) as exc:
        raise ModelFileError(
            f"the model file is corrupted or truncated (member {info.filename!r}): {exc}"
        ) from exc
    if array.dtype != dtype or array.shape != tuple(shape):
        raise ModelFileError(f"the model file's member {info.filename!r} changed while read")
    return array


def _parse_header(raw) -> dict:
    if raw is None:
        raise ModelFileError("not a gpmultirate model file: the archive has no 'header'")
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise ModelFileError("not a gpmultirate model file: 'header' is not a byte array")
    try:
        header = json.loads(bytes(raw).decode("utf-8"), parse_constant=_reject_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise ModelFileError(f"the model file header is not valid JSON: {exc}") from exc
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        raise ModelFileError(
            f"not a gpmultirate model file: the header's format is not {FORMAT_NAME!r}"
        )
    return header


def _reject_constant(token: str):
    raise ValueError(f"{token} is not allowed in the header")


def _check_versions(header: dict) -> None:
    version = header.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ModelFileError(f"invalid format_version {version!r} in the model file header")
    if version > FORMAT_VERSION:
        raise ModelFileError(
            f"the model file has format version {version}, newer than the version "
            f"{FORMAT_VERSION} this gpmultirate {__version__} reads; upgrade gpmultirate"
        )
    written_by = header.get("library_version")
    if _major(written_by) is None:
        raise ModelFileError(
            f"invalid library_version {written_by!r} in the model file header: expected a "
            f"version such as {__version__!r}"
        )
    if _major(written_by) != _major(__version__):
        raise ModelFileError(
            f"the model file was written by gpmultirate {written_by}, whose major version "
            f"differs from the running gpmultirate {__version__}; load it with gpmultirate "
            f"{_major(written_by)}.x, or refit the model"
        )


def _major(version) -> int | None:
    head = version.split(".")[0] if isinstance(version, str) else ""
    return int(head) if head.isdigit() else None


def _checksum(header: dict, arrays: dict[str, np.ndarray]) -> str:
    digest = hashlib.sha256()
    content = {key: value for key, value in header.items() if key != "sha256"}
    canonical = json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=False)
    digest.update(canonical.encode("utf-8") + b"\n")
    for name in sorted(arrays):
        array = arrays[name]
        shape = ",".join(str(n) for n in array.shape)
        digest.update(f"{name}:{array.dtype.str}:{shape}\n".encode("utf-8"))
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def _float_vector_or_matrix(name: str, array: np.ndarray) -> np.ndarray:
    ndims = (2,) if name == "coef_covariance" else (1, 2) if name.startswith("u_") else (1,)
    if array.dtype.kind != "f" or array.ndim not in ndims:
        expected = " or ".join(f"{n}-D" for n in ndims)
        raise ModelFileError(
            f"array {name!r} must be {expected} float; got {array.dtype} of shape {array.shape}"
        )
    return np.array(array, dtype=float)


def _several(model) -> bool:
    """Whether the model was fitted to a list of records (its predictions are lists then)."""
    return len(model.observation_.records) > 1


def _record_arrays(header: dict, name: str, version: int = 2) -> tuple[str, ...]:
    fitted = _section(header, "fitted")
    expected_layout = "timed" if version in (4, 5) else "records"
    if fitted.get("layout", "records") != expected_layout:
        raise ModelFileError(
            f"header entry 'layout' must be {expected_layout!r} in format version {version}; "
            f"got {fitted.get('layout')!r}")
    n = _integer(fitted, "n_records")
    if n < 1 or n > 100_000:
        raise ModelFileError(f"header entry 'n_records' must be in 1..100000; got {n}")
    if name == "LeastSquaresFIR":
        keys, extra = ("u", "sample_indices"), ("coef_covariance",)
    else:
        instants = "sample_times" if version in (4, 5) else "sample_indices"
        keys, extra = ("u", instants, "y_slow"), ()
    return ("coef", *[f"{key}_{r}" for r in range(n) for key in keys], *extra)


def _load_records(header: dict, arrays: dict, estimator: type, classes, timed: bool = False,
                  durations_in_periods: bool = False):
    """Versions 2, 4 and 5: the stored records, fitted again or with the stored estimate.

    A Gaussian process is conditioned on the stored data at the stored
    hyperparameters (version 4: the readings at their stored stamps, with
    the exposure and latency of the parameters); least squares keeps no slow
    output, so its observation is rebuilt from the inputs and instants and
    its estimate restored.
    """
    params = _decode_params(header, estimator, classes)
    fitted = _section(header, "fitted")
    n = _integer(fitted, "n_records")
    us = [arrays[f"u_{r}"] for r in range(n)]
    indices = [arrays[f"sample_{'times' if timed else 'indices'}_{r}"] for r in range(n)]
    ys = (
        [arrays[f"y_slow_{r}"] for r in range(n)] if estimator is FIRGaussianProcess
        else [np.zeros(index.shape[0]) for index in indices]
    )
    if not fitted.get("several_records") and n == 1:
        us, ys, indices = us[0], ys[0], indices[0]
    order = _integer(fitted, "order")
    if estimator is LeastSquaresFIR:
        experiment = build_experiment(
            us, ys, indices, order=order, initial_conditions=params.get("initial_conditions", "zero")
        )
        P = experiment.observation.n_coefficients
        coef, covariance = arrays["coef"], arrays["coef_covariance"]
        if coef.shape != (P,) or covariance.shape != (P, P):
            raise ModelFileError(
                f"coef and coef_covariance must have shapes ({P},) and ({P}, {P}); "
                f"got {coef.shape} and {covariance.shape}"
            )
        model = LeastSquaresFIR(**params)
        model.observation_ = experiment.observation
        model.n_inputs_ = experiment.n_inputs
        model.coef_ = coef.reshape(model.n_inputs_, -1) if model.n_inputs_ > 1 else coef
        model.noise_variance_ = _number(fitted, "noise_variance_")
        model.coef_covariance_ = covariance
        model.posterior_ = GaussianCoefficients(coef, covariance, np.zeros((0, P)))
        return model
    arguments = dict(
        params, kernel=_kernel_from_tree(fitted["kernel_"], classes),
        noise_level=_number(fitted, "noise_level_"), optimizer=None, normalize=False,
        order=order, **_stored_noise_bounds(fitted), **_stored_noise_kernel(fitted, classes),
    )
    if timed:
        _check_quadrature_nodes(fitted)
        # the stored stamps are in fast periods: fitted with the exposure and latency in fast
        # periods too (version 4 stores them so; version 5 in the units of sample_time)
        period = float(params.get("sample_time", 1.0))
        names = ("exposure", "latency")
        if durations_in_periods:
            in_periods = {name: params.get(name, 0.0) for name in names}
            params = dict(params, **{name: in_periods[name] * period for name in names})
        else:
            in_periods = {name: duration_in_fast_periods(params.get(name, 0.0), period)
                          for name in names}
        arguments.update(sample_time=1.0, **in_periods)
        model = _fit_stored(arguments, fitted, us, ys, sample_times=indices)
    else:
        # readings on the fast ticks are the fast samples of their indices: the exposure (0)
        # and the latency (whole periods) of the parameters are in the indices already
        arguments.update(exposure=0.0, latency=0.0)
        model = _fit_stored(arguments, fitted, us, ys, sample_indices=indices)
    if model.observation_.order != order:
        raise ModelFileError(
            f"inconsistent model file: order is {order!r} in the header "
            f"but {model.observation_.order} for the stored data"
        )
    _warn_if_not_reproduced(
        model.posterior_.coef, arrays["coef"], model.log_marginal_likelihood_value_,
        _number(fitted, "log_marginal_likelihood_value_"),
    )
    model.set_params(**{"normalize": True, **params})
    _restore_optimizer_result(model, fitted)
    _restore_resonances(model, fitted)
    _restore_tuning_results(model, fitted)
    return model


def _check_quadrature_nodes(fitted: dict) -> None:
    """The exposure windows are integrated as when the model was saved."""
    nodes = _integer(fitted, "quadrature_nodes")
    if nodes != QUADRATURE_NODES:
        warnings.warn(
            f"the model file was written with {nodes} quadrature nodes per exposure window; "
            f"this gpmultirate integrates with {QUADRATURE_NODES}, so a model with an "
            "exposure may differ slightly from the saved one",
            UserWarning, stacklevel=5,
        )


def _fit_stored(arguments: dict, fitted: dict, u, y_slow, **kwargs) -> FIRGaussianProcess:
    """The stored model fitted again at its stored hyperparameters.

    These are in the data's units, or (``hyperparameter_units_`` stored as
    ``"normalized"``) in the units of the data divided by the stored powers
    of two, which the fit of the stored data finds again.
    """
    model = FIRGaussianProcess(**arguments)
    kind = fitted.get("hyperparameter_units_", "data")
    if kind == "data":
        return model.fit(u, y_slow, **kwargs)
    if kind != "normalized":
        raise ModelFileError(
            f"header entry 'hyperparameter_units_' must be 'data' or 'normalized'; got {kind!r}")
    inputs = fitted.get("input_scale_exponents")
    output = fitted.get("output_scale_exponent")
    if not (isinstance(inputs, list) and inputs
            and all(isinstance(e, int) and not isinstance(e, bool) for e in inputs)
            and isinstance(output, int) and not isinstance(output, bool)):
        raise ModelFileError(
            "a model file with hyperparameters in normalized units must hold the integer "
            f"entries 'input_scale_exponents' and 'output_scale_exponent'; got {inputs!r} "
            f"and {output!r}"
        )
    model._prior_in_normalized_units = True
    try:
        with warnings.catch_warnings():
            # the stored model had it too: its hyperparameters stay in normalized units
            warnings.filterwarnings("ignore", message="kernel_ and noise_level_ are in "
                                    "normalized units", category=NumericalWarning)
            model.fit(u, y_slow, **kwargs)
    finally:
        del model._prior_in_normalized_units
    found = [int(e) for e in np.frexp(model.input_scale_)[1] - 1]
    if found != inputs or int(np.frexp(model.output_scale_)[1] - 1) != output:
        raise ModelFileError(
            "inconsistent model file: the stored data are not in the units of its normalized "
            f"hyperparameters (powers of two {inputs} and {output}, the data's "
            f"{found} and {int(np.frexp(model.output_scale_)[1] - 1)})"
        )
    return model


def _is_white(noise_kernel) -> bool:
    return isinstance(noise_kernel, str) and noise_kernel == "white"


def _stored_noise_kernel(fitted: dict, classes) -> dict:
    """The tuned noise kernel of the file as the ``noise_kernel`` to condition on, if any."""
    if "noise_kernel_" not in fitted:
        return {"noise_kernel": "white"}
    return {"noise_kernel": _kernel_from_tree(fitted["noise_kernel_"], classes)}


def _stored_noise_bounds(fitted: dict) -> dict:
    """The noise bounds the model was tuned with, in the data's units (files since 0.1)."""
    if "noise_level_bounds_" not in fitted:
        return {}
    return {"noise_level_bounds": _decode(fitted["noise_level_bounds_"])}


def _restore_resonances(model, fitted: dict) -> None:
    found = fitted.get("resonances_")
    if found is None:
        return
    if not isinstance(found, list) or any(
        not isinstance(r, dict) or set(r) != set(_RESONANCE_FIELDS) for r in found
    ):
        raise ModelFileError(f"invalid resonances_ in the model file: {found!r}")
    model.resonances_ = [
        Resonance(**{key: _decode(value) for key, value in r.items()}) for r in found
    ]


def _restore_tuning_results(model, fitted: dict) -> None:
    """``cv_log_predictive_likelihood_`` and ``order_selection_``, where the fit made them."""
    if "cv_log_predictive_likelihood_" in fitted:
        model.cv_log_predictive_likelihood_ = _number(fitted, "cv_log_predictive_likelihood_")
    selection = fitted.get("order_selection_")
    if selection is None:
        return
    if not isinstance(selection, dict) or set(selection) != set(_SELECTION_FIELDS):
        raise ModelFileError(f"invalid order_selection_ in the model file: {selection!r}")
    model.order_selection_ = {key: _decode(value) for key, value in selection.items()}


def _restore_optimizer_result(model, fitted: dict) -> None:
    result = fitted.get("optimizer_result_")
    if result is not None:
        if not isinstance(result, dict) or set(result) - set(_OPTIMIZER_FIELDS):
            raise ModelFileError(f"invalid optimizer_result_ in the model file: {result!r}")
        model.optimizer_result_ = OptimizeResult(
            {key: _decode(value) for key, value in result.items()}
        )


def _load_gaussian_process(header: dict, arrays: dict, classes) -> FIRGaussianProcess:
    params = _decode_params(header, FIRGaussianProcess, classes)
    fitted = _section(header, "fitted")
    # the last step of fit, at the stored hyperparameters
    refit = dict(
        params,
        kernel=_kernel_from_tree(fitted["kernel_"], classes),
        noise_level=_number(fitted, "noise_level_"),
        optimizer=None,
        # the stored kernel and noise level are in the data's units
        normalize=False,
        # the order that was fitted (the parameter may be "auto" or a list)
        order=_integer(fitted, "order"),
        **_stored_noise_bounds(fitted),
        **_stored_noise_kernel(fitted, classes),
    )
    model = _fit_stored(refit, fitted, arrays["u"], arrays["y_slow"])
    _check_layout(model.observation_, fitted)
    _warn_if_not_reproduced(
        model.coef_, arrays["coef"],
        model.log_marginal_likelihood_value_, _number(fitted, "log_marginal_likelihood_value_"),
    )
    model.set_params(**{"normalize": True, **params})
    _restore_optimizer_result(model, fitted)
    _restore_resonances(model, fitted)
    _restore_tuning_results(model, fitted)
    return model


def _load_least_squares(header: dict, arrays: dict) -> LeastSquaresFIR:
    # fit keeps no y_slow, so the fitted arrays are restored rather than recomputed
    params = _decode_params(header, LeastSquaresFIR)
    fitted = _section(header, "fitted")
    model = LeastSquaresFIR(**params)
    observation = DownsampledConvolution(
        arrays["u"], _integer(fitted, "factor"), _integer(fitted, "order"),
        _integer(fitted, "offset"),
    )
    _check_layout(observation, {key: getattr(model, key) for key in ("factor", "order", "offset")})
    coef, covariance = arrays["coef"], arrays["coef_covariance"]
    P = observation.order
    if coef.shape != (P,) or covariance.shape != (P, P):
        raise ModelFileError(
            f"coef and coef_covariance must have shapes ({P},) and ({P}, {P}); "
            f"got {coef.shape} and {covariance.shape}"
        )
    model.observation_ = observation
    model.n_inputs_ = 1
    model.coef_ = coef
    model.noise_variance_ = _number(fitted, "noise_variance_")
    model.coef_covariance_ = covariance
    model.posterior_ = GaussianCoefficients(coef, covariance, np.zeros((0, P)))
    return model


def _decode_params(header: dict, estimator: type, classes=KERNEL_CLASSES) -> dict:
    params = _section(header, "params")
    unknown = set(params) - set(estimator().get_params(deep=False))
    if unknown:
        raise ModelFileError(
            f"unknown {estimator.__name__} parameters {sorted(unknown)} in the model file"
        )
    return {key: _decode(value, classes) for key, value in params.items()}


def _section(header: dict, key: str) -> dict:
    value = header.get(key)
    if not isinstance(value, dict):
        raise ModelFileError(f"the model file header has no {key!r} object")
    return value


def _number(section: dict, key: str) -> float:
    value = _decode(section.get(key))
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelFileError(f"header entry {key!r} must be a number; got {value!r}")
    return float(value)


def _integer(section: dict, key: str) -> int:
    value = section.get(key)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ModelFileError(f"header entry {key!r} must be an integer; got {value!r}")
    return value


def _check_layout(observation: DownsampledConvolution, fitted: dict) -> None:
    for key in ("factor", "order", "offset"):
        if fitted.get(key) != getattr(observation, key):
            raise ModelFileError(
                f"inconsistent model file: {key} is {fitted.get(key)!r} in the header "
                f"but {getattr(observation, key)} for the stored data"
            )


#: the relative difference (of the coefficients to their largest, of the log evidence)
#: up to which a loaded model counts as the saved one: the same libraries with another
#: number of BLAS threads sum in another order (4.2e-12 on a camera log's model saved
#: by ``gpmultirate fit`` and loaded in one thread)
REPRODUCED_RTOL = 1e-8


def _warn_if_not_reproduced(coef, saved_coef, evidence, saved_evidence) -> None:
    if coef.shape != saved_coef.shape:
        raise ModelFileError(
            f"inconsistent model file: {saved_coef.shape[0]} saved coefficients for "
            f"order {coef.shape[0]}"
        )
    scale = float(np.max(np.abs(saved_coef))) if saved_coef.size else 1.0
    scale = scale or 1.0
    close = (np.max(np.abs(coef - saved_coef), initial=0.0) <= REPRODUCED_RTOL * scale
             and abs(evidence - saved_evidence) <= REPRODUCED_RTOL * max(1.0, abs(saved_evidence)))
    if close or (np.array_equal(coef, saved_coef) and evidence == saved_evidence):
        return
    warnings.warn(
        "the loaded model differs from the saved one (coefficients by up to "
        f"{np.max(np.abs(coef - saved_coef)) / scale:.2g} relative, log marginal "
        f"likelihood {evidence!r} instead of {saved_evidence!r}); the numerical "
        "libraries differ from those that wrote the file",
        UserWarning,
        stacklevel=4,
    )


# ------------------------------------------------------ plain-data values
def _encode(value, where: str):
    """Return a JSON value that :func:`_decode` turns back into ``value``."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if np.isfinite(value) else {"type": "float", "value": repr(value)}
    if isinstance(value, tuple):
        return {"type": "tuple", "items": [_encode(item, where) for item in value]}
    if isinstance(value, list):
        return [_encode(item, where) for item in value]
    if isinstance(value, np.ndarray) and value.dtype.name in _ARRAY_DTYPES:
        return {
            "type": "ndarray",
            "dtype": value.dtype.name,
            "shape": list(value.shape),
            "data": [_encode(item, where) for item in value.ravel().tolist()],
        }
    if isinstance(value, Kernel):
        return {"type": "kernel", "tree": describe_kernel(value)}
    if isinstance(value, np.random.RandomState):
        kind, keys, position, has_gauss, cached = value.get_state(legacy=True)
        return {
            "type": "RandomState",
            "keys": keys.tolist(),
            "pos": int(position),
            "has_gauss": int(has_gauss),
            "cached_gaussian": float(cached),
        }
    raise ValueError(
        f"cannot save {where} of type {type(value).__name__}: model files hold numbers, "
        "strings, tuples, lists, numeric arrays, kernels and numpy RandomState only"
    )


def _decode(value, classes=KERNEL_CLASSES):
    """The value :func:`_encode` encoded; kernels only of ``classes``."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        return [_decode(item, classes) for item in value]
    kind = value.get("type") if isinstance(value, dict) else None
    if kind == "kernel":
        return _kernel_from_tree(value.get("tree"), classes)
    try:
        if kind == "float" and value["value"] in _NON_FINITE:
            return _NON_FINITE[value["value"]]
        if kind == "tuple" and isinstance(value["items"], list):
            return tuple(_decode(item, classes) for item in value["items"])
        if kind == "ndarray" and value["dtype"] in _ARRAY_DTYPES:
            data = [_decode(item, classes) for item in value["data"]]
            return np.array(data, dtype=value["dtype"]).reshape(value["shape"])
        if kind == "RandomState":
            random_state = np.random.RandomState()
            random_state.set_state(
                (
                    "MT19937",
                    np.array(value["keys"], dtype=np.uint32),
                    int(value["pos"]),
                    int(value["has_gauss"]),
                    float(value["cached_gaussian"]),
                )
            )
            return random_state
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ModelFileError(f"malformed {kind} value in the model file header: {exc}") from exc
    raise ModelFileError(f"unsupported value in the model file header: {value!r}")


def _encode_optimizer_result(result) -> dict:
    return {
        key: _encode(
            result[key].decode() if isinstance(result[key], bytes) else result[key],
            f"optimizer_result_.{key}",
        )
        for key in _OPTIMIZER_FIELDS
        if key in result
    }
