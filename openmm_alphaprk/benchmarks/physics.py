"""Does holding the energy bend the physics? NVE segments and a long stress run, against RATTLE.

Two kinds of runs, each a run directory of :func:`~openmm_alphaprk.runs.run_nve` with
positions and velocities in ``trajectory.trr`` (so results are written as they go and
the same command resumes an interrupted run):

``segments``
    ``--starts`` independent states, each drawn by ``--spacing`` ps of Langevin dynamics
    (OpenMM's ``LangevinMiddleIntegrator`` at the system's temperature, 1/ps, 2 fs) from
    the one before, the first from the system's equilibrated start
    (``OUTPUT/starts/start_<i>.xml``); from each, ``--length`` ps of NVE of every row
    (``OUTPUT/segments/<integrator>@<h>fs/start_<i>/``). Each figure of a setting (a
    partition temperature, D, a g(r) peak) then has an error bar from the spread over
    the independent segments, and rows from one start share E_ref.
``stress``
    ``--time`` ps of every rescaled row and RATTLE from the system's start at one step
    (``OUTPUT/stress/<integrator>@<h>fs/``), for the partition temperatures against time
    (a "flying ice cube" would open a growing gap).
``order``
    ``--length`` ps of every row at each of ``--timesteps`` from the system's start
    (``OUTPUT/order/<integrator>@<h>fs/``), for the order of the fluctuations of H and
    the power of h the scaling shrinks with.

``report`` reads every finished run directory of the three and writes ``OUTPUT/physics.json``:
``alphaprk validate`` (:func:`~openmm_alphaprk.workflows.validate.validate`) of the segments
against RATTLE at the smallest step and of the order runs;
:func:`~openmm_alphaprk.workflows.transport.transport_of_runs` of the segments; per setting
the mean O–O g(r) and oxygen MSD over its segments (for figures); and per stress row the
partition temperatures over consecutive windows
(:class:`~openmm_alphaprk.analysis.Equipartition`). The command is ``alphaprk bench physics``
(:func:`main`); ``--help`` lists its options.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import openmm as mm
import openmm.unit as unit

from ..runs import RunOptions, run_nve
from ..systems import PreparedSystem, load_definition, prepare_system
from ..systems.build import FINAL_CONSTRAINT_TOLERANCE
from .long import one_evaluation

#: Rows of the segments at each step (fs): the rescaled rows, RATTLE and the explicit splitting.
SEGMENT_ROWS = ("rattle", "rattle+rescale", "rattle+rescale@10", "rattle4+rescale", "split-me")
#: The unscaled small-step references: RATTLE at these steps (fs); the smallest is the reference.
REFERENCE_STEPS_FS = (1.0, 0.5)
#: Rows of the stress run.
STRESS_ROWS = ("rattle", "rattle+rescale", "rattle+rescale@10", "rattle4+rescale")
#: Rows of the order runs: second order (RATTLE, the splitting), fourth (Suzuki's composition), rescaled.
ORDER_ROWS = ("rattle", "split-me", "alpha4=0", "rattle+rescale", "rattle4+rescale")
#: Simulated time between frames of trajectory.trr and trajectory.dcd (ps), the same at every step.
FRAME_SPACING_PS = 0.02


def setting_folder(integrator: str, timestep_fs: float) -> str:
    """Folder name of a setting: ``rattle+rescale@10@2fs``."""
    return f"{integrator}@{timestep_fs:g}fs"


def nvt_starts(
    prepared: PreparedSystem, count: int, spacing_ps: float, seed: int, folder: Path, platform: str
) -> list[PreparedSystem]:
    """Return ``count`` starts, each ``spacing_ps`` of Langevin dynamics after the one before.

    Written to ``folder/start_<i>.xml`` as they are made and read from there when present.
    Each start's positions and velocities are projected onto the constraints (as the systems'
    own starts are; a start read from a file written before, too): LangevinMiddleIntegrator's
    velocities keep components along the constraints (about 2 kJ/mol of kinetic energy on
    tip3p-2nm) which RATTLE's first step removes and a rescaled row would hold in its E_ref.
    Each start keeps the system's name (its segments are one setting) and gets its own key
    (``<key>-nvt<i>``), so its run directories are told apart.
    """
    folder.mkdir(parents=True, exist_ok=True)
    temperature = prepared.definition.equilibration.get("temperature_K", 300.0)
    integrator = mm.LangevinMiddleIntegrator(temperature * unit.kelvin, 1 / unit.picosecond, 0.002)
    integrator.setRandomNumberSeed(seed)
    context = mm.Context(prepared.system, integrator, mm.Platform.getPlatformByName(platform))
    starts, state = [], prepared.state
    for i in range(count):
        path = folder / f"start_{i}.xml"
        if path.is_file():
            context.setState(mm.XmlSerializer.deserialize(path.read_text(encoding="utf-8")))
        else:
            context.setState(state)
            integrator.step(round(spacing_ps / 0.002))
        context.applyConstraints(FINAL_CONSTRAINT_TOLERANCE)
        context.applyVelocityConstraints(FINAL_CONSTRAINT_TOLERANCE)
        state = context.getState(getPositions=True, getVelocities=True, enforcePeriodicBox=False)
        if not path.is_file():
            path.write_text(mm.XmlSerializer.serialize(state), encoding="utf-8")
        starts.append(replace(prepared, state=state, key=f"{prepared.key}-nvt{i}", source="built"))
    return starts


def _options(timestep_fs: float, time_ps: float, args: argparse.Namespace) -> RunOptions:
    timestep_ps = timestep_fs / 1000
    frames = max(1, round(FRAME_SPACING_PS / timestep_ps))
    return RunOptions(
        steps=round(time_ps / timestep_ps),
        timestep=timestep_ps,
        platform=args.platform,
        precision=args.precision,
        energy_interval=frames * args.energy_every,
        trajectory_interval=frames * args.position_every,
        velocity_interval=frames * args.velocity_every,
        checkpoint_interval=frames * 500,
        cpu_threads=args.threads,
        progress=not args.no_progress,
    )


def run_segments(prepared: PreparedSystem, args: argparse.Namespace, output: Path) -> None:
    """Every row at every ``--timesteps`` and the references, ``--length`` ps from each start."""
    starts = nvt_starts(prepared, args.starts, args.spacing, args.seed, output / "starts", args.platform)
    settings = [("rattle", h) for h in REFERENCE_STEPS_FS]
    settings += [(name, h) for h in args.timesteps for name in args.rows]
    for i, start in enumerate(starts):
        for name, h in settings:
            run = output / "segments" / setting_folder(name, h) / f"start_{i}"
            run_nve(start, name, run, _options(h, args.length, args))


def run_stress(prepared: PreparedSystem, args: argparse.Namespace, output: Path) -> None:
    """Every stress row from the system's start: ``--time`` ps, ``--time-multi`` for multi-evaluation rows."""
    for name in args.rows:
        time_ps = args.time if one_evaluation(name) else args.time_multi
        h = args.timesteps[0]
        run_nve(prepared, name, output / "stress" / setting_folder(name, h), _options(h, time_ps, args))


