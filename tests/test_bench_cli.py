"""``alphaprk bench`` runs the benchmarks through the installed script."""

import shutil
import subprocess

import pytest

ALPHAPRK = shutil.which("alphaprk")


@pytest.mark.skipif(ALPHAPRK is None, reason="the alphaprk script is not installed")
def test_bench_forwards_to_each_benchmark():
    for name, option in (("cost", "--energy-steps"), ("energy", "--system")):
        result = subprocess.run(
            [ALPHAPRK, "bench", name, "--help"], capture_output=True, text=True, timeout=120
        )
        assert (
            result.returncode == 0 and f"alphaprk bench {name}" in result.stdout and option in result.stdout
        )
    result = subprocess.run([ALPHAPRK, "bench", "speed"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "invalid choice: 'speed'" in result.stderr


def test_cost_help_names_the_system_and_integrator_options(capsys):
    from openmm_alphaprk.benchmarks.cost import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for option in (
        "--system NAME",
        "--hydrogen-mass AMU",
        "--integrators NAME [NAME ...]",
        "rattle4+rescale",
    ):
        assert option in text
