"""Interrupted studies resume from their journal and give the uninterrupted result."""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from gpmultirate.cli import main
from gpmultirate.study import run_paper_study
from gpmultirate.study.journal import (
    JOURNAL_NAME,
    JournalError,
    StudyJournal,
    read_journal,
    study_settings,
)

# runs of about 0.3 s, so that an interrupt lands while some are still to do (the journal
# keeps every method's numbers alike: PK, which would make the study 4 times longer, adds nothing)
STUDY = ["--runs", "8", "--orders", "100", "200", "--n-samples", "300", "--methods", "LS", "DC",
         "--no-figures"]
N_RUNS = 8
# a quick study for the journal checks that need no interrupt
QUICK = ["--runs", "4", "--orders", "10", "20", "--n-samples", "60", "--methods", "LS", "DC",
         "--n-jobs", "1", "--no-figures", "--quiet"]
QUICK_STUDY = {"n_runs": 4, "orders": (10, 20), "methods": ("LS", "DC"), "n_samples": 60,
               "progress": False}
# wall times differ between any two runs; everything else must be equal
TIMES = {"fit_seconds", "run_seconds", "total_seconds", "mean_fit_seconds"}
TABLES = ("study.csv", "study_runs.csv", "study.json", "study.md", "study.rst")


def outputs(out, printed):
    """Every number and table of a demo's output folder, without the wall times."""
    study = {k: v for k, v in json.loads((out / "study.json").read_text()).items()
             if k not in TIMES}
    tables = {}
    for name in ("study.csv", "study_runs.csv"):
        with open(out / name, newline="") as stream:
            tables[name] = [{k: v for k, v in row.items() if k not in TIMES}
                            for row in csv.DictReader(stream)]
    texts = {name: (out / name).read_text() for name in ("study.md", "study.rst")}
    return {"json": study, **tables, **texts, "printed": printed}


def demo(out, options, capsys, *extra):
    capsys.readouterr()
    status = main(["demo", *options, "--output", str(out), *extra])
    return status, capsys.readouterr()


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    argv = [sys.executable, "-m", "gpmultirate", "demo", *STUDY, "--n-jobs", "1", "--quiet",
            "--output", str(out)]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=True)
    assert not (out / JOURNAL_NAME).exists()  # removed once the study is complete
    return outputs(out, done.stdout)


def journal_lines(path):
    try:
        return path.read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def interrupt(out, sig, n_jobs):
    """Start the study, send ``sig`` once two runs are in the journal, wait for the end."""
    argv = [sys.executable, "-m", "gpmultirate", "demo", *STUDY, "--n-jobs", str(n_jobs),
            "--output", str(out)]
    # the default SIGINT action in the child: a shell without job control starts
    # background commands (``pytest &``, ``nohup``) with SIGINT ignored, which
    # the child would inherit and the study would then run to its end
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, preexec_fn=_default_sigint)
    journal = out / JOURNAL_NAME
    deadline = time.monotonic() + 60
    try:
        while journal_lines(journal) < 3:  # the header and two runs
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "no run finished within 60 s"
            time.sleep(0.01)
        process.send_signal(sig)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    return process.returncode, err


# ------------------------------------------------------------ interrupts
@pytest.mark.slow
@pytest.mark.parametrize(("sig", "n_jobs"), [(signal.SIGINT, 2), (signal.SIGKILL, 1)],
                         ids=["SIGINT", "SIGKILL"])
def test_interrupted_study_resumes_to_the_same_result(tmp_path, capsys, reference, sig,
                                                      n_jobs):
    status, err = interrupt(tmp_path, sig, n_jobs)
    settings, trials = read_journal(tmp_path / JOURNAL_NAME)
    assert settings["n_runs"] == N_RUNS
    assert 2 <= len(trials) < N_RUNS, "the study ended before the interrupt"
    assert not (tmp_path / "study.json").exists()
    if sig == signal.SIGINT:
        assert status == 130
        assert "Traceback" not in err
        last = err.strip().splitlines()[-1]
        assert "interrupted" in last and "--resume" in last
        assert f"{len(trials)} of {N_RUNS} runs" in last
    else:
        assert status == -signal.SIGKILL

    # the same command without --resume refuses to discard the finished runs
    with pytest.raises(SystemExit) as exit_info:
        demo(tmp_path, STUDY, capsys, "--n-jobs", "1", "--quiet")
    assert exit_info.value.code == 2
    assert "--resume" in capsys.readouterr().err
    assert len(read_journal(tmp_path / JOURNAL_NAME)[1]) == len(trials)

    status, captured = demo(tmp_path, STUDY, capsys, "--n-jobs", "1", "--resume")
    assert status == 0
    assert f"{len(trials)} of {N_RUNS} runs done earlier" in captured.err
    assert f"run {len(trials) + 1}/{N_RUNS} done" in captured.err
    assert "run 1/" not in captured.err  # the finished runs were not run again
    assert outputs(tmp_path, captured.out) == reference
    assert not (tmp_path / JOURNAL_NAME).exists()


# ------------------------------------------------------------ the journal
@pytest.fixture(scope="module")
def quick_reference(tmp_path_factory):
    """Outputs of the quick study, and its full journal."""
    out = tmp_path_factory.mktemp("quick")
    assert main(["demo", *QUICK, "--output", str(out)]) == 0
    path = out / "full.jsonl"
    run_paper_study(**QUICK_STUDY, journal=path)
    return out, path.read_bytes()


def quick_outputs(out, printed):
    return {k: v for k, v in outputs(out, printed).items() if k != "printed"}


@pytest.mark.parametrize("tail", [b'{"run":3,"snr_db":4', b"{garbage\n", b""],
                         ids=["no-newline", "invalid-json", "none"])
