"""Progress of ``gpmultirate fit`` on stderr, and the library pieces the command calls."""

import io
import logging

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from gpmultirate.arguments import int_at_least, order_or_auto  # noqa: E402
from gpmultirate.cli import main  # noqa: E402
from gpmultirate.progress import FIT_LOGGER, show_progress  # noqa: E402
from gpmultirate.report import FIT_KERNELS, kernel_option  # noqa: E402
from gpmultirate.study import run_paper_study  # noqa: E402
from gpmultirate.study.journal import (  # noqa: E402
    interrupted_message,
    journal_progress,
    prepare_journal,
)


def _long_record(path, n=2400, factor=3):
    """A record longer than the short-record limit (2048): the default order is read from it."""
    rng = np.random.default_rng(0)
    u = rng.standard_normal(n)
    g = 0.8 ** np.arange(30) * np.cos(0.9 * np.arange(30))
    y = np.convolve(u, g)[:n] + 0.01 * rng.standard_normal(n)
    rows = ["u,y"] + [f"{a:.17g},{b:.17g}" if k % factor == 0 else f"{a:.17g},"
                      for k, (a, b) in enumerate(zip(u, y))]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.mark.slow
def test_fit_shows_progress_with_the_time_left_on_stderr(tmp_path, capsys):
    data = _long_record(tmp_path / "data.csv")
    assert main(["fit", str(data), "--input", "u", "--output", "y",
                 "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err.splitlines()
    progress = [line for line in err if line.startswith("gpmultirate fit: [")]
    # the pilot fit at order 512 and the refit at the order read from the prior's decay
    assert any("default order: fitted order 512 in" in line for line in progress)
    assert any("s left)" in line for line in progress)
    elapsed = [float(line.split("[", 1)[1].split(" s]", 1)[0]) for line in progress]
    assert elapsed == sorted(elapsed) and elapsed[0] >= 0.0
    assert logging.getLogger(FIT_LOGGER).handlers == []  # detached after the fit


@pytest.mark.slow
def test_fit_quiet_shows_nothing(tmp_path, capsys):
    data = _long_record(tmp_path / "data.csv")
    assert main(["fit", str(data), "--input", "u", "--output", "y", "--quiet",
                 "--out", str(tmp_path / "out")]) == 0
    assert capsys.readouterr().err == ""


def test_show_progress_restores_the_logger():
    logger = logging.getLogger(FIT_LOGGER)
    level = logger.level
    stream = io.StringIO()
    with show_progress(stream, prefix="p"):
        logger.info("step %d of %d", 1, 2)
        logger.debug("not shown")
    logger.info("after the block")
    lines = stream.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("p: [") and lines[0].endswith("] step 1 of 2")
    assert logger.level == level and logger.handlers == []


def test_kernel_option_gives_the_estimators_kernels():
    from gpmultirate.kernels import SS, TC

    assert kernel_option("dc") is None and kernel_option("auto") == "auto"
    for name, cls in (("tc", TC), ("ss", SS)):
        kernel = kernel_option(name)
        assert isinstance(kernel.k2, cls) and kernel.k1.constant_value == 1.0
        assert tuple(kernel.k1.constant_value_bounds) == (1e-8, 1e8)
    assert set(FIT_KERNELS) == {"dc", "tc", "ss", "auto"}
    with pytest.raises(ValueError, match="name"):
        kernel_option("pk")


def test_argument_types():
    import argparse

    assert int_at_least(3)("3") == 3 and order_or_auto("auto") == "auto"
    for parse, text in ((int_at_least(3), "2"), (int_at_least(3), "x"), (order_or_auto, "0")):
        with pytest.raises(argparse.ArgumentTypeError):
            parse(text)


def test_journal_helpers(tmp_path):
    path = tmp_path / "runs.jsonl"
    assert prepare_journal(path) is None and journal_progress(path) is None
    assert "nothing to resume" in prepare_journal(path, resume=True)
    run_paper_study(n_runs=1, orders=(10,), methods=("LS",), n_samples=60, progress=False,
                    journal=path)
    assert journal_progress(path) == (1, 1)
    with pytest.raises(ValueError, match="1 of 1 finished runs"):
        prepare_journal(path)
    assert prepare_journal(path, resume=True) is None and path.exists()
    assert "1 of 1 runs are saved" in interrupted_message(path)
    assert prepare_journal(path, force=True) is None and not path.exists()
    path.write_text("not a journal\nnor this\n")
    with pytest.raises(ValueError, match="unreadable"):
        prepare_journal(path)
    path.unlink()
    path.mkdir()
    with pytest.raises(ValueError, match="directory"):
        prepare_journal(path)
