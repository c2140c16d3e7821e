"""Read named columns of measured data from CSV, NumPy ``.npz`` and MATLAB ``.mat`` files.

The rows of a file are fast samples.  :func:`read_slow_samples` finds the
slow-sample instants of an output column from its empty cells.  A column is
named by

* its header name in a CSV file (comma-separated, UTF-8, a header row,
  empty cells or ``NaN`` for samples that were not measured);
* the name of a 1-D array (or a single-row / single-column 2-D array) in an
  ``.npz`` or ``.mat`` file;
* ``name:index`` for column ``index`` (from 0) of a 2-D array.

Every problem raises :class:`DataFileError`, a :class:`ValueError` whose
one-line message names the file and what is wrong.  Nothing is executed or
unpickled: ``.npz`` files are opened with ``allow_pickle=False`` and MATLAB
files of version 7.3 (HDF5) are refused with a hint to save them with
``-v7``.
"""

from __future__ import annotations

import csv
import difflib
import os
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sklearn.utils.validation import check_is_fitted

from gpmultirate.exceptions import DataFileError
from gpmultirate.units import in_fast_periods

__all__ = ["DataFileError", "DataTable", "SlowLog", "SlowSamples", "check_folder",
           "model_slow_samples", "read_columns", "read_record", "read_slow_log",
           "read_slow_samples", "read_table", "write_file", "write_folder"]

#: The largest number of columns a CSV file may have.
MAX_COLUMNS = 100_000
_SUFFIXES = (".csv", ".npz", ".mat")
_MAT_HEADER = 128


def _short(text: str, limit: int = 40) -> str:
    text = repr(text)
    return text if len(text) <= limit else text[: limit - 4] + "...'"


def _bare_name(name: str) -> str:
    """A header name without a trailing unit: ``'u [V]'``, ``'u (V)'``, ``'u / V'`` give ``'u'``.
    """
    bare = re.sub(r"\s*(\[[^\]]*\]|\([^)]*\)|\{[^}]*\}|/\s*[^/\s]+)\s*$", "", name.strip())
    return bare or name.strip()


def _split_spec(spec: str) -> tuple[str, int | None]:
    name, sep, index = spec.rpartition(":")
    if sep and name and index.strip().lstrip("-").isdigit():
        return name, int(index)
    return spec, None


class DataTable:
    """The variables of a data file, converted to float columns on request.

    Build it with :func:`read_table`.

    Attributes
    ----------
    path : str
        The file.
    names : tuple of str
        The header names (CSV) or variable names (``.npz``, ``.mat``).

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.io import read_table
    >>> path = os.path.join(tempfile.mkdtemp(), "data.csv")
    >>> with open(path, "w") as f:
    ...     _ = f.write("u,y\\n1,2\\n3,\\n")
    >>> table = read_table(path)
    >>> table.names, table.column("y")
    (('u', 'y'), array([ 2., nan]))
    """

    def __init__(self, path, names, fetch):
        self.path = str(path)
        self.names = tuple(names)
        self._fetch = fetch

    def __repr__(self) -> str:
        return f"DataTable({self.path!r}, names={list(self.names)[:10]!r})"

    def _error(self, problem: str) -> DataFileError:
        return DataFileError(self.path, problem)

    def column(self, spec: str) -> np.ndarray:
        """The float column ``spec``: a name, or ``name:index`` of a 2-D array.

        Parameters
        ----------
        spec : str

        Returns
        -------
        ndarray of shape (n_rows,)
            A new float array; ``NaN`` where the file has an empty cell or
            ``NaN``.

        Raises
        ------
        DataFileError
            Unknown column, non-numeric values, infinite values, a variable
            that is not a numeric vector or matrix.
        """
        if not isinstance(spec, str) or not spec:
            raise self._error(f"column names must be non-empty strings; got {spec!r}")
        if spec in self.names:
            name, index = spec, None
        else:
            name, index = _split_spec(spec)
            if name not in self.names:
                name = self._by_bare_name(spec, name)
        values = np.asarray(self._fetch(name))
        if values.ndim == 2 and 1 in values.shape and index is None:
            values = values.reshape(-1)
        if index is not None:
            if values.ndim != 2:
                raise self._error(f"column {_short(spec)}: {name!r} is not a 2-D array, so "
                                  f"it takes no ':index' (use {name!r})")
            if not 0 <= index < values.shape[1]:
                raise self._error(f"column {_short(spec)}: index {index} is out of range "
                                  f"0..{values.shape[1] - 1} of {name!r}")
            values = values[:, index]
        elif values.ndim == 2:
            raise self._error(f"column {_short(spec)} is a {values.shape[0]} x "
                              f"{values.shape[1]} array: name one of its columns as "
                              f"'{name}:0' .. '{name}:{values.shape[1] - 1}'")
        if values.ndim != 1:
            raise self._error(f"column {_short(spec)} has {values.ndim} dimensions; a column "
                              "is a 1-D array or a column of a 2-D array")
        if values.shape[0] == 0:
            raise self._error(f"column {_short(spec)} has no rows")
        column = np.array(values, dtype=float)  # a copy
        infinite = np.flatnonzero(np.isinf(column))
        if infinite.size:
            raise self._error(f"column {_short(spec)} has an infinite value at row "
                              f"{infinite[0]}; mark missing samples with an empty cell or NaN")
        return column

    def _by_bare_name(self, spec: str, name: str) -> str:
        """The header name whose bare name (its unit dropped) is ``name``, or an error
        naming the near matches."""
        bare = [n for n in self.names if _bare_name(n) == name]
        if len(bare) == 1:
            return bare[0]
        if len(bare) > 1:
            raise self._error(f"column {_short(spec)} is ambiguous: "
                              + ", ".join(_short(n, 24) for n in bare) + " (name one in full)")
        near = difflib.get_close_matches(name, list(self.names), n=3, cutoff=0.6)
        near += [n for n in difflib.get_close_matches(
            name, [_bare_name(n) for n in self.names], n=3, cutoff=0.6) if n not in near]
        near = [n for n in self.names if n in near or _bare_name(n) in near][:3]
        known = ", ".join(_short(n, 24) for n in self.names[:12])
        more = f" and {len(self.names) - 12} more" if len(self.names) > 12 else ""
        hint = (f"; did you mean {' or '.join(_short(n, 24) for n in near)}?" if near else "")
        raise self._error(f"no column {_short(spec)}{hint} (columns: {known}{more})")

    def columns(self, specs) -> dict[str, np.ndarray]:
        """Several columns of the same length, by name.

        Parameters
        ----------
        specs : sequence of str

        Returns
        -------
        dict of str to ndarray of shape (n_rows,)

        Raises
        ------
        DataFileError
            As :meth:`column`, or if the columns differ in length.
        """
        out = {spec: self.column(spec) for spec in specs}
        lengths = {spec: c.shape[0] for spec, c in out.items()}
        if len(set(lengths.values())) > 1:
            detail = ", ".join(f"{_short(s)}: {n}" for s, n in lengths.items())
            raise self._error(f"the columns differ in length ({detail})")
        return out