def test_a_torn_last_line_is_dropped_on_resume(tmp_path, capsys, quick_reference, tail):
    reference_out, full = quick_reference
    lines = full.splitlines(keepends=True)
    assert len(lines) == 5  # header and 4 runs
    (tmp_path / JOURNAL_NAME).write_bytes(b"".join(lines[:3]) + tail)
    assert len(read_journal(tmp_path / JOURNAL_NAME)[1]) == 2

    status, _ = demo(tmp_path, QUICK, capsys, "--resume")
    assert status == 0
    assert quick_outputs(tmp_path, None) == quick_outputs(reference_out, None)


def test_resuming_cuts_the_torn_line_before_appending(tmp_path, quick_reference):
    _, full = quick_reference
    lines = full.splitlines(keepends=True)
    path = tmp_path / JOURNAL_NAME
    path.write_bytes(b"".join(lines[:3]) + lines[3][:25])
    result = run_paper_study(**QUICK_STUDY, journal=path)
    assert sorted(read_journal(path)[1]) == [0, 1, 2, 3]
    text = path.read_bytes()
    assert text.endswith(b"\n") and text.count(b"\n") == 5
    assert all(json.loads(line) for line in text.splitlines())
    uninterrupted = run_paper_study(**QUICK_STUDY)
    for method in ("LS", "DC"):
        np.testing.assert_array_equal(result.gof[method], uninterrupted.gof[method])
    np.testing.assert_array_equal(result.snr_db, uninterrupted.snr_db)


def test_other_settings_are_refused(tmp_path, capsys, quick_reference):
    _, full = quick_reference
    path = tmp_path / JOURNAL_NAME
    path.write_bytes(b"".join(full.splitlines(keepends=True)[:3]))
    for extra, difference in [(["--seed", "1"], "seed 0 (journal) vs 1 (now)"),
                              (["--factor", "2"], "factor 3 (journal) vs 2 (now)"),
                              (["--snr", "30", "60"],
                               "SNR range 40.0 60.0 (journal) vs 30.0 60.0 (now)")]:
        with pytest.raises(SystemExit) as exit_info:
            demo(tmp_path, QUICK, capsys, "--resume", *extra)
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert "other settings" in err and difference in err and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1
    with pytest.raises(SystemExit):
        demo(tmp_path, [*QUICK[:1], "5", *QUICK[2:]], capsys, "--resume")
    assert "runs 4 (journal) vs 5 (now)" in capsys.readouterr().err
    assert path.read_bytes() == b"".join(full.splitlines(keepends=True)[:3])  # untouched


def test_an_existing_journal_needs_resume_or_force(tmp_path, capsys, quick_reference):
    _, full = quick_reference
    path = tmp_path / JOURNAL_NAME
    partial = b"".join(full.splitlines(keepends=True)[:3])
    path.write_bytes(partial)
    with pytest.raises(SystemExit) as exit_info:
        demo(tmp_path, QUICK, capsys, "--seed", "3")
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "2 of 4 finished runs" in err and "--resume" in err and "--force" in err
    assert path.read_bytes() == partial
    with pytest.raises(SystemExit) as exit_info:
        demo(tmp_path, QUICK, capsys, "--resume", "--force")
    assert exit_info.value.code == 2
    status, _ = demo(tmp_path, QUICK, capsys, "--seed", "3", "--force")
    assert status == 0
    assert json.loads((tmp_path / "study.json").read_text())["random_state"] == 3
    assert not path.exists()


def test_a_corrupt_journal_is_refused(tmp_path, capsys, quick_reference):
    _, full = quick_reference
    lines = full.splitlines(keepends=True)
    path = tmp_path / JOURNAL_NAME
    path.write_bytes(lines[0] + b"{garbage\n" + lines[2])
    with pytest.raises(SystemExit) as exit_info:
        demo(tmp_path, QUICK, capsys, "--resume")
    assert exit_info.value.code == 2
    assert "line 2 is corrupt" in capsys.readouterr().err
    path.write_bytes(b'{"format": "something else"}\n')
    with pytest.raises(JournalError, match="not a study journal"):
        read_journal(path)


def test_resume_without_a_journal_starts_the_study(tmp_path, capsys, quick_reference):
    reference_out, _ = quick_reference
    status, _ = demo(tmp_path, QUICK, capsys, "--resume")
    assert status == 0
    assert quick_outputs(tmp_path, None) == quick_outputs(reference_out, None)


def test_a_journal_without_a_finished_run_is_replaced(tmp_path, capsys, quick_reference):
    _, full = quick_reference
    path = tmp_path / JOURNAL_NAME
    path.write_bytes(full[:20])  # killed while writing the header
    assert read_journal(path) == (None, {})
    status, _ = demo(tmp_path, QUICK, capsys, "--seed", "2")
    assert status == 0


def test_the_journal_is_locked_while_written(tmp_path):
    root = np.random.SeedSequence(0)
    from gpmultirate.study.simulation import check_config

    settings = study_settings(2, [10], ("LS",), check_config(60, 3, 0.1, (40, 60), 0.1), root)
    with StudyJournal.open(tmp_path / JOURNAL_NAME, settings):
        if os.name == "posix":
            with pytest.raises(JournalError, match="another process"):
                StudyJournal.open(tmp_path / JOURNAL_NAME, settings)


def test_a_fresh_seed_resumes_with_the_journal_seed(tmp_path):
    path = tmp_path / JOURNAL_NAME
    first = run_paper_study(**QUICK_STUDY, random_state=None, journal=path)
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join(lines[:2]))
    again = run_paper_study(**QUICK_STUDY, random_state=None, journal=path)
    assert again.random_state == first.random_state
    np.testing.assert_array_equal(again.gof["DC"], first.gof["DC"])
