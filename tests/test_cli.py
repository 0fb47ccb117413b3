"""The ``alphaprk`` command line: in this process (``cli.main``), and through the installed script
where the process is the point (the script itself, exit statuses, signals, a killed run)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

from openmm_alphaprk.observables import drift_text
from openmm_alphaprk.systems.definitions import DEFINITIONS_DIR, load_definition

SCRIPT = Path(sys.executable).with_name("alphaprk")


def alphaprk(*args, cwd, env_cache, check=True, process=False):
    """Run ``alphaprk ARGS`` in ``cwd`` with ``env_cache`` as the systems cache: its exit status and output.

    In this process (``cli.main``) unless ``process``: through the installed script, where
    the process itself is what a test checks.
    """
    if process:
        env = {**os.environ, "ALPHAPRK_CACHE_DIR": str(env_cache)}
        result = subprocess.run(
            [str(SCRIPT), *map(str, args)],
            cwd=cwd,
            env=env,
            capture_output=True,
            text=True,
            encoding="utf-8",
            timeout=300,
        )
    else:
        result = _in_process(list(map(str, args)), cwd, env_cache)
    if check and result.returncode != 0:
        raise AssertionError(f"alphaprk {args} failed ({result.returncode}):\n{result.stderr}")
    return result


def _in_process(args: list[str], cwd, env_cache) -> subprocess.CompletedProcess:
    """``cli.main(args)`` as the script runs it: in ``cwd``, with the cache variable set, output captured."""
    from openmm_alphaprk.cli import main

    stdout, stderr = io.StringIO(), io.StringIO()
    previous_cwd, previous_cache = Path.cwd(), os.environ.get("ALPHAPRK_CACHE_DIR")
    os.chdir(cwd)
    os.environ["ALPHAPRK_CACHE_DIR"] = str(env_cache)
    try:
        with (
            contextlib.redirect_stdout(stdout),
            contextlib.redirect_stderr(stderr),
            warnings.catch_warnings(),
        ):
            warnings.simplefilter("default")  # each call shows its warnings, as a new process would
            try:
                returncode = main(args)
            except SystemExit as exit_:  # argparse: --help, usage errors
                returncode = exit_.code if isinstance(exit_.code, int) else 1
    finally:
        os.chdir(previous_cwd)
        if previous_cache is None:
            os.environ.pop("ALPHAPRK_CACHE_DIR", None)
        else:
            os.environ["ALPHAPRK_CACHE_DIR"] = previous_cache
    return subprocess.CompletedProcess(
        ["alphaprk", *args], returncode or 0, stdout.getvalue(), stderr.getvalue()
    )


@pytest.fixture(scope="module")
def quick_definition(tmp_path_factory):
    """tip3p-2nm as a definition file with a short equilibration (the CLI takes .toml paths)."""
    folder = tmp_path_factory.mktemp("definitions")
    source = (DEFINITIONS_DIR / "tip3p-2nm.toml").read_text(encoding="utf-8")
    source = source.replace("langevin_steps = 1000", "langevin_steps = 10").replace(
        "minimize_max_iterations = 500", "minimize_max_iterations = 50"
    )
    path = folder / "quick-box.toml"
    path.write_text(source, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cli-cache")


def test_script_is_installed():
    assert SCRIPT.is_file(), "run `pip install -e .[test,plots]` to install the alphaprk console script"


def test_help_explains_every_option_with_units(tmp_path, cache):
    top = alphaprk("--help", cwd=tmp_path, env_cache=cache, process=True).stdout
    for command in ("systems", "run", "compare", "analyze"):
        assert command in top
    assert "leapfrog" in top and "BASE[:SET][=alpha][+rescale[@N]]" in top and "alpha[4|6]" in top
    run_help = alphaprk("run", "--help", cwd=tmp_path, env_cache=cache).stdout
    for option, unit in (
        ("--timestep", "fs"),
        ("--length", "ps"),
        ("--steps", "steps"),
        ("--platform", "CPU"),
        ("--constraint-tolerance", "dimensionless"),
        ("--energy-interval", "steps"),
        ("--trajectory-interval", "steps"),
        ("--checkpoint-interval", "steps"),
        ("--checkpoint-seconds", "seconds"),
        ("--controller-interval", "steps"),
        ("--cache-dir", "ALPHAPRK_CACHE_DIR"),
    ):
        assert option in run_help and unit in run_help
    compare_help = alphaprk("compare", "--help", cwd=tmp_path, env_cache=cache).stdout
    assert "kJ/mol/ns per DOF" in compare_help and "tip3p-3nm" in compare_help
    # where the output goes when -o is not given
    flat = " ".join(compare_help.split())
    assert "alphaprk-compare-<system> in the current directory" in flat, flat
    assert "alphaprk-run-<system>-<integrator> in the current directory" in " ".join(run_help.split())
    analyze_help = alphaprk("analyze", "--help", cwd=tmp_path, env_cache=cache).stdout
    assert "--rdf-max" in analyze_help and "nm" in analyze_help
    module = subprocess.run(
        [sys.executable, "-m", "openmm_alphaprk", "--help"],
        capture_output=True,
        text=True,
        encoding="utf-8",
        check=True,
    )
    assert module.stdout == top


def test_systems_lists_the_definitions_and_where_their_states_come_from(tmp_path):
    out = alphaprk("systems", cwd=tmp_path, env_cache=tmp_path / "empty").stdout
    for name in ("tip3p-3nm", "spce-3nm", "tip4pew-3nm", "water-cluster", "villin"):
        assert name in out
    assert re.search(r"^tip3p-3nm +shipped ", out, re.M) and re.search(r"^tip3p-4nm +to build ", out, re.M)


def test_systems_build_uses_the_shipped_state_and_rebuild_builds(tmp_path):
    cache = tmp_path / "cache"
    out = alphaprk("systems", "--build", "water-cluster", cwd=tmp_path, env_cache=cache).stdout
    assert "water-cluster: 222 atoms, shipped start state" in out and "--rebuild" in out
    assert not cache.exists()  # nothing built
    out = alphaprk("systems", "--build", "water-cluster", "--rebuild", cwd=tmp_path, env_cache=cache).stdout
    assert "water-cluster: 222 atoms, cached in" in out and len(list(cache.glob("water-cluster-*"))) == 1
    refused = alphaprk("systems", "--rebuild", cwd=tmp_path, env_cache=cache, check=False, process=True)
    assert refused.returncode == 2 and "--rebuild needs the systems to build" in refused.stderr


@pytest.mark.parametrize("command", ["run", "compare"])
def test_rebuild_option_starts_runs_from_a_state_built_here(tmp_path, command):
    from openmm_alphaprk.systems.cache import system_key
    from openmm_alphaprk.systems.shipped import shipped_key

    definition = load_definition("water-cluster")
    keys = {}
    for rebuild in ((), ("--rebuild",)):
        output = tmp_path / f"out{len(rebuild)}"
        args = [command, "water-cluster", "-o", output, "--steps", "2", "--quiet", *rebuild]
        args += ["-i", "rattle", "--no-plot"] if command == "compare" else ["rattle"]
        alphaprk(*args, cwd=tmp_path, env_cache=tmp_path / "cache")
        run_json = output / "run.json" if command == "run" else output / "rattle" / "run.json"
        keys[bool(rebuild)] = json.loads(run_json.read_text(encoding="utf-8"))["system_key"]
    assert keys == {False: shipped_key(definition), True: system_key(definition)}
    if command == "run":  # a run started from a rebuilt state is not continued from the shipped one
        args = ["run", "water-cluster", "rattle", "-o", tmp_path / "out1", "--steps", "2", "--quiet"]
        again = alphaprk(*args, cwd=tmp_path, env_cache=tmp_path / "cache", check=False)
        assert again.returncode == 2 and "system_key: stored" in again.stderr


def test_systems_build_caches_a_definition(tmp_path, cache, quick_definition):
    out = alphaprk("systems", "--build", quick_definition, cwd=tmp_path, env_cache=cache).stdout
    assert "quick-box: 774 atoms, cached in" in out and str(cache) in out


def test_run_then_analyze(tmp_path, cache, quick_definition):
    result = alphaprk(
        "run",
        quick_definition,
        "alpha=1/6",
        "-o",
        "out",
        "--length",
        "0.04ps",
        "--timestep",
        "2 fs",
        "--energy-interval",
        "2",
        "--trajectory-interval",
        "5",
        "--velocity-interval",
        "4",
        "--quiet",
        "--json",
        cwd=tmp_path,
        env_cache=cache,
    )
    summary = json.loads(result.stdout)
    assert summary["steps"] == 20 and summary["integrator"] == "alpha=1/6"
    import MDAnalysis as mda  # --velocity-interval: positions and velocities every 4 steps, in a TRR

    frames = mda.Universe(str(tmp_path / "out" / "topology.pdb"), str(tmp_path / "out" / "trajectory.trr"))
    assert [ts.data["step"] for ts in frames.trajectory] == [4, 8, 12, 16, 20]
    assert frames.trajectory.ts.has_velocities and abs(frames.atoms.velocities).max() > 1  # Å/ps
    assert json.loads((tmp_path / "out" / "summary.json").read_text(encoding="utf-8")) == summary
    analysis = alphaprk("analyze", "out", "--rdf-max", "0.8nm", cwd=tmp_path, env_cache=cache)
    assert "O-O RDF: first peak" in analysis.stdout and "drift" in analysis.stdout
    # rounded fit window, labelled progress bars, why the DCD's constraint error is larger
    assert re.search(r"fit over lags \d+(\.\d{1,3})?-\d+(\.\d{1,3})? ps\)", analysis.stdout), analysis.stdout
    # D with its standard error and the frames it is from; the drift with its standard error
    analysed = json.loads((tmp_path / "out" / "analysis.json").read_text(encoding="utf-8"))
    msd, energy = analysed["msd"], analysed["energy"]
    d, error = (
        msd["diffusion_coefficient_1e-5_cm2_per_s"],
        msd["diffusion_coefficient_standard_error_1e-5_cm2_per_s"],
    )
    assert f"D = {d:.3g} ± {error:.2g} x 1e-5 cm^2/s from 4 frames" in analysis.stdout, analysis.stdout
    assert msd["frames"] == 4 and error > 0
    drift = drift_text(energy["drift_per_dof"], energy["drift_per_dof_standard_error"], "kJ/mol/ns")
    assert f"drift/DOF {drift};" in analysis.stdout and "±" in drift
    assert (
        energy["drift_per_dof"] == summary["drift_per_dof"]
        and energy["rms_residual"] == summary["rms_residual"]
    )
    assert "constraint deviation: 100%" in analysis.stderr and "MSD (EinsteinMSD): 100%" in analysis.stderr
    assert "float32" in analysis.stdout and "full-precision final state" in analysis.stdout
    note = json.loads((tmp_path / "out" / "analysis.json").read_text(encoding="utf-8"))["constraints"]["note"]
    assert "float32" in note and "full-precision final state" in note
    assert (tmp_path / "out" / "rdf_OO.png").is_file() and (tmp_path / "out" / "analysis.json").is_file()
    # the same command again: the finished run is reported, not redone
    again = alphaprk(
        "run",
        quick_definition,
        "alpha=1/6",
        "-o",
        "out",
        "--length",
        "0.04ps",
        "--energy-interval",
        "2",
        "--trajectory-interval",
        "5",
        "--velocity-interval",
        "4",
        "--quiet",
        "--json",
        cwd=tmp_path,
        env_cache=cache,
    )
    assert json.loads(again.stdout) == summary


def test_compare_prints_the_table(tmp_path, cache, quick_definition):
    result = alphaprk(
        "compare",
        quick_definition,
        "-i",
        "rattle",
        "energy",
        "verlet",
        "--steps",
        "4",
        "--energy-interval",
        "2",
        "--accuracy-steps",
        "2",
        "--quiet",
        "-o",
        "cmp",
        cwd=tmp_path,
        env_cache=cache,
    )
    lines = result.stdout.splitlines()
    assert any(line.startswith("rattle ") for line in lines)
    assert any(line.startswith("energy ") for line in lines)
    assert "leapfrog" in result.stdout and (tmp_path / "cmp" / "energy_residuals.png").is_file()
    assert "pos. error" in result.stdout  # after 2 steps (--accuracy-steps)


def test_run_prints_a_table_and_where_the_files_are(tmp_path, cache, quick_definition):
    """`alphaprk run` prints compare's table (with the energy mode's alpha* line), not raw JSON."""
    result = alphaprk(
        "run",
        quick_definition,
        "energy",
        "-o",
        "e",
        "--steps",
        "4",
        "--energy-interval",
        "2",
        "--quiet",
        cwd=tmp_path,
        env_cache=cache,
    )
    lines = result.stdout.splitlines()
    assert lines[0].startswith("quick-box: 774 atoms") and "4 steps" in lines[0]
    for column in ("integrator", "steps", "drift/DOF", "RMS|H-Eref|", "max|H-Eref|", "evals/step", "ns/day"):
        assert column in lines[1]
    assert re.match(r"energy +4 ", lines[3])
    assert "alpha* median" in result.stdout and "fell back" in result.stdout
    assert f"run directory: e, summary: {Path('e') / 'summary.json'}" in result.stdout
    assert not result.stdout.lstrip().startswith("{")


def test_integrator_help_lists_every_name(tmp_path, cache):
    """the integrator argument's help (run) and -i's (compare) name every family's form."""
    from openmm_alphaprk.runs.integrator_names import VOCABULARY

    run_help = alphaprk("run", "--help", cwd=tmp_path, env_cache=cache).stdout
    compare_help = alphaprk("compare", "--help", cwd=tmp_path, env_cache=cache).stdout
    for text, start, end in (
        (run_help, "\n  integrator ", "\noptions:"),
        (compare_help, "\n  -i ", "\n  -o "),
    ):
        block = text[text.index(start) :]
        words = " ".join(block[: block.index(end)].split())
        for form in VOCABULARY:
            assert form in words, (form, words)