# --------------------------------------------------------------------- CSV
def _parse_cell(path, cell: str, line: int, name: str) -> float:
    text = cell.strip()
    if not text:
        return np.nan
    try:
        return float(text)
    except ValueError:
        raise DataFileError(path, f"line {line}, column {_short(name)}: "
                                  f"{_short(text)} is not a number") from None


def _read_csv(path: Path) -> DataTable:
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise DataFileError(path, f"cannot be read ({error.strerror or error})") from None
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark is dropped
    except UnicodeDecodeError as error:
        raise DataFileError(path, f"is not UTF-8 text (byte {error.start}); save it as "
                                  "UTF-8") from None
    if "\x00" in text:
        raise DataFileError(path, "contains NUL bytes: not a text file")
    lines = text.splitlines()
    if not any(line.strip() for line in lines):
        raise DataFileError(path, "is empty")
    # comment lines ('#') and blank lines before the header are skipped; the messages
    # still count the file's lines
    skipped = 0
    while skipped < len(lines) and (not lines[skipped].strip()
                                    or lines[skipped].lstrip().startswith("#")):
        skipped += 1
    if skipped == len(lines):
        raise DataFileError(path, "has only comment lines ('#'), no header")
    try:
        reader = csv.reader(lines[skipped:], strict=True)
        header = next(reader)
        rows = []
        for row in reader:
            if row and not row[0].lstrip().startswith("#"):
                # a blank or comment line is skipped; a row of empty cells is a row of NaN
                rows.append((skipped + reader.line_num, row))
    except csv.Error as error:
        raise DataFileError(path, f"is not valid CSV ({error})") from None
    names = [name.strip() for name in header]
    if len(names) > MAX_COLUMNS:
        raise DataFileError(path, f"has {len(names)} columns; at most {MAX_COLUMNS} are read")
    if len(names) == 1:
        for sep, label in ((";", "';'"), ("\t", "tabs")):
            if sep in names[0]:
                raise DataFileError(path, f"the header is separated by {label}; columns must "
                                          "be separated by commas")
    empty = [k for k, name in enumerate(names) if not name]
    if empty:
        raise DataFileError(path, f"the header has an empty name in column {empty[0] + 1}")
    seen: dict[str, int] = {}
    for k, name in enumerate(names):
        if name in seen:
            raise DataFileError(path, f"the header names column {_short(name)} twice "
                                      f"(columns {seen[name] + 1} and {k + 1})")
        seen[name] = k
    if not rows:
        raise DataFileError(path, "has a header but no data rows")
    for line, row in rows:
        if len(row) != len(names):
            hint = ""
            if line == rows[0][0] and all(len(r) == len(row) for _, r in rows[:20]):
                hint = (f" (if line {skipped + 1} is not the header, mark it as a comment "
                        "with '#')")
            raise DataFileError(path, f"line {line} has {len(row)} fields; the header (line "
                                      f"{skipped + 1}) has {len(names)}{hint}")

    def fetch(name: str) -> np.ndarray:
        k = seen[name]
        return np.array([_parse_cell(path, row[k], line, name) for line, row in rows])

    return DataTable(path, names, fetch)


# -------------------------------------------------------------- NumPy, MATLAB
def _check_numeric(path, name: str, values) -> np.ndarray:
    if not isinstance(values, np.ndarray):
        raise DataFileError(path, f"variable {_short(name)} is a {type(values).__name__}, not "
                                  "a numeric array")
    kind = values.dtype.kind
    if values.dtype.names is not None:
        raise DataFileError(path, f"variable {_short(name)} is a struct (record) array; store "
                                  "its fields as separate numeric variables")
    if kind == "O":
        raise DataFileError(path, f"variable {_short(name)} holds objects (e.g. a cell array); "
                                  "store a numeric array")
    if kind == "c":
        raise DataFileError(path, f"variable {_short(name)} is complex; store a real array")
    if kind not in "biuf":
        raise DataFileError(path, f"variable {_short(name)} is not numeric "
                                  f"(dtype {values.dtype.str})")
    if values.ndim == 0:
        raise DataFileError(path, f"variable {_short(name)} is a scalar (0-d array); a column "
                                  "needs one value per row")
    if values.ndim > 2:
        raise DataFileError(path, f"variable {_short(name)} has {values.ndim} dimensions; "
                                  "store 1-D or 2-D arrays")
    return values


