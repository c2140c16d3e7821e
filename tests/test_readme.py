"""The README's Python examples run exactly as printed."""

from __future__ import annotations

import contextlib
import io
import pathlib
import re

import matplotlib
import pytest

matplotlib.use("Agg")

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.DOTALL)


def test_the_readme_has_a_python_example():
    assert BLOCKS


@pytest.mark.parametrize("code", BLOCKS, ids=[f"block {i}" for i in range(len(BLOCKS))])
def test_readme_python_block_runs_as_printed(code, tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, str(README), "exec"), {"__name__": "__readme__"})
    plt.close("all")
    if "validation GoF" in code:
        gof = float(re.search(r"validation GoF ([-\d.]+) %", printed.getvalue()).group(1))
        assert gof > 99.0


def test_ci_runs_the_readme_test_command():
    """The README's install-and-test command is the one continuous integration runs."""
    command = re.search(r'pip install "(\.\[[^\]]*\])" && (python -m pytest[^\n]*)\n',
                        README.read_text(encoding="utf-8"))
    assert command, "the README gives no install-and-test command"
    ci = (README.parent / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert f'pip install "{command.group(1)}"' in ci
    assert command.group(2) in ci