@pytest.mark.parametrize(
    "args", [["run", "tip4pew-3nm", "energy"], ["run", "tip4pew-3nm", "rattle"], ["compare", "tip4pew-3nm"]]
)
def test_virtual_site_refusal_names_commands_that_work(tmp_path, cache, args):
    """the advice is runnable: integrators are positional (run) or -i (compare), no --integrator."""
    from openmm_alphaprk.cli import build_parser

    result = alphaprk(*args, cwd=tmp_path, env_cache=cache, check=False)
    assert result.returncode == 2 and "virtual sites" in result.stderr
    assert "`alphaprk run tip4pew-3nm verlet`" in result.stderr
    assert "`alphaprk compare tip4pew-3nm -i verlet`" in result.stderr
    assert "use the integrator" not in result.stderr and "--integrator" not in result.stderr
    commands = re.findall(r"`alphaprk ([^`]+)`", result.stderr)
    assert len(commands) >= 3
    for command in commands:
        build_parser().parse_args(command.split())  # exits (fails the test) on an unknown option
    help_text = alphaprk("run", "--help", cwd=tmp_path, env_cache=cache).stdout
    for option in re.findall(r"(?<![\w-])--[a-z][a-z-]*", result.stderr):
        assert option in help_text, option


def test_compare_refuses_a_folder_of_longer_runs(tmp_path, cache):
    """--steps 20 over 40-step runs is refused in one line that says so (not a DCD reader's error)."""
    common = ["compare", "water-cluster", "-i", "rattle", "-o", "cmp", "--no-plot", "--quiet"]
    alphaprk(*common, "--steps", "40", cwd=tmp_path, env_cache=cache)
    shorter = alphaprk(*common, "--steps", "20", cwd=tmp_path, env_cache=cache, check=False)
    assert shorter.returncode == 2 and len(shorter.stderr.strip().splitlines()) == 1
    assert "holds a run of 40 steps, longer than the 20 asked for" in shorter.stderr
    assert "--steps 40" in shorter.stderr and "another output directory" in shorter.stderr
    assert "not a DCD file" not in shorter.stderr
    longer = alphaprk(*common, "--steps", "60", cwd=tmp_path, env_cache=cache)  # extended: the header is true
    assert "60 steps" in longer.stdout.splitlines()[0]
    assert any(re.match(r"rattle +60 ", line) for line in longer.stdout.splitlines())


