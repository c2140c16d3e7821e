"""CSV headers: units in the names, near matches in the message, comment lines before the header."""

import pytest

from gpmultirate.io import DataFileError, read_table


def _table(tmp_path, text):
    path = tmp_path / "data.csv"
    path.write_text(text, encoding="utf-8")
    return read_table(path)


@pytest.mark.parametrize("header", ["t [s],u [V],y [mm]", "t (s),u (V),y (mm)",
                                    "t / s,u / V,y / mm", "t,u {V},y"])
def test_a_name_with_its_unit_is_found_by_the_bare_name(tmp_path, header):
    table = _table(tmp_path, f"{header}\n0,1,2\n1,3,\n")
    assert table.column("u").tolist() == [1.0, 3.0]
    assert table.column("y")[0] == 2.0
    assert table.column(header.split(",")[1]).tolist() == [1.0, 3.0]  # the full name too


def test_two_columns_with_the_same_bare_name_are_ambiguous(tmp_path):
    table = _table(tmp_path, "u [V],u [A]\n1,2\n")
    with pytest.raises(DataFileError, match=r"'u' is ambiguous: 'u \[V\]', 'u \[A\]'"):
        table.column("u")


def test_an_unknown_column_names_the_near_matches(tmp_path):
    table = _table(tmp_path, "time,input,output\n0,1,2\n")
    with pytest.raises(DataFileError, match=r"no column 'inpt'; did you mean 'input'\?"):
        table.column("inpt")
    with pytest.raises(DataFileError) as info:
        table.column("zzz")
    assert "did you mean" not in str(info.value) and "columns: 'time'" in str(info.value)
    table = _table(tmp_path, "t,u1 [V],u2 [V]\n0,1,2\n")
    with pytest.raises(DataFileError, match=r"did you mean 'u1 \[V\]' or 'u2 \[V\]'"):
        table.column("u")


def test_comment_lines_before_the_header_are_skipped_and_lines_counted_in_the_file(tmp_path):
    table = _table(tmp_path, "# camera log\n# T = 0.01 s\nt,u\n0,1\n1,2\n# end\n")
    assert table.names == ("t", "u") and table.column("u").tolist() == [1.0, 2.0]
    with pytest.raises(DataFileError, match=r"line 5 has 3 fields; the header \(line 3\) has 2$"):
        _table(tmp_path, "# camera log\n\nt,u\n0,1\n1,2,3\n")


def test_a_title_line_without_a_comment_mark_is_named_as_the_header(tmp_path):
    with pytest.raises(DataFileError, match=r"line 2 has 3 fields; the header \(line 1\) has 1 "
                                            r"\(if line 1 is not the header, mark it as a "
                                            r"comment with '#'\)"):
        _table(tmp_path, "camera log\nt,u,y\n0,1,2\n")


def test_a_file_of_comments_only_is_refused(tmp_path):
    with pytest.raises(DataFileError, match="only comment lines"):
        _table(tmp_path, "# nothing\n# here\n")
