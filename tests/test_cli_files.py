"""Malformed data files given to ``gpmultirate fit``: one clear line, status 2, no output.

Several hundred hostile files are generated: broken CSV (empty, header only,
ragged rows, text in numbers, infinities, missing inputs, duplicate or
missing columns, wrong encodings, other separators), ``.npz`` archives with
objects, wrong dtypes or scalars, and MATLAB files of version 7.3, without
the variable, or holding structs, cells, text or sparse matrices.  Each must
end the command with exit status 2 and a single line on stderr that names
the file and the problem, with no traceback and no file written.
"""

import io
import os
import pickle
import subprocess
import sys
import zipfile

import numpy as np
import pytest
import scipy.io
import scipy.sparse

from gpmultirate.cli import main
from gpmultirate.io import DataFileError, read_columns, read_table

N = 12
U = np.linspace(-1.0, 1.0, N)
Y = np.where(np.arange(N) % 3 == 0, np.cos(np.arange(N)), np.nan)


def _cell(value) -> str:
    return "" if np.isnan(value) else repr(float(value))


def _csv(u=U, y=Y, header="u,y") -> str:
    return header + "\n" + "".join(f"{_cell(a)},{_cell(b)}\n" for a, b in zip(u, y))


def _rows(text_rows, header="u,y") -> str:
    return header + "\n" + "".join(row + "\n" for row in text_rows)


def _good_rows():
    return [f"{_cell(a)},{_cell(b)}" for a, b in zip(U, Y)]


# ------------------------------------------------------------------ the cases
# each case: (id, suffix, content as str or bytes or a writer function, expected words)
CASES = []


def case(name, suffix, content, expected, columns=("u", "y")):
    CASES.append(pytest.param(suffix, content, expected, columns, id=name))


# CSV: empty and header only
for k, text in enumerate(["", "\n", "\n\n\n", "   \n  \n", "\r\n"]):
    case(f"csv-empty-{k}", ".csv", text, "is empty")
for k, header in enumerate(["u,y", "u,y\n", "u,y\n\n", "u,y,z\n", " u , y \n\n\n"]):
    case(f"csv-header-only-{k}", ".csv", header, "no data rows")

# ragged rows: one field too many or too few, at every row
for row in range(N):
    for kind, edit in (("long", lambda r: r + ",1.0"), ("short", lambda r: r.split(",")[0])):
        rows = _good_rows()
        rows[row] = edit(rows[row])
        case(f"csv-ragged-{kind}-{row}", ".csv", _rows(rows), "fields")

# text where a number belongs, in the input or in the output column
TOKENS = ["abc", "1.2.3", "--1", "0x10", "1e", "1,5", "one", "NaN!", "1 2", "$3", "'7'",
          "TRUE", "1e+", "∞", "nan nan"]
for k, token in enumerate(TOKENS):
    for column in ("u", "y"):
        # a row where y is measured, and one where it is not (text is refused there too)
        for row in ((3 * k) % N, (3 * k + 1) % N):
            u = [_cell(a) for a in U]
            y = [_cell(b) for b in Y]
            (u if column == "u" else y)[row] = f'"{token}"' if "," in token else token
            case(f"csv-text-{column}-{k}-{row}", ".csv",
                 _rows([f"{a},{b}" for a, b in zip(u, y)]), "is not a number")

# infinities in either column
for k, token in enumerate(["inf", "-inf", "Infinity", "-Infinity", "1e999", "INF"]):
    for column in ("u", "y"):
        for row in (0, 6, 9):
            u = [_cell(a) for a in U]
            y = [_cell(b) for b in Y]
            (u if column == "u" else y)[row] = token
            case(f"csv-inf-{column}-{k}-{row}", ".csv",
                 _rows([f"{a},{b}" for a, b in zip(u, y)]), "infinite")

# missing inputs: empty cells or NaN in the input column
for row in range(N):
    for k, token in enumerate(["", "nan", "NaN"]):
        u = [_cell(a) for a in U]
        u[row] = token
        case(f"csv-nan-input-{row}-{k}", ".csv",
             _rows([f"{a},{_cell(b)}" for a, b in zip(u, Y)]), "missing value")

# an output column with no measured value
for k, token in enumerate(["", "nan", "NaN", " ", "nan"]):
    case(f"csv-no-output-{k}", ".csv",
         _rows([f"{_cell(a)},{token}" for a in U]), "no measured")

# duplicate or empty names in the header
for k, header in enumerate(["u,u", "u,y,u", "y,u,y", " u,u ", "a,a,u,y", "u,y,z,z",
                            "u,,y", ",u,y", "u,y,", "x,u,x,y"]):
    n_fields = header.count(",") + 1
    rows = [",".join(["1.0"] * n_fields) for _ in range(N)]
    case(f"csv-bad-header-{k}", ".csv", _rows(rows, header),
         "twice" if len(set(h.strip() for h in header.split(","))) < n_fields
         and "" not in [h.strip() for h in header.split(",")] else "empty name")