def _read_npz(path: Path) -> DataTable:
    try:
        with np.load(path, allow_pickle=False) as archive:
            names = list(archive.files)
            arrays = {}
            for name in names:
                try:
                    arrays[name] = archive[name]
                except ValueError as error:
                    if "pickle" in str(error):
                        arrays[name] = DataFileError(
                            path, f"variable {_short(name)} holds Python objects; it is not "
                                  "unpickled (store a numeric array)")
                    else:
                        arrays[name] = DataFileError(
                            path, f"variable {_short(name)} cannot be read ({error})")
    except DataFileError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as error:
        raise DataFileError(path, f"is not a readable .npz archive ({error})") from None
    except Exception as error:  # any other failure of a corrupted archive
        raise DataFileError(path, f"is not a readable .npz archive "
                                  f"({type(error).__name__}: {error})") from None
    if not isinstance(arrays, dict) or not names:
        raise DataFileError(path, "holds no arrays")

    def fetch(name: str) -> np.ndarray:
        value = arrays[name]
        if isinstance(value, DataFileError):
            raise value
        return _check_numeric(path, name, value)

    return DataTable(path, names, fetch)


def _mat_version(path: Path) -> int | None:
    """The version field of a MATLAB 5+ header (0x0100 for v5-v7, 0x0200 for v7.3)."""
    try:
        with open(path, "rb") as stream:
            header = stream.read(_MAT_HEADER)
    except OSError as error:
        raise DataFileError(path, f"cannot be read ({error.strerror or error})") from None
    if len(header) < _MAT_HEADER:
        return None
    endian = header[126:128]
    if endian == b"IM":
        return int.from_bytes(header[124:126], "little")
    if endian == b"MI":
        return int.from_bytes(header[124:126], "big")
    return None


def _read_mat(path: Path) -> DataTable:
    from scipy import io as sio

    if path.stat().st_size == 0:
        raise DataFileError(path, "is empty")
    hdf5 = "is a MATLAB v7.3 (HDF5) file, which is not read; save it with save(..., '-v7')"
    if _mat_version(path) == 0x0200:
        raise DataFileError(path, hdf5)
    try:
        listing = sio.whosmat(str(path))
    except NotImplementedError:  # scipy's word for a v7.3 file it recognizes itself
        raise DataFileError(path, hdf5) from None
    except Exception as error:  # scipy raises many types for corrupted files
        raise DataFileError(path, f"is not a readable MATLAB file "
                                  f"({type(error).__name__}: {error})") from None
    names = [entry[0] for entry in listing]
    classes = {entry[0]: entry[2] for entry in listing}
    if not names:
        raise DataFileError(path, "holds no variables")

    def fetch(name: str) -> np.ndarray:
        kind = classes.get(name)
        if kind in ("struct", "object"):
            raise DataFileError(path, f"variable {_short(name)} is a MATLAB {kind}; store its "
                                      "fields as separate numeric variables")
        if kind == "cell":
            raise DataFileError(path, f"variable {_short(name)} is a cell array; store a "
                                      "numeric array")
        if kind == "sparse":
            raise DataFileError(path, f"variable {_short(name)} is sparse; store it with "
                                      "full(...)")
        if kind == "char":
            raise DataFileError(path, f"variable {_short(name)} is text (char); store a "
                                      "numeric array")
        try:
            content = sio.loadmat(str(path), variable_names=[name], mat_dtype=False)
        except Exception as error:  # corrupted content
            raise DataFileError(path, f"variable {_short(name)} cannot be read "
                                      f"({type(error).__name__}: {error})") from None
        if name not in content:
            raise DataFileError(path, f"variable {_short(name)} cannot be read")
        return _check_numeric(path, name, content[name])

    return DataTable(path, names, fetch)


# ------------------------------------------------------------------ entry
def read_table(path) -> DataTable:
    """Open a CSV, ``.npz`` or ``.mat`` data file (chosen by its suffix).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    DataTable
        Its columns are converted on request by :meth:`DataTable.column`.

    Raises
    ------
    DataFileError
        A missing or unreadable file, an unknown suffix, or a malformed
        file; the message names the file and the problem.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from gpmultirate.io import read_table
    >>> path = os.path.join(tempfile.mkdtemp(), "data.npz")
    >>> np.savez(path, u=np.arange(3.0), Y=np.ones((3, 2)))
    >>> table = read_table(path)
    >>> sorted(table.names), table.column("Y:1")
    (['Y', 'u'], array([1., 1., 1.]))
    """
    try:
        path = Path(os.fspath(path))
    except TypeError:
        raise DataFileError(path, "is not a file name") from None
    try:
        if not path.exists():
            raise DataFileError(path, "does not exist")
        if not path.is_file():
            raise DataFileError(path, "is not a file")
    except OSError as error:  # e.g. a name too long for the file system
        raise DataFileError(path, f"cannot be opened ({error.strerror or error})") from None
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return _read_csv(path)
    if suffix == ".npz":
        return _read_npz(path)
    if suffix == ".mat":
        return _read_mat(path)
    raise DataFileError(path, f"has the unknown suffix {_short(path.suffix or '(none)')}; "
                              f"expected one of {', '.join(_SUFFIXES)}")


