"""Every script in examples/ runs in its quick mode and writes its figures."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"

# script -> files it must write into --output
OUTPUTS = {
    "adding_a_kernel.py": ["adding_a_kernel.png", "adding_a_kernel.npz"],
    "example1_nonidentifiability.py": ["example1_nonidentifiability.png"],
    "wafer_stage_pk.py": ["wafer_stage_bode.png"],
    "intersample_prediction.py": ["intersample_prediction.png"],
    "sklearn_gpr_observed_kernel.py": ["sklearn_gpr_observed_kernel.png"],
    "robot_arm_real_data.py": ["robot_arm_real_data.png"],
    "cd_player_arm.py": ["cd_player_arm.png"],
    "dropped_frames.py": ["dropped_frames.png"],
    "camera_frames.py": ["camera_frames.png"],
    "experiment_design.py": ["experiment_design.png"],
    "closed_loop.py": ["closed_loop.png"],
    "reduced_model.py": ["reduced_model.png"],
    "paper_simulation.py": ["paper_study_gof.png", "paper_example_bode.png", "paper_systems_frf.png",
                            "paper_study.json"],
}
# a line each script prints when it got to its key result
KEY_OUTPUT = {
    "adding_a_kernel.py": "LowRankTerm",
    "example1_nonidentifiability.py": "IdentifiabilityError",
    "wafer_stage_pk.py": "validation GoF",
    "intersample_prediction.py": "empirical coverage",
    "sklearn_gpr_observed_kernel.py": "log marginal likelihood",
    "robot_arm_real_data.py": "validation GoF",
    "cd_player_arm.py": "two-input fit",
    "dropped_frames.py": "dropped frames",
    "camera_frames.py": "own instants, exact (tuned)",
    "experiment_design.py": "designed input narrows the predicted mean band",
    "closed_loop.py": "| excitation |",
    "reduced_model.py": "closed loop stable on the true system: True",
    "paper_simulation.py": "| P |",
}
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_every_example_is_covered():
    scripts = {p.name for p in EXAMPLES.glob("*.py")}
    assert scripts == set(OUTPUTS)


def test_every_example_is_described_and_shown():
    """Each script has a section in examples/README.md, an entry and its source in the docs."""
    readme = (EXAMPLES / "README.md").read_text()
    docs = (EXAMPLES.parent / "docs" / "examples.rst").read_text()
    for script in sorted(OUTPUTS):
        assert f"## `{script}`" in readme, f"examples/README.md has no section for {script}"
        assert f"\n``{script}``\n" in docs, f"docs/examples.rst does not list {script}"
        assert f"literalinclude:: ../examples/{script}" in docs, \
            f"docs/examples.rst does not show the source of {script}"


@pytest.mark.slow
@pytest.mark.parametrize("script", sorted(OUTPUTS))
def test_example_runs_and_writes_figures(script, tmp_path):
    output = tmp_path / "figures"
    env = dict(os.environ)
    # One BLAS thread: the matrices are small, and several test processes or a
    # busy machine make multithreaded BLAS many times slower, not faster.
    env.update(MPLBACKEND="Agg", OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    completed = subprocess.run(
        [sys.executable, str(EXAMPLES / script), "--output", str(output), "--quick"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
    )
    assert completed.returncode == 0, completed.stdout[-2000:] + completed.stderr[-4000:]
    assert "Traceback" not in completed.stderr
    assert KEY_OUTPUT[script] in completed.stdout
    for name in OUTPUTS[script]:
        path = output / name
        assert path.is_file(), f"{script} did not write {name}"
        data = path.read_bytes()
        if name.endswith(".png"):
            assert data.startswith(PNG_SIGNATURE) and len(data) > 10_000
        else:
            assert len(data) > 0
    # nothing but the figures goes into the working directory
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figures"]