@pytest.mark.parametrize(
    "args, message",
    [
        (["run", "tip5p-box", "rattle"], "unknown system 'tip5p-box'"),
        (["run", "tip3p-2nm", "leapfrog"], "unknown integrator 'leapfrog'"),
        (["run", "tip3p-2nm", "rattle", "--timestep", "2nm"], "'nm' is not a unit of a time"),
        (["run", "tip3p-2nm", "rattle", "--timestep", "2"], "has no unit"),
        (["run", "tip3p-2nm", "rattle", "--length=-1ps"], "must be positive"),
        (["run", "tip4pew-3nm", "rattle"], "virtual sites"),
        (["compare", "tip4pew-3nm"], "virtual sites"),
        (["analyze", "nowhere"], "not a run directory"),
    ],
)
def test_errors_are_one_clear_line(tmp_path, cache, args, message):
    result = alphaprk(*args, cwd=tmp_path, env_cache=cache, check=False)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_output_directory_with_a_different_run_is_refused(tmp_path, cache, quick_definition):
    common = ["--steps", "2", "--quiet", "-o", "out"]
    alphaprk("run", quick_definition, "rattle", *common, cwd=tmp_path, env_cache=cache)
    result = alphaprk("run", quick_definition, "verlet", *common, cwd=tmp_path, env_cache=cache, check=False)
    assert result.returncode == 2
    assert "holds a different run (integrator: stored 'rattle', requested 'verlet')" in result.stderr
    (tmp_path / "papers").mkdir()
    (tmp_path / "papers" / "draft.tex").write_text("keep me", encoding="utf-8")
    result = alphaprk(
        "run",
        quick_definition,
        "rattle",
        "--steps",
        "2",
        "-o",
        "papers",
        cwd=tmp_path,
        env_cache=cache,
        check=False,
    )
    assert result.returncode == 2 and "not a run directory" in result.stderr
    assert (tmp_path / "papers" / "draft.tex").read_text(encoding="utf-8") == "keep me"