def read_columns(path, specs) -> dict[str, np.ndarray]:
    """Read named float columns of one length from a data file.

    Parameters
    ----------
    path : str or path-like
        A ``.csv``, ``.npz`` or ``.mat`` file.
    specs : sequence of str
        Column names, or ``name:index`` for a column of a 2-D array.

    Returns
    -------
    dict of str to ndarray of shape (n_rows,)
        New float arrays; ``NaN`` marks an empty cell.

    Raises
    ------
    DataFileError

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.io import DataFileError, read_columns
    >>> path = os.path.join(tempfile.mkdtemp(), "data.csv")
    >>> with open(path, "w") as f:
    ...     _ = f.write("u,y\\n1,2\\n3,oops\\n")
    >>> read_columns(path, ["u"])
    {'u': array([1., 3.])}
    >>> try:
    ...     read_columns(path, ["y"])
    ... except DataFileError as error:
    ...     print(error.problem)
    line 3, column 'y': 'oops' is not a number
    """
    return read_table(path).columns(specs)


def read_record(path, inputs, output: str | None = None, *, complete: bool = False):
    """Read a record's input columns, and its output column, from a data file.

    Parameters
    ----------
    path : str or path-like
        A ``.csv``, ``.npz`` or ``.mat`` file (see :func:`read_columns`).
    inputs : sequence of str
        The input columns; every row must hold a value.
    output : str, optional
        The output column: ``NaN`` where nothing was measured (see
        :func:`read_slow_samples`).
    complete : bool, default False
        Require the output at every row (validation data).

    Returns
    -------
    u : ndarray of shape (n_rows,) or (n_rows, n_inputs)
        The inputs, one column per input when there are several.
    y : ndarray of shape (n_rows,) or None
        The output column, or None without ``output``.

    Raises
    ------
    DataFileError
        The file or a column cannot be read, or a value is missing where one
        is required; the message names the file, the column and the row.

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.io import read_record
    >>> path = os.path.join(tempfile.mkdtemp(), "data.csv")
    >>> with open(path, "w") as f:
    ...     _ = f.write("u,y\\n1,2\\n3,\\n5,6\\n")
    >>> read_record(path, ["u"], "y")
    (array([1., 3., 5.]), array([ 2., nan,  6.]))
    """
    columns = read_columns(path, [*inputs] + ([] if output is None else [output]))
    required = [*inputs] + ([output] if complete and output is not None else [])
    for name in required:
        missing = np.flatnonzero(np.isnan(columns[name]))
        if missing.size:
            what = "inputs" if name in inputs else "the output of validation data"
            raise DataFileError(path, f"{'input' if name in inputs else 'output'} column "
                                      f"{name!r} has a missing value (empty or NaN) at row "
                                      f"{missing[0]}; {what} must be measured at every row")
    u = np.column_stack([columns[name] for name in inputs])
    return (u[:, 0] if u.shape[1] == 1 else u), (None if output is None else columns[output])