def run_order(prepared: PreparedSystem, args: argparse.Namespace, output: Path) -> None:
    """Every row at every ``--timesteps`` for ``--length`` ps from the system's start."""
    for name in args.rows:
        for h in args.timesteps:
            run_nve(
                prepared, name, output / "order" / setting_folder(name, h), _options(h, args.length, args)
            )


def finished_runs(folder: Path) -> list[Path]:
    """Run directories under ``folder`` whose run is complete (``summary.json`` written), sorted."""
    return sorted(path.parent for path in folder.glob("**/summary.json"))


def report(args: argparse.Namespace, output: Path) -> dict:
    """Analyse what the runs in ``output`` wrote; return the data of ``physics.json``."""
    from ..workflows.transport import transport_of_runs
    from ..workflows.validate import validate

    path = output / "physics.json"
    data: dict = {"system": None, "frame_spacing_ps": FRAME_SPACING_PS, "arguments": {}}
    if path.is_file():  # what an earlier report found, its parts replaced by those asked for
        data = json.loads(path.read_text(encoding="utf-8"))
    for mode in ("segments", "stress", "order"):
        arguments = output / f"{mode}_arguments.json"
        if arguments.is_file():
            data["arguments"][mode] = json.loads(arguments.read_text(encoding="utf-8"))
    segments = finished_runs(output / "segments") if "segments" in args.parts else []
    if segments:
        reference = [
            run for run in segments if run.parent.name == setting_folder("rattle", min(REFERENCE_STEPS_FS))
        ]
        validation = validate(
            segments, reference=reference or None, workers=args.workers, progress=not args.no_progress
        )
        data["system"] = validation.system
        data["segments"] = validation.as_dict()
        data["transport"] = transport_of_runs(segments, progress=not args.no_progress).as_dict()
        data["curves"] = _curves(segments)
        data["paired"] = paired_means(segments, setting_folder("rattle", min(REFERENCE_STEPS_FS)))
    order = finished_runs(output / "order") if "order" in args.parts else []
    if order:
        data["order"] = validate(order, workers=args.workers, progress=not args.no_progress).as_dict()
        data["system"] = data["system"] or data["order"]["system"]
    # a stress run still going (or stopped) is read as far as it got, and marked so
    stress = (
        sorted(path.parent for path in (output / "stress").glob("*/trajectory.trr"))
        if "stress" in args.parts
        else []
    )
    if stress:
        data["stress"] = {run.name: _windows(run, args.windows, args.workers) for run in stress}
        data["system"] = (
            data["system"] or json.loads((stress[0] / "run.json").read_text(encoding="utf-8"))["system"]
        )
    return data