def _ctrl_c_as_in_a_terminal() -> None:
    """In the child: SIGINT's default disposition, which Python turns into KeyboardInterrupt.

    A shell starts the background jobs of a script (and ``nohup``/``&`` starts pytest) with
    SIGINT ignored, which a child inherits and Python then leaves ignored.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_checkpoints_and_says_from_which_step_the_same_command_resumes(tmp_path, cache):
    """SIGINT (Ctrl-C) long before the first step-count checkpoint: the work is kept, and said to be."""
    source = (DEFINITIONS_DIR / "water-cluster.toml").read_text(encoding="utf-8")
    definition = tmp_path / "quick-cluster.toml"
    definition.write_text(source.replace("langevin_steps = 1000", "langevin_steps = 10"), encoding="utf-8")
    args = [SCRIPT, "run", definition, "rattle", "--platform", "Reference", "--steps", "3000"]
    args += [
        "--checkpoint-interval",
        "100000",
        "--energy-interval",
        "10",
        "--trajectory-interval",
        "50",
        "--quiet",
    ]
    env = {**os.environ, "ALPHAPRK_CACHE_DIR": str(cache)}
    subprocess.run([*map(str, args), "-o", "whole"], cwd=tmp_path, env=env, check=True, capture_output=True)
    process = subprocess.Popen(
        [*map(str, args), "-o", "parts"],
        cwd=tmp_path,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_ctrl_c_as_in_a_terminal,
    )
    energies = tmp_path / "parts" / "energies.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and process.poll() is None:
        if energies.is_file() and len(energies.read_text(encoding="utf-8").splitlines()) > 30:
            break
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    found = re.search(
        r"interrupted at step (\d+) of 3000; checkpoint written: "
        r"the same command resumes it from step (\d+)\.",
        stderr,
    )
    assert found and found.group(1) == found.group(2), stderr
    assert int(found.group(1)) % 10 == 0 and 290 <= int(found.group(1)) < 3000
    assert (tmp_path / "parts" / "checkpoint.chk").is_file()
    alphaprk(*args[1:], "-o", "parts", cwd=tmp_path, env_cache=cache)
    summary = json.loads((tmp_path / "parts" / "summary.json").read_text(encoding="utf-8"))
    assert summary["steps_this_call"] == 3000 - int(found.group(1))
    assert energies.read_text(encoding="utf-8") == (tmp_path / "whole" / "energies.csv").read_text(
        encoding="utf-8"
    )


def test_interrupt_messages_say_what_the_same_command_does(tmp_path, monkeypatch, capsys):
    """The CLI prints the run's own account of an interruption, and otherwise what resuming does."""
    import openmm_alphaprk.runs as runs
    from openmm_alphaprk.cli import main
    from openmm_alphaprk.runs import RunInterrupted

    def no_checkpoint(*args, **kwargs):
        raise RunInterrupted(
            "run in x interrupted at step 6 of 30; no checkpoint yet: "
            "the same command starts it again from step 0.",
            tmp_path,
            6,
            None,
        )

    monkeypatch.setattr(runs, "run_nve", no_checkpoint)
    assert main(["run", "water-cluster", "rattle", "-o", str(tmp_path / "x"), "--quiet"]) == 130
    assert capsys.readouterr().err == (
        "alphaprk run: run in x interrupted at step 6 of 30; no checkpoint yet: the same command starts it "
        "again from step 0.\n"
    )

    def elsewhere(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runs, "run_nve", elsewhere)
    assert main(["run", "water-cluster", "rattle", "-o", str(tmp_path / "x"), "--quiet"]) == 130
    err = capsys.readouterr().err
    assert "interrupted while no run was stepping" in err and "from step 0 where it has none" in err