# columns that do not exist
for k, (u_name, y_name) in enumerate([("v", "y"), ("u", "Y"), ("U", "y"), ("u", "y_slow"),
                                      ("u:0", "y"), ("u", "y:1"), ("input", "output"),
                                      ("u ", "yy"), ("", "y"), ("u", "z")]):
    case(f"csv-missing-column-{k}", ".csv", _csv(), "column", columns=(u_name, y_name))

# encodings that are not UTF-8, and byte-order marks of other encodings
for k, (encoding, extra) in enumerate([("latin-1", "é"), ("cp1252", "€"), ("utf-16", ""),
                                       ("utf-16-le", ""), ("utf-16-be", ""),
                                       ("utf-32", ""), ("shift_jis", "ｱ"), ("cp437", "ñ")]):
    text = _csv(header=f"u{extra},y")
    case(f"csv-encoding-{encoding}", ".csv", text.encode(encoding),
         "NUL" if encoding in ("utf-16-le", "utf-16-be") else "not UTF-8")
case("csv-binary", ".csv", bytes(range(256)) * 4, "not UTF-8")
case("csv-nul", ".csv", b"u,y\n1,\x002\n", "NUL")
case("csv-utf8-bom-but-text", ".csv", ("\ufeff" + _csv()).replace("0.0", "zero").encode(),
     "is not a number")

# other separators
for k, sep in enumerate([";", "\t", ";", "\t"]):
    text = _csv().replace(",", sep)
    if k >= 2:
        text = text.replace(".", ",")  # decimal commas, as often with ';'
    case(f"csv-separator-{k}", ".csv", text, "separated by")
case("csv-separator-space", ".csv", _csv().replace(",", " "), "column")

# quoting errors
for k, text in enumerate(['u,y\n"1,2\n', 'u,y\n1,"2"x\n', '"u,y\n1,2\n']):
    case(f"csv-quote-{k}", ".csv", text, "")


# NPZ archives
def npz(**arrays):
    def write(path):
        np.savez(path, **arrays)
    return write


class _Trap:
    """Unpickling this would create a file: it must never happen."""

    def __reduce__(self):
        return (open, (os.environ.get("GPMULTIRATE_TRAP", os.devnull), "w"))


for k, obj in enumerate([["a", "b"], [{"x": 1}], [1, [2, 3]], [None] * N, [_Trap()]]):
    array = np.empty(len(obj), dtype=object)
    array[:] = obj
    for column in ("u", "y"):
        arrays = {"u": U, "y": Y, column: array}
        case(f"npz-object-{column}-{k}", ".npz", npz(**arrays), "not unpickled")

for k, bad in enumerate([np.array(["1", "2"] * 6), np.array([b"1"] * N),
                         U + 1j, np.arange(N).astype("datetime64[s]"),
                         np.zeros(N, dtype=[("a", float), ("b", float)]),
                         np.zeros(N, dtype="V8"), np.arange(N).astype("timedelta64[s]")]):
    for column in ("u", "y"):
        arrays = {"u": U, "y": Y, column: bad}
        expected = ("struct" if bad.dtype.names else "complex" if bad.dtype.kind == "c"
                    else "not numeric")
        case(f"npz-dtype-{column}-{k}", ".npz", npz(**arrays), expected)

for k, scalar in enumerate([np.float64(1.0), np.array(2.0), np.array(3), np.array(True)]):
    for column in ("u", "y"):
        arrays = {"u": U, "y": Y, column: np.asarray(scalar)}
        case(f"npz-0d-{column}-{k}", ".npz", npz(**arrays), "scalar")

for column in ("u", "y"):
    case(f"npz-3d-{column}", ".npz", npz(**{"u": U, "y": Y, column: np.zeros((N, 2, 2))}),
         "dimensions")
    case(f"npz-empty-{column}", ".npz", npz(**{"u": U, "y": Y, column: np.zeros(0)}),
         "no rows")
    case(f"npz-matrix-{column}", ".npz", npz(**{"u": U, "y": Y, column: np.zeros((N, 3))}),
         ":0")
    case(f"npz-short-{column}", ".npz", npz(**{"u": U, "y": Y, column: np.zeros(N - 1)}),
         "differ in length")
    case(f"npz-missing-{column}", ".npz", npz(**{"u": U, "y": Y, "w": U}), "no column",
         columns=("w", "v") if column == "u" else ("u", "v"))