def paired_means(runs: list[Path], reference: str) -> dict:
    """Mean temperature and potential energy of each setting against the reference's, start by start.

    Segments of one start share the start state and so E_ref: the difference of their means
    (``energies.csv``, the rows after the start) to the reference's is free of the spread
    between starts. Per setting folder: mean ± standard error over starts of ΔT (K) and ΔU
    (kJ/mol), and each start's own means.
    """
    import numpy as np

    from ..runs import read_energies, rundir

    means: dict[str, dict[str, tuple[float, float]]] = {}
    for run in runs:
        rows = read_energies(run / rundir.ENERGIES_FILE)[1:]
        means.setdefault(run.parent.name, {})[run.name] = (float(rows[:, 5].mean()), float(rows[:, 2].mean()))
    base = means.get(reference, {})
    paired = {}
    for name, starts in means.items():
        shared = sorted(set(starts) & set(base))
        if len(shared) < 2:
            continue
        d = np.array([[starts[k][0] - base[k][0], starts[k][1] - base[k][1]] for k in shared])
        error = d.std(axis=0, ddof=1) / np.sqrt(len(shared))
        paired[name] = {
            "starts": shared,
            "temperature_difference_K": [float(d[:, 0].mean()), float(error[0])],
            "potential_difference_kJ_per_mol": [float(d[:, 1].mean()), float(error[1])],
            "temperature_K": [starts[k][0] for k in shared],
            "potential_kJ_per_mol": [starts[k][1] for k in shared],
        }
    return paired


def _curves(runs: list[Path]) -> dict:
    """Per setting folder: the mean O–O g(r) (where the runs have a periodic box) and oxygen MSD."""
    import numpy as np

    from ..analysis import WATER_OXYGENS, Diffusion, oxygen_rdf
    from ..runs import rundir

    settings: dict[str, list[Path]] = {}
    for run in runs:
        settings.setdefault(run.parent.name, []).append(run)
    curves = {}
    for name, group in settings.items():
        rdfs, msds = [], []
        for run in group:
            universe = rundir.open_universe(run)
            if universe.dimensions is not None:  # a cluster in vacuum has no volume for a g(r)
                rdf = oxygen_rdf(universe)
                rdfs.append(rdf.results.rdf)
            msd = Diffusion(universe, select=WATER_OXYGENS).run()
            msds.append(msd.results.timeseries)
        length = min(len(m) for m in msds)
        curves[name] = {
            "lag_ps": msd.results.delta_t_values[:length].tolist(),
            "msd_angstrom2": np.mean([m[:length] for m in msds], axis=0).tolist(),
        }
        if rdfs:
            curves[name].update(r_angstrom=rdf.results.bins.tolist(), g=np.mean(rdfs, axis=0).tolist())
    return curves


