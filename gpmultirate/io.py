"""Read named columns of measured data from CSV, NumPy ``.npz`` and MATLAB ``.mat`` files.

The rows of a file are fast samples.  A column is named by

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
import os
import zipfile
from pathlib import Path

import numpy as np

from gpmultirate.exceptions import DataFileError

__all__ = ["DataFileError", "DataTable", "read_columns", "read_table"]

#: The largest number of columns a CSV file may have.
MAX_COLUMNS = 100_000
_SUFFIXES = (".csv", ".npz", ".mat")
_MAT_HEADER = 128


def _short(text: str, limit: int = 40) -> str:
    text = repr(text)
    return text if len(text) <= limit else text[: limit - 4] + "...'"


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
                known = ", ".join(_short(n, 24) for n in self.names[:12])
                more = f" and {len(self.names) - 12} more" if len(self.names) > 12 else ""
                raise self._error(f"no column {_short(spec)} (columns: {known}{more})")
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
    try:
        reader = csv.reader(lines, strict=True)
        header = next(reader)
        rows = []
        for row in reader:
            if row:  # a blank line is skipped; a row of empty cells is a row of NaN
                rows.append((reader.line_num, row))
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
            raise DataFileError(path, f"line {line} has {len(row)} fields; the header has "
                                      f"{len(names)}")

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
    if not path.exists():
        raise DataFileError(path, "does not exist")
    if not path.is_file():
        raise DataFileError(path, "is not a file")
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