for k, spec in enumerate(["M:2", "M:-1", "M:99", "u:0"]):
    case(f"npz-index-{k}", ".npz", npz(M=np.zeros((N, 2)), u=U, y=Y),
         "range" if spec.startswith("M") else "not a 2-D array", columns=(spec, "y"))
case("npz-nan-input", ".npz", npz(u=np.where(np.arange(N) == 4, np.nan, U), y=Y),
     "missing value")
case("npz-no-output", ".npz", npz(u=U, y=np.full(N, np.nan)), "no measured")
case("npz-inf-output", ".npz", npz(u=U, y=np.where(np.arange(N) == 3, np.inf, Y)),
     "infinite")
case("npz-no-arrays", ".npz", npz(), "no arrays")
for k, content in enumerate([b"", b"garbage", b"PK\x03\x04" + b"\x00" * 40,
                             b"\x93NUMPY" + b"\x00" * 20]):
    case(f"npz-corrupt-{k}", ".npz", content, ".npz")


def _truncated_npz(path):
    buffer = io.BytesIO()
    np.savez(buffer, u=U, y=Y)
    path.write_bytes(buffer.getvalue()[: len(buffer.getvalue()) // 2])


case("npz-truncated", ".npz", _truncated_npz, ".npz")


def _npz_bad_member(path):
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("u.npy", b"not an array")
        archive.writestr("y.npy", b"\x93NUMPY\x01\x00garbage")


case("npz-bad-member", ".npz", _npz_bad_member, "")


def _npz_pickle_member(path):
    # a raw pickle in an archive member, not even a .npy header
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("u.npy", pickle.dumps(_Trap()))
        archive.writestr("y.npy", pickle.dumps(_Trap()))


case("npz-raw-pickle", ".npz", _npz_pickle_member, "")


# MATLAB files
def mat(**variables):
    def write(path):
        scipy.io.savemat(path, variables)
    return write


def mat73(text=b"MATLAB 7.3 MAT-file, Platform: GLNXA64", endian=b"IM", tail=b""):
    def write(path):
        header = text.ljust(116, b" ")[:116] + b"\x00" * 8
        version = (0x0200).to_bytes(2, "little" if endian == b"IM" else "big")
        path.write_bytes(header + version + endian + tail)
    return write


for k, (text, endian, tail) in enumerate([
        (b"MATLAB 7.3 MAT-file, Platform: GLNXA64", b"IM", b""),
        (b"MATLAB 7.3 MAT-file, Platform: MACI64", b"MI", b""),
        (b"MATLAB 7.3 MAT-file", b"IM", b"\x89HDF\r\n\x1a\n" + b"\x00" * 64),
        (b"", b"IM", b"\x00" * 512)]):
    case(f"mat-v73-{k}", ".mat", mat73(text, endian, tail), "v7.3")

for k, names in enumerate([{"a": U, "y": Y}, {"u": U, "b": Y}, {"x": U}]):
    case(f"mat-missing-variable-{k}", ".mat", mat(**names), "no column")
for column in ("u", "y"):
    case(f"mat-struct-{column}", ".mat", mat(**{"u": U, "y": Y, column: {"a": U, "b": Y}}),
         "struct")
    cell = np.empty(2, dtype=object)
    cell[:] = [U, Y]
    case(f"mat-cell-{column}", ".mat", mat(**{"u": U, "y": Y, column: cell}), "cell")
    case(f"mat-char-{column}", ".mat", mat(**{"u": U, "y": Y, column: "hello"}), "text")
    case(f"mat-sparse-{column}", ".mat",
         mat(**{"u": U, "y": Y, column: scipy.sparse.csc_matrix(np.eye(N, 1))}), "sparse")
    case(f"mat-complex-{column}", ".mat", mat(**{"u": U, "y": Y, column: U + 1j}), "complex")
    case(f"mat-matrix-{column}", ".mat", mat(**{"u": U, "y": Y, column: np.ones((N, 2))}),
         ":0")
    case(f"mat-3d-{column}", ".mat", mat(**{"u": U, "y": Y, column: np.ones((N, 2, 2))}),
         "dimensions")
case("mat-nan-input", ".mat", mat(u=np.where(np.arange(N) == 2, np.nan, U), y=Y),
     "missing value")
case("mat-no-output", ".mat", mat(u=U, y=np.full(N, np.nan)), "no measured")
case("mat-no-variables", ".mat", mat(), "no variables")
for k, content in enumerate([b"", b"garbage", b"MATLAB 5.0 MAT-file" + b"\x00" * 30,
                             b"\x00" * 200, bytes(range(256)) * 2]):
    case(f"mat-corrupt-{k}", ".mat", content, "")


def _truncated_mat(path):
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, {"u": U, "y": Y})
    path.write_bytes(buffer.getvalue()[:150])


case("mat-truncated", ".mat", _truncated_mat, "")

# files that are not data files
for k, suffix in enumerate([".txt", ".xlsx", "", ".dat", ".h5"]):
    case(f"suffix-{k}", suffix, _csv(), "suffix")


# ------------------------------------------------------------------- the tests
def _write(path, content):
    if callable(content):
        content(path)
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_bytes(content.encode("utf-8"))


def test_there_are_hundreds_of_cases():
    assert len(CASES) >= 300


@pytest.mark.parametrize("suffix, content, expected, columns", CASES)
def test_hostile_file_gives_one_line_and_status_2(suffix, content, expected, columns, tmp_path,
                                                  capsys, monkeypatch):
    trap = tmp_path / "unpickled"
    monkeypatch.setenv("GPMULTIRATE_TRAP", str(trap))
    path = tmp_path / f"data{suffix}"
    _write(path, content)
    before = path.read_bytes()
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_info:
        main(["fit", str(path), "--input", columns[0], "--output", columns[1],
              "--out", str(out), "--quiet"])
    assert exit_info.value.code == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    line = lines[0]
    assert line.startswith("gpmultirate fit: error: ")
    assert str(path) in line
    assert expected in line
    assert "Traceback" not in captured.err
    assert not out.exists()  # no output, not even the folder
    assert not trap.exists()  # nothing was unpickled
    assert path.read_bytes() == before  # the data file is left alone
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary files


def test_one_million_columns_are_refused(tmp_path, capsys):
    path = tmp_path / "wide.csv"
    n = 10**6
    path.write_text(",".join(f"c{k}" for k in range(n)) + "\n" + ",".join(["1"] * n) + "\n")
    with pytest.raises(SystemExit) as exit_info:
        main(["fit", str(path), "--input", "c0", "--output", "c1", "--out",
              str(tmp_path / "out")])
    assert exit_info.value.code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert str(path) in line and "1000000 columns" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.parametrize("name, content, expected", [
    ("empty.csv", "", "is empty"),
    ("text.csv", "u,y\n1,x\n", "is not a number"),
    ("v73.mat", None, "v7.3"),
])
def test_console_command_exit_status_and_stderr(name, content, expected, tmp_path):
    path = tmp_path / name
    if content is None:
        mat73()(path)
    else:
        path.write_text(content)
    result = subprocess.run(
        [sys.executable, "-m", "gpmultirate", "fit", str(path), "--input", "u", "--output",
         "y", "--out", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=120,
    )
    assert result.returncode == 2
    assert result.stdout == ""
    (line,) = result.stderr.splitlines()
    assert str(path) in line and expected in line
    assert not (tmp_path / "out").exists()


# -------------------------------------------------------- the readers directly
def test_readers_give_the_same_columns_from_every_format(tmp_path):
    """The same numbers written as CSV, .npz and .mat read back identically."""
    rng = np.random.default_rng(0)
    u = rng.standard_normal((N, 2))
    y = np.where(np.arange(N) % 2 == 0, rng.standard_normal(N), np.nan)
    csv_path = tmp_path / "d.csv"
    csv_path.write_text("a,b,y\n" + "".join(
        f"{float(a)!r},{float(b)!r},{'' if np.isnan(c) else repr(float(c))}\n"
        for a, b, c in zip(*u.T, y)),
        encoding="utf-8-sig")  # with a byte-order mark
    np.savez(tmp_path / "d.npz", U=u, y=y)
    scipy.io.savemat(tmp_path / "d.mat", {"U": u, "y": y})
    from_csv = read_columns(csv_path, ["a", "b", "y"])
    for path in (tmp_path / "d.npz", tmp_path / "d.mat"):
        other = read_columns(path, ["U:0", "U:1", "y"])
        np.testing.assert_array_equal(other["U:0"], from_csv["a"])
        np.testing.assert_array_equal(other["U:1"], from_csv["b"])
        np.testing.assert_array_equal(other["y"], from_csv["y"])
    np.testing.assert_array_equal(from_csv["a"], u[:, 0])
    np.testing.assert_array_equal(np.isnan(from_csv["y"]), np.isnan(y))


def test_read_column_returns_a_new_array(tmp_path):
    np.savez(tmp_path / "d.npz", u=U)
    table = read_table(tmp_path / "d.npz")
    first = table.column("u")
    first[:] = 0.0
    np.testing.assert_array_equal(table.column("u"), U)


def test_data_file_error_is_a_value_error_naming_the_file(tmp_path):
    path = tmp_path / "none.csv"
    with pytest.raises(ValueError, match="does not exist") as info:
        read_table(path)
    assert isinstance(info.value, DataFileError)
    assert str(info.value).startswith(str(path))
