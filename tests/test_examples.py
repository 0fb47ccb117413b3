"""The examples run (with few steps), so they cannot rot."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return {**os.environ, "ALPHAPRK_CACHE_DIR": str(tmp_path_factory.mktemp("example-cache"))}


def _run(script: str, *args, cwd, env) -> str:
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        encoding="utf-8",
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "NonSmoothForcesWarning" not in result.stderr, result.stderr
    return result.stdout


def test_dropin_simulation_script(tmp_path, env):
    args = ["--steps", "20", "--minimize-steps", "50", "--output", "run"]
    out = _run("simulation_dropin.py", *args, cwd=tmp_path, env=env)
    assert "force evaluations per step" in out
    assert re.search(r"^CMMotionRemover \(force \d+\): removed", out, re.M)  # createSystem's default
    rows = (tmp_path / "run" / "energies.csv").read_text(encoding="utf-8").splitlines()
    assert rows[0].startswith("#") and len(rows) == 3  # header + steps 10, 20


def test_compare_script(tmp_path, env):
    args = ["--steps", "6", "--accuracy-steps", "2", "--output", "cmp"]
    out = _run("compare_integrators.py", *args, cwd=tmp_path, env=env)
    assert "alpha=1/6" in out and "figure:" in out and "pos. error" in out
    assert (tmp_path / "cmp" / "energy_residuals.png").is_file()


def test_analysis_script(tmp_path, env):
    out = _run("analyze_run.py", "--steps", "40", cwd=tmp_path, env=env)
    assert "O-O RDF: first peak" in out and "diffusion: D =" in out and "drift_per_dof" in out
    assert "from 4 frames" in out and "drift/DOF: " in out and " ± " in out