def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path, cache):
    """SIGKILL part-way (no clean-up at all), then the same command: the same files as one run."""
    source = (DEFINITIONS_DIR / "water-cluster.toml").read_text(encoding="utf-8")
    definition = tmp_path / "quick-cluster.toml"
    definition.write_text(source.replace("langevin_steps = 1000", "langevin_steps = 10"), encoding="utf-8")
    args = [
        str(SCRIPT),
        "run",
        definition,
        "rattle",
        "--platform",
        "Reference",
        "--steps",
        "2500",
        "--checkpoint-interval",
        "500",
        "--energy-interval",
        "10",
        "--trajectory-interval",
        "50",
        "--quiet",
    ]
    env = {**os.environ, "ALPHAPRK_CACHE_DIR": str(cache)}
    subprocess.run([*map(str, args), "-o", "whole"], cwd=tmp_path, env=env, check=True, capture_output=True)
    process = subprocess.Popen([*map(str, args), "-o", "parts"], cwd=tmp_path, env=env)
    checkpoint = tmp_path / "parts" / "checkpoint.chk"
    deadline = time.monotonic() + 120
    while not checkpoint.exists() and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
    process.kill()
    process.wait()
    assert not (tmp_path / "parts" / "summary.json").exists(), "the run finished before it could be killed"
    energies = (tmp_path / "parts" / "energies.csv").read_text(encoding="utf-8")
    assert energies.startswith("#") and len(energies.splitlines()) > 1  # readable after a kill
    alphaprk(*args[1:], "-o", "parts", cwd=tmp_path, env_cache=cache)
    read = {run: (tmp_path / run / "trajectory.dcd").read_bytes() for run in ("parts", "whole")}
    assert (tmp_path / "parts" / "energies.csv").read_text(encoding="utf-8") == (
        tmp_path / "whole" / "energies.csv"
    ).read_text(encoding="utf-8")
    # DCD: the same frame count and frames; the header's title holds the creation time
    assert read["parts"][8:12] == read["whole"][8:12] and read["parts"][276:] == read["whole"][276:]
    assert len(read["whole"]) > 276 + 40 * 3 * 222 * 4
    whole = json.loads((tmp_path / "whole" / "summary.json").read_text(encoding="utf-8"))
    parts = json.loads((tmp_path / "parts" / "summary.json").read_text(encoding="utf-8"))
    for key in ("e_ref", "drift_per_dof", "rms_residual", "max_relative_constraint_error", "momentum_change"):
        assert parts[key] == whole[key], key


def test_input_errors_are_one_line_and_bugs_keep_their_traceback(monkeypatch, capsys):
    """An InputError (the package's error about the user's input) is one line; a plain ValueError is a bug."""
    from openmm_alphaprk import cli
    from openmm_alphaprk._units import InputError

    def raise_(error):
        def command(args):
            raise error

        return command

    monkeypatch.setitem(cli.COMMANDS, "systems", raise_(InputError("steps must be positive, got -1.")))
    assert cli.main(["systems"]) == 2
    assert capsys.readouterr().err.strip() == "alphaprk systems: error: steps must be positive, got -1."
    monkeypatch.setitem(cli.COMMANDS, "systems", raise_(ValueError("a library bug")))
    with pytest.raises(ValueError, match="a library bug"):
        cli.main(["systems"])
