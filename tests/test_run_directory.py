"""A run directory held by a live run is refused to another; a damaged checkpoint loses one interval."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from quick_systems import quick_system

from openmm_alphaprk.runs import run_nve, rundir
from openmm_alphaprk.runs.rundir import RunDirectoryError

RUN = dict(
    platform="Reference", energy_interval=2, trajectory_interval=4, checkpoint_interval=10, progress=False
)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    return quick_system("water-cluster", tmp_path_factory.mktemp("cache"))


def test_a_directory_held_by_a_run_is_refused_to_another_before_anything_is_touched(cluster, tmp_path):
    run_nve(cluster, "rattle", tmp_path, steps=10, **RUN)
    before = {path.name: path.read_bytes() for path in tmp_path.iterdir() if path.is_file()}
    held = rundir.lock_run_directory(tmp_path)  # what a live run holds
    try:
        with pytest.raises(
            RunDirectoryError, match=rf"in use by another run \(process {os.getpid()}\): wait"
        ):
            run_nve(cluster, "rattle", tmp_path, steps=20, **RUN)
        after = {path.name: path.read_bytes() for path in tmp_path.iterdir() if path.is_file()}
        assert after == before
    finally:
        held.close()
    assert run_nve(cluster, "rattle", tmp_path, steps=20, **RUN).steps == 20  # released: extended


def test_two_processes_on_one_output_directory(tmp_path):
    """Through the installed script: the second process is refused (exit status 2) while the first runs."""
    script = Path(sys.executable).with_name("alphaprk")
    env = {**os.environ, "ALPHAPRK_CACHE_DIR": str(tmp_path / "cache")}
    args = [str(script), "run", "water-cluster", "rattle", "--platform", "Reference", "--steps", "100000",
            "-o", "out", "--quiet", "--energy-interval", "10"]  # fmt: skip
    first = subprocess.Popen(args, cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True, encoding="utf-8")
    try:
        energies = tmp_path / "out" / rundir.ENERGIES_FILE
        deadline = time.monotonic() + 120
        while not (energies.is_file() and len(energies.read_text().splitlines()) > 3):
            assert time.monotonic() < deadline and first.poll() is None, "the first run did not start"
            time.sleep(0.1)
        second = subprocess.run(
            args, cwd=tmp_path, env=env, capture_output=True, text=True, encoding="utf-8", timeout=120
        )
        assert second.returncode == 2, second.stderr
        assert f"in use by another run (process {first.pid})" in second.stderr
        assert "Traceback" not in second.stderr
        assert first.poll() is None  # the first one runs on, untouched
    finally:
        first.kill()
        first.wait()


def _energies(path: Path) -> np.ndarray:
    return rundir.read_energies(path / rundir.ENERGIES_FILE)


def test_a_damaged_checkpoint_resumes_from_the_one_before_it(cluster, tmp_path):
    whole = run_nve(cluster, "rattle", tmp_path / "whole", steps=30, **RUN)
    parts = tmp_path / "parts"
    run_nve(cluster, "rattle", parts, steps=20, **RUN)  # checkpoints of steps 10 and 20
    (parts / rundir.CHECKPOINT_FILE).write_bytes(b"cut short")
    with pytest.warns(
        RuntimeWarning, match=r"checkpoint.chk: .*unreadable; resumed from .*previous.chk \(step 10\)"
    ):
        extended = run_nve(cluster, "rattle", parts, steps=30, **RUN)
    assert extended.steps == 30 and extended.steps_this_call == 20  # one interval lost, no more
    np.testing.assert_array_equal(_energies(parts)[:, :5], _energies(tmp_path / "whole")[:, :5])
    assert whole.steps == 30


def test_no_readable_checkpoint_names_the_files_and_the_way_out(cluster, tmp_path):
    run_nve(cluster, "rattle", tmp_path, steps=20, **RUN)
    for name in (rundir.CHECKPOINT_FILE, rundir.PREVIOUS_CHECKPOINT_FILE):
        (tmp_path / name).write_bytes(b"damaged")
    with pytest.raises(RunDirectoryError) as refused:
        run_nve(cluster, "rattle", tmp_path, steps=30, **RUN)
    message = str(refused.value)
    assert (
        str(tmp_path / rundir.CHECKPOINT_FILE) in message
        and str(tmp_path / rundir.PREVIOUS_CHECKPOINT_FILE) in message
    )
    assert f"To start the run again from step 0, remove {tmp_path}" in message
