"""Tests of the ``gpmultirate`` command on tiny configurations."""

import csv
import importlib.metadata
import runpy
import sys

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from gpmultirate.cli import build_parser, main  # noqa: E402
from gpmultirate.study import StudyResult  # noqa: E402

PNG = b"\x89PNG\r\n\x1a\n"
TINY = ["--runs", "1", "--n-samples", "60", "--orders", "10", "20", "--n-jobs", "1"]
FIGURES = ("gof_vs_order.png", "bode.png", "impulse_response.png", "intersample.png")
TABLES = ("study.csv", "study_runs.csv", "study.md", "study.rst", "study.json")
DEMO_OPTIONS = ("--runs", "--orders", "--methods", "--n-jobs", "--seed", "--output",
                "--no-figures", "--quiet", "--n-samples", "--factor", "--snr", "--example-order")


@pytest.mark.slow
def test_demo_writes_tables_and_figures(tmp_path, capsys):
    out = tmp_path / "results"
    argv = ["demo", *TINY, "--methods", "LS", "DC", "--output", str(out), "--quiet",
            "--example-order", "30"]
    assert main(argv) == 0
    assert plt.get_fignums() == []  # figures are not left open in pyplot
    captured = capsys.readouterr()
    assert captured.err == ""  # --quiet
    for name in TABLES:
        assert (out / name).stat().st_size > 0
    for name in FIGURES:
        assert (out / name).read_bytes()[:8] == PNG

    result = StudyResult.from_json(out / "study.json")
    assert result.n_runs == 1 and result.methods == ("LS", "DC")
    np.testing.assert_array_equal(result.orders, [10, 20])
    assert np.isnan(result.gof["LS"][0, 1])  # P = 20 = M
    table = result.to_markdown()
    assert table in captured.out  # the table printed is the one of the saved study
    assert table in (out / "study.md").read_text(encoding="utf-8")
    with open(out / "study.csv", newline="") as stream:
        rows = {(r["method"], int(r["order"])): r for r in csv.DictReader(stream)}
    assert float(rows[("DC", 20)]["mean"]) == pytest.approx(result.gof["DC"][0, 1])
    assert rows[("LS", 20)]["identifiable"] == "False"


def test_demo_progress_and_no_figures(tmp_path, capsys):
    assert main(["demo", *TINY, "--methods", "LS", "--output", str(tmp_path),
                 "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "run 1/1 done" in err and "wrote" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(TABLES)


def test_example1_writes_the_figure(tmp_path):
    assert main(["example1", "--output", str(tmp_path), "--n-samples", "120", "--quiet"]) == 0
    assert (tmp_path / "example1.png").read_bytes()[:8] == PNG


def test_help_documents_every_option(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for option in DEMO_OPTIONS:
        assert option in text
    # and everything any parser declares, found from the parsers themselves
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    assert set(commands) == {"demo", "example1"}
    for name, sub in commands.items():
        assert f"gpmultirate {name}" in text
        for action in sub._actions:
            for option in action.option_strings:
                assert option in text, option


@pytest.mark.parametrize("argv", [
    [],
    ["unknown"],
    ["demo", "--bogus"],
    ["demo", "--runs", "0"],
    ["demo", "--runs", "two"],
    ["demo", "--orders", "0"],
    ["demo", "--orders", "700"],  # above the default N = 600
    ["demo", "--orders", "100", "100"],
    ["demo", "--methods", "GP"],
    ["demo", "--n-jobs", "0"],
    ["demo", "--seed", "-1"],
    ["demo", "--factor", "0"],
    ["demo", "--snr", "60", "40"],
    ["demo", "--snr", "nan", "40"],
    ["demo", "--n-samples", "60", "--example-order", "61"],
    ["example1", "--factor", "1"],
    ["example1", "--n-samples", "6", "--factor", "4"],
])
def test_bad_arguments_exit_with_status_2(argv, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--output", str(tmp_path)] if argv[:1] in (["demo"], ["example1"])
             else argv)
    assert exit_info.value.code == 2
    assert "error" in capsys.readouterr().err


def test_output_must_be_a_directory(tmp_path, capsys):
    target = tmp_path / "file.txt"
    target.write_text("x")
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", *TINY, "--output", str(target)])
    assert exit_info.value.code == 2


def test_python_dash_m_runs_the_command(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["gpmultirate", "--version"])
    with pytest.raises(SystemExit) as exit_info:
        runpy.run_module("gpmultirate", run_name="__main__")
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.startswith("gpmultirate ")


def test_console_script_is_declared():
    entry_points = importlib.metadata.entry_points(group="console_scripts")
    assert any(ep.name == "gpmultirate" and ep.value == "gpmultirate.cli:main"
               for ep in entry_points)
