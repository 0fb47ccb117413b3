"""The measurement scripts, run on tiny inputs: each still runs against the package as it is.

The scripts of tools/scripts and the experiments of ``openmm_alphaprk.benchmarks`` run as
modules measure numbers that pages of docs/ quote (each names its page). Their full runs
take minutes to hours or a GPU; here each runs once on the smallest input it accepts, so a
change of the package that breaks a script fails a test instead of the next measurement.
"""

from __future__ import annotations

import importlib.util
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "tools" / "scripts"


def _run(script: str, *args: str, timeout: float = 120) -> str:
    """Run ``python tools/scripts/SCRIPT ARGS`` (or ``-m MODULE ARGS``) from the root; return the output."""
    command = [str(SCRIPTS / script)] if script.endswith(".py") else ["-m", script]
    result = subprocess.run(
        [sys.executable, *command, *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        encoding="utf-8",  # the scripts print α, Δ, …: not the locale's (another test may have set it to C)
        timeout=timeout,
        env={**os.environ, "OPENMM_CPU_THREADS": "1", "PYTHONUTF8": "1"},
    )
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-4000:]
    return result.stdout


def test_alpha_placement_runs(tmp_path):
    out = tmp_path / "placement.json"
    text = _run(
        "openmm_alphaprk.benchmarks.alpha_placement",
        "--system",
        "water-cluster",
        "--horizons",
        "1",
        "2",
        "--json",
        str(out),
    )
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data["horizons"] == [1, 2] and "stages" in text
    # suzuki5: the energy mode on stages 1, 2, 3; α = 0 once; the fixed α on 1, 2, 3 and all
    assert [row["alpha"] for row in data["rows"]] == ["energy"] * 3 + [0.0] + [0.02] * 4
    assert all(len(row["position_rms"]) == 2 for row in data["rows"])


def test_compositions_survey_runs(tmp_path):
    out = tmp_path / "survey.json"
    _run(
        "openmm_alphaprk.benchmarks.compositions_survey",
        "--system",
        "water-cluster",
        "--horizons",
        "1",
        "--json",
        str(out),
    )
    rows = json.loads(out.read_text(encoding="utf-8"))["rows"]
    assert any(row["row"].startswith("RATTLE h/") for row in rows)
    assert sum(row["row"].endswith("energy mode") for row in rows) == sum(
        row["row"].endswith("α = 0") for row in rows
    )


def test_energy_noise_runs(tmp_path):
    out = tmp_path / "noise.json"
    _run(
        "openmm_alphaprk.benchmarks.energy_noise", "--boxes", "1.5", "--platforms", "CPU", "--json", str(out)
    )
    (result,) = json.loads(out.read_text(encoding="utf-8"))
    assert result["reference"] == "Reference" and 0 < result["std"]["CPU"] < 0.1


def test_pme_tolerance_runs_and_prints_its_table_again(tmp_path):
    out = tmp_path / "pme.json"
    args = ["--system", "tip3p-2nm", "--steps", "3", "--tolerances", "1e-4", "--timing-steps", "2"]
    _run("openmm_alphaprk.benchmarks.pme_tolerance", *args, "--timing-rounds", "1", "--json", str(out))
    assert json.loads(out.read_text(encoding="utf-8"))
    assert "1e-04" in _run("openmm_alphaprk.benchmarks.pme_tolerance", "--table", str(out)).replace(
        "0.0001", "1e-04"
    )


def test_reporter_cost_runs():
    text = _run(
        "openmm_alphaprk.benchmarks.reporter_cost",
        "--system",
        "water-cluster",
        "--rounds",
        "1",
        "--energy4-steps",
        "2",
        "--rattle-steps",
        "2",
        "--repeats",
        "3",
    )
    assert "| energy4 |" in text and "| rattle |" in text


def test_rescale_sync_cost_runs(tmp_path):
    out = tmp_path / "sync.json"
    args = [
        "--platform",
        "CPU",
        "--box",
        "1.9",
        "--steps",
        "2",
        "--rounds",
        "1",
        "--equilibration-steps",
        "2",
    ]
    _run("openmm_alphaprk.benchmarks.rescale_sync_cost", *args, "--json", str(out))
    (medians,) = json.loads(out.read_text(encoding="utf-8")).values()
    assert set(medians) == {"verlet", "rattle", "energy", "K", "K+moved", "K+P", "K+P+moved"}