def _windows(run: Path, count: int, workers: int = 1) -> dict:
    """Partition temperatures (K) of a stress run over ``count`` consecutive windows of its frames."""
    from ..analysis import Equipartition
    from ..runs import rundir

    system = mm.XmlSerializer.deserialize((run / rundir.SYSTEM_FILE).read_text(encoding="utf-8"))
    universe = rundir.open_universe(run, rundir.TRR_FILE)
    frames = universe.trajectory.n_frames
    edges = [round(i * frames / count) for i in range(count + 1)]
    windows = []
    for start, stop in zip(edges[:-1], edges[1:]):
        parallel = {"backend": "multiprocessing", "n_workers": workers} if workers > 1 else {}
        check = Equipartition.from_system(universe, system).run(start=start, stop=stop, **parallel)
        universe.trajectory[stop - 1]
        windows.append(
            {"end_ps": float(universe.trajectory.time), "temperatures": check.results.temperatures}
        )
    result = {"frames": frames, "complete": (run / rundir.SUMMARY_FILE).is_file(), "windows": windows}
    if result["complete"]:
        summary = json.loads((run / rundir.SUMMARY_FILE).read_text(encoding="utf-8"))
        keys = (
            "simulated_ps",
            "degrees_of_freedom",
            "drift_per_dof",
            "drift_per_dof_standard_error",
            "rescaling",
        )
        result["summary"] = {key: summary[key] for key in keys}
    return result


def _prepared(args: argparse.Namespace) -> PreparedSystem:
    definition = load_definition(args.system)
    if args.hydrogen_mass is not None:
        definition = definition.with_hydrogen_mass(args.hydrogen_mass)
    return prepare_system(definition)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="alphaprk bench physics",
        description="NVE segments from independent NVT starts and a long stress run, with positions "
        "and velocities saved, for `alphaprk validate` and the transport analyses.",
    )
    parser.add_argument(
        "mode", choices=("segments", "stress", "order", "report"), help="which runs, or report"
    )
    parser.add_argument("--system", default="tip3p-2nm", help="system name (default tip3p-2nm)")
    parser.add_argument("--hydrogen-mass", type=float, default=None, help="hydrogen mass (amu) of a solute")
    parser.add_argument("--rows", nargs="+", default=None, help="integrator names (default: the mode's)")
    parser.add_argument("--timesteps", nargs="+", type=float, default=[2.0, 4.0], help="steps in fs")
    parser.add_argument("--starts", type=int, default=4, help="segments: independent starts (default 4)")
    parser.add_argument("--spacing", type=float, default=5.0, help="segments: ps of NVT between starts")
    parser.add_argument("--seed", type=int, default=2026, help="segments: Langevin seed")
    parser.add_argument("--length", type=float, default=10.0, help="segments: ps of NVE each (default 10)")
    parser.add_argument("--time", type=float, default=500.0, help="stress: ps of the one-evaluation rows")
    parser.add_argument("--time-multi", type=float, default=100.0, help="stress: ps of the compositions")
    parser.add_argument("--energy-every", type=int, default=1, help="energies.csv row every this many frames")
    parser.add_argument("--velocity-every", type=int, default=1, help="TRR frame every this many frames")
    parser.add_argument("--position-every", type=int, default=5, help="DCD frame every this many frames")
    parser.add_argument("--platform", default="CPU", help="OpenMM platform (default CPU)")
    parser.add_argument(
        "--precision", default=None, help="precision on CUDA/OpenCL/HIP (default: the platform's)"
    )
    parser.add_argument("--threads", type=int, default=None, help="CPU threads per run")
    parser.add_argument("--output", default="alphaprk-physics", help="output folder")
    parser.add_argument("--windows", type=int, default=10, help="report: windows of each stress run")
    parser.add_argument("--workers", type=int, default=1, help="report: processes reading the trajectories")
    parser.add_argument(
        "--parts",
        nargs="+",
        choices=("segments", "order", "stress"),
        default=["segments", "order", "stress"],
        help="report: which runs to analyse again (the others are kept from OUTPUT/physics.json)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    output = Path(args.output)
    if args.mode == "report":
        path = output / "physics.json"
        path.write_text(json.dumps(report(args, output), indent=1) + "\n", encoding="utf-8")
        print(f"written: {path}", file=sys.stderr)
        return 0
    if args.rows is None:
        args.rows = list({"segments": SEGMENT_ROWS, "stress": STRESS_ROWS, "order": ORDER_ROWS}[args.mode])
    output.mkdir(parents=True, exist_ok=True)
    prepared = _prepared(args)
    (output / f"{args.mode}_arguments.json").write_text(
        json.dumps(vars(args), indent=2) + "\n", encoding="utf-8"
    )
    {"segments": run_segments, "stress": run_stress, "order": run_order}[args.mode](prepared, args, output)
    print(f"{args.mode} of {prepared.name} in {output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
