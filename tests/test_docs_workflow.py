"""The Python blocks of the workflow page run, in order, as printed."""

from __future__ import annotations

import pathlib
import re

import matplotlib
import pytest

matplotlib.use("Agg")

PAGE = pathlib.Path(__file__).resolve().parents[1] / "docs" / "workflow.rst"


def python_blocks(text: str) -> list[str]:
    """The bodies of the ``.. code-block:: python`` directives, dedented."""
    blocks = []
    for match in re.finditer(r"\.\. code-block:: python\n\n((?:    .*\n|\n)+)", text):
        lines = [line[4:] for line in match.group(1).splitlines()]
        blocks.append("\n".join(lines).strip() + "\n")
    return blocks


@pytest.mark.slow
def test_workflow_page_runs_as_printed(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    blocks = python_blocks(PAGE.read_text(encoding="utf-8"))
    assert len(blocks) >= 4
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__workflow__"}
    for block in blocks:
        exec(compile(block, str(PAGE), "exec"), namespace)
    plt.close("all")
    # the search finds the arm's two resonances, and the reduced model is small
    assert len(namespace["model"].resonances_) >= 1
    assert namespace["reduced"].A.shape[0] <= 12