def test_make_own_files_builds_its_peptide_without_parmed():
    """The peptide of the generator of tests/data/files/ takes amber14's hydrogens (no ParmEd needed)."""
    import openmm
    import openmm.app as app

    spec = importlib.util.spec_from_file_location("make_own_files", SCRIPTS / "make_own_files.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    topology, positions = module.heavy_topology()
    assert [r.name for r in topology.residues()] == ["ACE", "ALA", "ALA", "ALA", "NME"]
    modeller = app.Modeller(topology, positions)
    modeller.addHydrogens(
        app.ForceField("amber14-all.xml"), platform=openmm.Platform.getPlatformByName("CPU")
    )
    assert modeller.topology.getNumAtoms() == 42  # the 42 peptide atoms of tests/data/files/README.md


@pytest.mark.slow  # ParmEd, which the script converts with, is not a dependency (sdist only: a compile)
def test_make_own_files_runs_where_parmed_is(tmp_path):
    pytest.importorskip("parmed", reason="make_own_files.py converts with ParmEd: pip install parmed")
    _run("make_own_files.py", str(tmp_path), timeout=600)
    assert {"peptide.prmtop", "peptide.psf", "peptide.top", "tip4pew_state.xml"} <= {
        path.name for path in tmp_path.iterdir()
    }


#: A stand-in for python3 in cuda_check.sh: the package's command lines parse what it is given (and
#: make the files it would make), the DHFR script's integrator names are the package's, pytest runs
#: are recorded, a ``-c`` snippet runs.
_STAND_IN = r"""
import json, os, sys
log = os.environ["STAND_IN_LOG"]
args = sys.argv[1:]
def record(entry):
    with open(log, "a", encoding="utf-8") as handle:
        handle.write(json.dumps(entry) + "\n")
def value(flag):
    return args[args.index(flag) + 1]
if args[:2] == ["-m", "pytest"]:
    record({"pytest": args[2:], "platforms": os.environ.get("ALPHAPRK_TEST_PLATFORMS")})
elif args[:3] == ["-m", "openmm_alphaprk", "bench"]:
    name, rest = args[3], args[4:]
    if name == "long":
        from openmm_alphaprk.benchmarks import long
        parser = long._parser()
        long._check_arguments(parser, parser.parse_args(rest))
        os.makedirs(value("--output"), exist_ok=True)
    elif name == "physics":
        from openmm_alphaprk.benchmarks import physics
        from openmm_alphaprk.runs.integrator_names import parse_integrator
        parsed = physics._parser().parse_args(rest)
        [parse_integrator(n) for n in parsed.rows or []]
        os.makedirs(parsed.output, exist_ok=True)
        if parsed.mode == "report":
            with open(os.path.join(parsed.output, "physics.json"), "w", encoding="utf-8") as handle:
                handle.write("{}")
    else:
        from openmm_alphaprk.benchmarks import cost
        cost._parser().parse_args(rest)
        from openmm_alphaprk.runs.integrator_names import parse_integrator
        names = rest[rest.index("--integrators") + 1 : rest.index("--json")]
        [parse_integrator(n) for n in names]
        with open(value("--json"), "w", encoding="utf-8") as handle:
            handle.write("{}")
    record({"bench": name, "args": rest})
elif args[:2] == ["-m", "openmm_alphaprk.benchmarks.dhfr_openmm_settings"]:
    from openmm_alphaprk.runs.integrator_names import parse_integrator
    names = args[args.index("--integrators") + 1 : args.index("--steps")]
    [parse_integrator(n) for n in names]
    record({"dhfr": names, "smooth": "--smooth" in args})
    with open(value("--json"), "w", encoding="utf-8") as handle:
        handle.write("{}")
elif args and args[0].endswith("splitting_survey.py"):
    sys.path.insert(0, os.path.dirname(args[0]))
    import splitting_survey
    parsed = splitting_survey.parser().parse_args(args[1:])
    labels = {label for label, _, _ in splitting_survey.ROWS + splitting_survey.ORDER4_ROWS}
    assert not parsed.rows or set(parsed.rows) <= labels, parsed.rows
    record({"survey": args[1:]})
    with open(value("--json"), "w", encoding="utf-8") as handle:
        handle.write("{}")
elif args[0] == "-c":
    exec(compile(args[1], "-c", "exec"))
else:
    sys.exit(f"unexpected {args}")
"""


def test_cuda_check_runs_its_commands_with_arguments_the_package_accepts(tmp_path):
    """cuda_check.sh with stand-ins for nvidia-smi and python3: the package takes every command it gives."""
    bin_dir, out, log = tmp_path / "bin", tmp_path / "out", tmp_path / "calls.jsonl"
    bin_dir.mkdir()
    (tmp_path / "stand_in.py").write_text(_STAND_IN, encoding="utf-8")
    stand_ins = {
        "nvidia-smi": "#!/bin/sh\necho 'stand-in GPU, 0.0'\n",
        "python3": f'#!/bin/sh\nexec "{sys.executable}" "{tmp_path / "stand_in.py"}" "$@"\n',
    }
    for name, text in stand_ins.items():
        (bin_dir / name).write_text(text, encoding="utf-8")
        (bin_dir / name).chmod(stat.S_IRWXU)
    env = {
        **os.environ,
        "PATH": f"{bin_dir}:{os.environ['PATH']}",
        "OUT": str(out),
        "WORK": str(tmp_path / "work" / "new"),  # a folder the script creates
        "STAND_IN_LOG": str(log),
        "PYTHONPATH": str(ROOT),
        "SURVEYS": "1",
        "PHYSICS": "1",
    }
    result = subprocess.run(
        ["bash", str(SCRIPTS / "cuda_check.sh")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        encoding="utf-8",
        timeout=120,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    calls = [json.loads(line) for line in log.read_text(encoding="utf-8").splitlines()]
    benches = [c["bench"] for c in calls if "bench" in c]
    # the long runs on villin then dhfr, mixed precision, one process; their reports; cost on two
    # boxes and dhfr
    assert benches == ["long"] * 4 + ["cost"] * 3 + ["physics", "physics"]
    stress, physics_report = [c["args"] for c in calls if c.get("bench") == "physics"]
    assert stress[0] == "stress" and stress[stress.index("--precision") + 1] == "mixed"
    assert physics_report[:1] == ["report"] and "--parts" in physics_report
    villin, dhfr, *reports = [c["args"] for c in calls if c.get("bench") == "long"]
    assert all("--report" in report for report in reports) and "--report" not in villin + dhfr
    for long_run, (system, picoseconds) in zip((villin, dhfr), (("villin", "1000"), ("dhfr", "200"))):
        assert long_run[long_run.index("--system") + 1] == system
        assert long_run[long_run.index("--time") + 1] == picoseconds
        assert [
            long_run[long_run.index(flag) + 1] for flag in ("--precision", "--timestep", "--hydrogen-mass")
        ] == [
            "mixed",
            "4",
            "3",
        ]
        assert long_run[long_run.index("--integrators") + 1 :][:3] == [
            "rattle",
            "rattle+rescale",
            "rattle+rescale@10",
        ]
    (tests,) = [c for c in calls if "pytest" in c]
    assert tests["platforms"] == "CUDA:mixed,CUDA:single"
    assert all((ROOT / arg).is_file() for arg in tests["pytest"] if arg.startswith("tests/"))
    rows = ["rattle", "rattle+rescale", "rattle+rescale@10", "rattle+rescale@100", "rattle4+rescale@10"]
    assert [(c["dhfr"], c["smooth"]) for c in calls if "dhfr" in c] == [(rows, False), (rows, True)]
    cost_dhfr = [c["args"] for c in calls if c.get("bench") == "cost"][-1]
    assert cost_dhfr[cost_dhfr.index("--hydrogen-mass") + 1] == "3" and "rattle+rescale@100" in cost_dhfr
    surveys = [c["survey"] for c in calls if "survey" in c]
    assert len(surveys) == 2 and all(s[s.index("--precision") + 1] == "mixed" for s in surveys)
    assert {p.name for p in out.iterdir()} == {"log.txt", "long.tar.gz", "cost.tar.gz", "physics.json"}
    assert "done in" in (out / "log.txt").read_text(encoding="utf-8")


@pytest.mark.parametrize("weight", [1.0, 2 / 3])
def test_the_half_kick_rescaling_holds_u_plus_k_plus_the_half_kicks_kinetic_energy(weight):
    """tools/scripts/half_kick_estimator.py's integrator (docs/physics.md): U + K + w K_a at E_ref every step.

    K_a computed here on its own: the velocities set to ½hF/m and projected by OpenMM's
    ``applyVelocityConstraints`` in a second Context at the same positions.
    """
    import numpy as np
    import openmm as mm

    from openmm_alphaprk.systems import prepare_system

    spec = importlib.util.spec_from_file_location("half_kick_estimator", SCRIPTS / "half_kick_estimator.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    water = prepare_system("water-cluster")
    h = 0.002
    integrator = module.HalfKickRescaleIntegrator(h, half_kick_weight=weight)
    platform = mm.Platform.getPlatformByName("Reference")
    context = mm.Context(water.system, integrator, platform)
    context.setState(water.state)
    e_ref = None
    probe = mm.Context(water.system, mm.VerletIntegrator(h), platform)
    for _ in range(5):
        integrator.step(4)
        state = context.getState(getPositions=True, getForces=True, getEnergy=True)
        masses = np.array(
            [water.system.getParticleMass(i)._value for i in range(water.system.getNumParticles())]
        )
        forces = state.getForces(asNumpy=True)._value
        probe.setPositions(state.getPositions())
        probe.setVelocities(0.5 * h * forces / masses[:, None])
        probe.applyVelocityConstraints(1e-10)
        kick = probe.getState(getVelocities=True).getVelocities(asNumpy=True)._value
        half_kick = 0.5 * float((masses[:, None] * kick**2).sum())  # not the State's: a Verlet time-shift
        held = state.getPotentialEnergy()._value + state.getKineticEnergy()._value + weight * half_kick
        e_ref = integrator.reference_energy._value if e_ref is None else e_ref
        assert abs(held - e_ref) < 1e-6 * abs(e_ref), (held, e_ref)
        assert (
            half_kick > 0 and abs(integrator.getGlobalVariableByName("half_kick_energy") - half_kick) < 1e-6
        )


def test_instruction_cost_takes_the_difference_of_two_counts_per_step(tmp_path):
    """instruction_cost.py with a stand-in valgrind: (count after warm + steps − after warm) / steps.

    The stand-in prints callgrind's line "Collected : N" for a start-up of 5e8 instructions
    plus 3e7 per step (RATTLE) or 3.3e7 (the other row); the script must cancel the start-up
    and give the second row 1.1× the first's instructions per step.
    """
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    valgrind = bin_dir / "valgrind"
    valgrind.write_text(
        "#!/bin/sh\n"
        "name=$(eval echo \\${$(($# - 2))}); steps=$(eval echo \\${$(($# - 1))})\n"
        'per=30000000; [ "$name" = rattle ] || per=33000000\n'
        'echo "==1== Collected : $((500000000 + steps * per))" >&2\n',
        encoding="utf-8",
    )
    valgrind.chmod(stat.S_IRWXU)
    out = tmp_path / "out.json"
    result = subprocess.run(
        [sys.executable, str(SCRIPTS / "instruction_cost.py"), "--integrators", "rattle", "rattle+rescale@10"]
        + ["--steps", "200", "--warm", "20", "--json", str(out), "--note", "stand-in"],
        env={**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}"},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    data = json.loads(out.read_text(encoding="utf-8"))
    rattle, interval = data["rows"]
    assert (rattle["integrator"], interval["integrator"]) == ("rattle", "rattle+rescale@10")
    assert rattle["instructions_per_step"] == 30000000 and rattle["ratio"] == 1.0
    assert interval["ratio"] == pytest.approx(1.1, rel=1e-12)
    assert data["note"] == "stand-in" and "1.1000" in result.stdout