@dataclass(frozen=True)
class SlowSamples:
    """The measured samples of an output column and where they lie on the fast grid.

    Build it with :func:`read_slow_samples`.  The samples lie either on a
    uniform slow grid (``offset`` is an int: rows ``offset, offset + factor,
    ...``, some of which may be missing) or at irregular instants (``offset``
    is None).

    Attributes
    ----------
    indices : ndarray of int, shape (n_measured,)
        Rows (fast-sample indices) of the measured samples, increasing.
    values : ndarray of float, shape (n_measured,)
        The measured values.
    n_samples : int
        Rows of the column: the number of fast samples ``N``.
    factor : int
        Spacing of the slow grid; for irregular instants the median spacing
        (the slow Nyquist frequency of plots).
    offset : int or None
        Row of the first grid sample, or None for irregular instants.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.io import read_slow_samples
    >>> samples = read_slow_samples([np.nan, 1.0, np.nan, np.nan, 2.0, np.nan])
    >>> samples.factor, samples.offset, samples.indices
    (3, 1, array([1, 4]))
    """

    indices: np.ndarray
    values: np.ndarray
    n_samples: int
    factor: int
    offset: int | None

    @property
    def uniform(self) -> bool:
        """Whether the samples lie on the uniform grid ``offset + factor * k``."""
        return self.offset is not None

    @property
    def n_missing(self) -> int:
        """Samples of the uniform grid that were not measured (0 for irregular instants)."""
        if not self.uniform:
            return 0
        return len(range(self.offset, self.n_samples, self.factor)) - self.values.shape[0]

    @property
    def y_slow(self) -> np.ndarray:
        """The ``y_slow`` argument of ``fit``: on a uniform grid every grid sample, ``NaN``
        where one is missing; otherwise the measured values."""
        if not self.uniform:
            return self.values.copy()
        y_slow = np.full(len(range(self.offset, self.n_samples, self.factor)), np.nan)
        y_slow[(self.indices - self.offset) // self.factor] = self.values
        return y_slow

    @property
    def estimator_params(self) -> dict:
        """Constructor arguments of the estimator: ``factor`` and ``offset`` on a uniform
        grid, none for irregular instants."""
        return {"factor": self.factor, "offset": self.offset} if self.uniform else {}

    @property
    def fit_params(self) -> dict:
        """Keyword arguments of ``fit`` beside ``y_slow``: ``sample_indices`` for irregular
        instants, none on a uniform grid."""
        return {} if self.uniform else {"sample_indices": self.indices.copy()}

    @property
    def description(self) -> str:
        """One phrase describing the sampling, e.g. ``'one sample in 3, from row 1'``."""
        if not self.uniform:
            return f"irregular instants, median spacing {self.factor}"
        text = f"one sample in {self.factor}, from row {self.offset}"
        return text + (f", {self.n_missing} missing" if self.n_missing else "")


def read_slow_samples(column, *, factor: int | None = None,
                      offset: int | None = None) -> SlowSamples:
    """The slow samples of an output column whose unmeasured rows are ``NaN``.

    A data file's output column holds a value at the rows where the output
    was measured and an empty cell (``NaN``, as :func:`read_columns` returns
    it) elsewhere.  Without ``factor`` and ``offset`` the sampling is read
    from that pattern: the slow grid's spacing is the median spacing of the
    measured rows, and when every measured row lies on that grid the samples
    are placed on it (missing grid samples become ``NaN`` in
    :attr:`SlowSamples.y_slow`); otherwise they are irregular instants.
    With ``factor`` (and ``offset``, default 0) the rows ``offset, offset +
    factor, ...`` are kept, as from a fully measured output, and the finite
    ones among them are the measured samples.

    Parameters
    ----------
    column : array-like of shape (n_samples,)
        One value per fast sample, ``NaN`` where nothing was measured.
    factor : int, optional
        Keep every ``factor``-th row.
    offset : int, optional
        Row of the first kept sample, in ``0 .. factor - 1``; only used with
        ``factor`` or alone (then ``factor`` is 1).

    Returns
    -------
    SlowSamples
        Its :attr:`~SlowSamples.estimator_params`, :attr:`~SlowSamples.y_slow`
        and :attr:`~SlowSamples.fit_params` are the arguments of
        :class:`~gpmultirate.FIRGaussianProcess`.

    Raises
    ------
    ValueError
        If ``column`` is not one-dimensional or holds an infinite value,
        ``factor`` or ``offset`` is out of range, or no kept row is measured.

    Examples
    --------
    Every third row measured, one of them missing:

    >>> import numpy as np
    >>> from gpmultirate.io import read_slow_samples
    >>> y = np.full(15, np.nan)
    >>> y[[1, 4, 7, 13]] = [0.5, 0.25, 0.75, 1.0]
    >>> samples = read_slow_samples(y)
    >>> samples.description
    'one sample in 3, from row 1, 1 missing'
    >>> samples.estimator_params, samples.y_slow
    ({'factor': 3, 'offset': 1}, array([0.5 , 0.25, 0.75,  nan, 1.  ]))

    Rows off the grid make the instants irregular:

    >>> y[9] = 2.0
    >>> samples = read_slow_samples(y)
    >>> samples.offset is None, samples.fit_params
    (True, {'sample_indices': array([ 1,  4,  7,  9, 13])})

    which fit as ``FIRGaussianProcess(**samples.estimator_params).fit(u,
    samples.y_slow, **samples.fit_params)``.
    """
    y = np.array(column, dtype=float)  # a copy: the caller's array is never touched
    if y.ndim != 1:
        raise ValueError(f"column must be one-dimensional; got shape {y.shape}")
    infinite = np.flatnonzero(np.isinf(y))
    if infinite.size:
        raise ValueError(f"column must hold finite values or NaN; row {infinite[0]} is "
                         f"{y[infinite[0]]}")
    n = y.shape[0]
    if factor is not None or offset is not None:
        factor = 1 if factor is None else _count(factor, "factor", 1)
        offset = 0 if offset is None else _count(offset, "offset", 0)
        if offset >= factor:
            raise ValueError(f"offset must lie in 0..factor-1 = 0..{factor - 1}; got {offset}")
        if offset >= n:
            raise ValueError(f"offset must be below the {n} rows of the column; got {offset}")
        grid = np.arange(offset, n, factor)
        measured = grid[np.isfinite(y[grid])]
        if measured.size == 0:
            raise ValueError("column has no measured (finite) value at the kept rows")
    else:
        measured = np.flatnonzero(np.isfinite(y))
        if measured.size == 0:
            raise ValueError("column has no measured (finite) value")
        factor = (max(1, int(round(float(np.median(np.diff(measured))))))
                  if measured.size > 1 else 1)
        offset = int(measured[0] % factor)
    uniform = bool(np.all((measured - offset) % factor == 0))
    return SlowSamples(indices=measured, values=y[measured], n_samples=n, factor=int(factor),
                       offset=int(offset) if uniform else None)


@dataclass(frozen=True)
class SlowLog:
    """Readings of a slow sensor with their own time stamps, beside a fast record.

    Build it with :func:`read_slow_log`.  It has the attributes of
    :class:`SlowSamples` that describe the sampling (``indices`` are the
    fast ticks at or before the stamps), so a report of the fit reads it
    alike.

    Attributes
    ----------
    stamps : ndarray of shape (M,)
        The time stamps in seconds, strictly increasing, in ``[0, N T)``.
    sample_times : ndarray of shape (M,)
        The stamps in fast sample periods, ``stamps / T`` (within ``1e-9`` of
        a tick: the tick, :func:`gpmultirate.units.in_fast_periods`), as an
        estimator of ``sample_time=T`` reads the stamps.
    values : ndarray of shape (M,) or None
        The readings (``NaN`` where one is missing); None for stamps alone.
    n_samples : int
        ``N``, the fast samples of the record.
    sample_time : float
        ``T`` in seconds.
    exposure, latency : float
        The sensor's exposure and latency in seconds.

    Examples
    --------
    >>> import numpy as np
    >>> log = SlowLog(np.array([0.0025, 0.0061]), np.array([2.5, 6.1]), np.array([1.0, 2.0]),
    ...               10, 0.001)
    >>> log.indices, log.factor, log.fit_params
    (array([2, 6]), 4, {'sample_times': array([0.0025, 0.0061])})

    which fit as ``FIRGaussianProcess(sample_time=log.sample_time,
    **log.estimator_params).fit(u, log.y_slow, **log.fit_params)``.
    """

    stamps: np.ndarray
    sample_times: np.ndarray
    values: np.ndarray | None
    n_samples: int
    sample_time: float
    exposure: float = 0.0
    latency: float = 0.0

    offset = None
    uniform = False
    n_missing = 0

    @property
    def indices(self) -> np.ndarray:
        """The fast tick at or before each stamp."""
        return np.floor(self.sample_times).astype(np.int64)

    @property
    def factor(self) -> int:
        """The median spacing of the stamps in fast sample periods, rounded (at least 1)."""
        if self.sample_times.shape[0] < 2:
            return 1
        return max(1, int(round(float(np.median(np.diff(self.sample_times))))))

    @property
    def y_slow(self) -> np.ndarray:
        """The ``y_slow`` argument of ``fit``: the readings, ``NaN`` where missing."""
        if self.values is None:
            raise ValueError("the slow log has stamps only: no readings were read")
        return self.values.copy()

    @property
    def estimator_params(self) -> dict:
        """Constructor arguments of the estimator: ``exposure`` and ``latency`` in seconds,
        the units of its ``sample_time`` (the log's ``sample_time``)."""
        return {"exposure": self.exposure, "latency": self.latency}

    @property
    def fit_params(self) -> dict:
        """Keyword arguments of ``fit`` beside ``y_slow``: ``sample_times``, the stamps in
        seconds (the estimator's ``sample_time`` carries them into fast periods)."""
        return {"sample_times": self.stamps.copy()}

    @property
    def description(self) -> str:
        """One phrase describing the sampling."""
        text = f"time stamps of their own, median spacing {self.factor} fast periods"
        for name in ("exposure", "latency"):
            if getattr(self, name):
                text += f", {name} {getattr(self, name):g} s"
        return text


def read_slow_log(path, time: str, output: str | None = None, *, sample_time: float,
                  n_samples: int, exposure: float = 0.0, latency: float = 0.0) -> SlowLog:
    """Read a slow log: readings and their time stamps in seconds, on the fast record's clock.

    The fast record's row ``n`` is the instant ``n T``; a reading stamped
    ``t`` seconds lies at ``t / T`` fast sample periods
    (:meth:`gpmultirate.FIRGaussianProcess.fit` with ``sample_times``).

    Parameters
    ----------
    path : str or path-like
        A ``.csv``, ``.npz`` or ``.mat`` file (:func:`read_table`).
    time : str
        The column of the time stamps, in seconds.
    output : str, optional
        The column of the readings (empty or ``NaN`` where one is missing);
        without it only the stamps are read (for a prediction).
    sample_time : float
        ``T``, the fast sample time in seconds.
    n_samples : int
        ``N``, the fast samples of the record: every stamp lies in ``[0, N T)``.
    exposure, latency : float, default=0.0
        The sensor's exposure and latency in seconds: a reading stamped ``t``
        is the mean output over ``[t - L - E, t - L]``.

    Returns
    -------
    SlowLog

    Raises
    ------
    DataFileError
        A malformed file, a missing column, text in a number, a missing
        stamp, stamps that are not strictly increasing (unsorted or
        duplicate) or that lie outside the record; one line naming the file.
    ValueError
        If ``sample_time``, ``n_samples``, ``exposure`` or ``latency`` is invalid.

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.io import DataFileError, read_slow_log
    >>> path = os.path.join(tempfile.mkdtemp(), "camera.csv")
    >>> with open(path, "w") as f:
    ...     _ = f.write("t,y\\n0.0025,1.0\\n0.0061,\\n0.009,3.0\\n")
    >>> log = read_slow_log(path, "t", "y", sample_time=0.001, n_samples=10)
    >>> log.sample_times, log.values
    (array([2.5, 6.1, 9. ]), array([ 1., nan,  3.]))
    >>> try:
    ...     read_slow_log(path, "t", "y", sample_time=0.001, n_samples=8)
    ... except DataFileError as error:
    ...     print(error.problem)
    column 't': stamp 3 (0.009 s) lies outside the record [0, 0.008) s of 8 fast samples
    """
    try:
        sample_time = float(sample_time)
    except (TypeError, ValueError):
        raise ValueError(f"sample_time must be a positive number; got {sample_time!r}") from None
    if not (np.isfinite(sample_time) and sample_time > 0):
        raise ValueError(f"sample_time must be a positive number; got {sample_time!r}")
    n_samples = _count(n_samples, "n_samples", 1)
    for name, value in (("exposure", exposure), ("latency", latency)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) \
                or not np.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be a non-negative number of seconds; got {value!r}")
    names = [time] if output is None else [time, output]
    if output is not None and output == time:
        raise DataFileError(path, f"the time column {_short(time)} is also the output column")
    columns = read_columns(path, names)
    stamps = columns[time]
    missing = np.flatnonzero(np.isnan(stamps))
    if missing.size:
        raise DataFileError(path, f"column {_short(time)}: stamp {missing[0] + 1} is missing "
                                  "(every reading needs its time stamp)")
    step = np.diff(stamps)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        k = bad[0]
        what = "repeats" if step[k] == 0 else "comes before"
        raise DataFileError(path, f"column {_short(time)}: stamp {k + 2} ({stamps[k + 1]:g} s) "
                                  f"{what} stamp {k + 1} ({stamps[k]:g} s); the stamps must be "
                                  "strictly increasing")
    times = in_fast_periods(stamps, sample_time)
    outside = np.flatnonzero((times < 0) | (times >= n_samples))
    if outside.size:
        k = outside[0]
        raise DataFileError(path, f"column {_short(time)}: stamp {k + 1} ({stamps[k]:g} s) lies "
                                  f"outside the record [0, {n_samples * sample_time:g}) s of "
                                  f"{n_samples} fast samples")
    values = None if output is None else columns[output]
    if values is not None and not np.any(np.isfinite(values)):
        raise DataFileError(path, f"column {_short(output)} has no reading (every cell is "
                                  "empty or NaN)")
    for array in (stamps, times) + (() if values is None else (values,)):
        array.setflags(write=False)
    return SlowLog(stamps, times, values, n_samples, sample_time, float(exposure),
                   float(latency))


def _count(value, name: str, low: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer; got {value!r}")
    if value < low:
        raise ValueError(f"{name} must be at least {low}; got {value}")
    return int(value)


# ------------------------------------------------------------------ writing
def _fsync_dir(folder: Path) -> None:
    try:
        handle = os.open(folder, os.O_RDONLY)
    except OSError:  # pragma: no cover - a platform without directory handles
        return
    try:
        os.fsync(handle)
    except OSError:  # pragma: no cover - a file system that cannot sync folders
        pass
    finally:
        os.close(handle)


def _write_new(path: Path, content: bytes) -> None:
    with open(path, "xb") as stream:
        stream.write(content)
        stream.flush()
        os.fsync(stream.fileno())


def _temp_name(path: Path, tag: str) -> str:
    # the prefix keeps the name of the target, shortened to stay within 255 bytes
    return f".{path.name[:96]}.{tag}-"


def write_file(path, content: bytes, *, overwrite: bool = False) -> None:
    """Write ``content`` to ``path`` all at once: the file is complete or absent.

    The bytes go to a temporary file in the same folder, which is flushed
    to disk and then renamed onto ``path`` in one step (``os.replace``), so
    an interruption, a full disk or a size limit leaves the earlier file (or
    none) and no temporary file.

    Parameters
    ----------
    path : str or path-like
        The file; its folder is created if needed.
    content : bytes
    overwrite : bool, default False
        Replace an existing file; otherwise :class:`FileExistsError`.

    Raises
    ------
    OSError
        The file cannot be written; nothing was changed.

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.io import write_file
    >>> path = os.path.join(tempfile.mkdtemp(), "out", "table.csv")
    >>> write_file(path, b"a,b\\n1,2\\n")
    >>> open(path).read()
    'a,b\\n1,2\\n'
    """
    path = Path(os.fspath(path))
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists")
    folder = path.parent
    folder.mkdir(parents=True, exist_ok=True)
    handle, temp = _mkstemp(path)
    try:
        os.chmod(temp, 0o666 & ~_umask())  # as open() would make it, not mkstemp's 0o600
        with os.fdopen(handle, "wb") as stream:
            stream.write(content)
            stream.flush()
            os.fsync(stream.fileno())
        if path.exists() and not overwrite:
            raise FileExistsError(f"{path} appeared while writing")
        os.replace(temp, path)
    except BaseException:
        if os.path.exists(temp):
            os.unlink(temp)
        raise
    _fsync_dir(folder)


def _mkstemp(path: Path):
    import tempfile

    return tempfile.mkstemp(prefix=_temp_name(path, "part"), dir=path.parent)


class _SignalsHeld:
    """Hold back SIGINT and SIGTERM in a block of a few system calls (delivered after it).

    The Python-level handlers are swapped for ones that only take note: blocking the
    signals with a mask would not do, since the kernel may deliver them to another
    thread (a BLAS worker), whose C handler then interrupts the main thread anyway.
    Outside the main thread nothing is held (handlers can only be set there).
    """

    def __enter__(self):
        import signal
        import threading

        self._previous, self._pending = {}, []
        if threading.current_thread() is threading.main_thread():
            for number in (signal.SIGINT, signal.SIGTERM):
                previous = signal.getsignal(number)
                if previous is not None:  # None: a handler not set from Python; keep it
                    self._previous[number] = previous
                    signal.signal(number, self._note)
        return self

    def _note(self, number, frame):
        self._pending.append((number, frame))

    def __exit__(self, *exc):
        import signal

        for number, previous in self._previous.items():
            signal.signal(number, previous)
        for number, frame in self._pending[:1]:  # now act on it as it would have
            previous = self._previous[number]
            if callable(previous):
                previous(number, frame)  # e.g. default_int_handler: KeyboardInterrupt
            elif previous == signal.SIG_DFL:
                os.kill(os.getpid(), number)
        return False


def write_folder(folder, files: dict, *, overwrite: bool = False, replaceable=()) -> None:
    """Write a folder of files all at once: it holds all of them or none.

    The files are written into a temporary folder beside ``folder``,
    flushed to disk, and the temporary folder is renamed to ``folder`` in
    one step.  An existing ``folder`` is replaced as a whole, so it may hold
    only files of a result (the names in ``files`` and ``replaceable``):
    with ``overwrite`` it is renamed aside, the new folder renamed in, and
    the old one removed.  Interrupts (SIGINT, SIGTERM) are held back during
    the two renames and the removal, so Ctrl-C never separates them.  Only a crash of the
    machine or ``SIGKILL`` between them leaves no ``folder``; then the old
    results are in ``.NAME.old-*`` and the new, complete ones in
    ``.NAME.part-*`` beside it, either of which can be renamed to ``NAME``.

    Parameters
    ----------
    folder : str or path-like
        The folder; its parent is created if needed.
    files : dict of str to bytes
        File names (without folders) and their content.
    overwrite : bool, default False
        Replace a folder that holds any of the result files; otherwise
        :class:`FileExistsError`.  An empty folder is always replaced.
    replaceable : sequence of str
        Further names an existing folder may hold (results of an earlier run
        that this one does not write).

    Raises
    ------
    FileExistsError
        ``folder`` holds results and ``overwrite`` is false, or holds other
        files, or is not a folder.
    OSError
        The files cannot be written; nothing was changed and no temporary
        folder is left.

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.io import write_folder
    >>> folder = os.path.join(tempfile.mkdtemp(), "results")
    >>> write_folder(folder, {"a.txt": b"1", "b.txt": b"2"})
    >>> sorted(os.listdir(folder))
    ['a.txt', 'b.txt']
    >>> write_folder(folder, {"a.txt": b"3"}, overwrite=True, replaceable=["b.txt"])
    >>> sorted(os.listdir(folder))
    ['a.txt']
    """
    import shutil
    import tempfile

    folder = Path(os.fspath(folder))
    for name in files:
        if not name or os.sep in name or name in (".", ".."):
            raise ValueError(f"files must be plain file names; got {name!r}")
    check_folder(folder, [*files, *replaceable], overwrite=overwrite)
    parent = folder.parent
    parent.mkdir(parents=True, exist_ok=True)
    temp = Path(tempfile.mkdtemp(prefix=_temp_name(folder, "part"), dir=parent))
    aside = None
    try:
        os.chmod(temp, 0o777 & ~_umask())  # as os.mkdir would make it, not mkdtemp's 0o700
        for name, content in files.items():
            _write_new(temp / name, content)
        _fsync_dir(temp)
        check_folder(folder, [*files, *replaceable], overwrite=overwrite)
        with _SignalsHeld():  # the swap and the removal of the earlier folder
            try:
                os.rename(temp, folder)  # onto a missing or an empty folder
            except OSError:
                if not folder.is_dir():
                    raise
                aside = Path(tempfile.mkdtemp(prefix=_temp_name(folder, "old"), dir=parent))
                os.rename(folder, aside)
                try:
                    os.rename(temp, folder)
                except BaseException:
                    os.rename(aside, folder)
                    aside = None
                    raise
            if aside is not None:
                shutil.rmtree(aside, ignore_errors=True)
                aside = None
        _fsync_dir(parent)
    except BaseException:
        with _SignalsHeld():
            shutil.rmtree(temp, ignore_errors=True)
            # the earlier results go only once the new ones are in place; if even moving
            # them back failed, they stay in .NAME.old-* (see above)
            if aside is not None and folder.is_dir():
                shutil.rmtree(aside, ignore_errors=True)
        raise


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def check_folder(folder, names, *, overwrite: bool = False) -> None:
    """Check that :func:`write_folder` may replace ``folder`` with result files ``names``.

    Parameters
    ----------
    folder : str or path-like
    names : sequence of str
        The files an existing ``folder`` may hold.
    overwrite : bool, default False
        Whether a folder holding some of them may be replaced.

    Raises
    ------
    FileExistsError
        ``folder`` is not a directory, holds a file not in ``names``, or
        holds any of them and ``overwrite`` is false.
    OSError
        ``folder`` cannot be examined (e.g. its name is too long).

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.io import check_folder
    >>> folder = tempfile.mkdtemp()
    >>> check_folder(folder, ["a.txt"])  # empty: fine
    >>> open(os.path.join(folder, "notes.txt"), "w").close()
    >>> try:
    ...     check_folder(folder, ["a.txt"], overwrite=True)
    ... except FileExistsError as error:
    ...     print(str(error).endswith("may hold only results"))
    True
    """
    folder = Path(os.fspath(folder))
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise FileExistsError(f"{folder} exists and is not a directory")
    if not folder.exists():
        return
    entries = sorted(os.listdir(folder))
    foreign = [name for name in entries if name not in names]
    if foreign:
        raise FileExistsError(f"{folder / foreign[0]} is not a result file; the folder is "
                              "replaced as a whole, so it may hold only results")
    if entries and not overwrite:
        raise FileExistsError(f"{folder / entries[0]} exists")


def model_slow_samples(model) -> SlowSamples:
    """The slow samples a fitted model saw, read from its sample instants.

    Parameters
    ----------
    model : FIRGaussianProcess
        A fitted estimator of one record.

    Returns
    -------
    SlowSamples or SlowLog
        As :func:`gpmultirate.io.read_slow_samples` reads them from a column
        holding the model's ``y_slow_`` at its sample instants and ``NaN``
        elsewhere; for readings at their own instants (``sample_times``), a
        :class:`SlowLog` of them.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.io import model_slow_samples
    >>> u = np.random.default_rng(0).standard_normal(30)
    >>> model = gm.FIRGaussianProcess(order=5, factor=3, offset=1).fit(u, u[1::3])
    >>> model_slow_samples(model).description
    'one sample in 3, from row 1'
    """
    check_is_fitted(model, "observation_")
    observation = model.observation_
    if getattr(observation, "sample_times", None) is not None:  # readings at their own instants
        period = getattr(model, "sample_time", None) or 1.0
        times = np.asarray(observation.sample_times, dtype=float)
        return SlowLog(times * period, times, np.asarray(model.y_slow_, dtype=float),
                       int(observation.n_samples), period, observation.exposure * period,
                       observation.latency * period)
    column = np.full(int(observation.n_samples), np.nan)
    column[np.asarray(observation.sample_indices)] = np.asarray(model.y_slow_, dtype=float)
    return read_slow_samples(column)
