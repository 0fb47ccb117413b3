"""The commands of ``alphaprk``: each turns its arguments into a library call and prints the result."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .._units import InputError, QuantityError, parse_length, parse_time
from ..observables import drift_text
from ..runs.integrator_names import parse_integrator
from ..runs.options import DEFAULTS, RunOptions
from .parser import BENCHMARKS


def _steps(args, default_steps: int = DEFAULTS.steps) -> tuple[int, float]:
    timestep = parse_time(args.timestep, "--timestep")
    if args.length is not None:
        steps = round(parse_time(args.length, "--length") / timestep)
        if steps < 1:
            raise QuantityError(f"--length {args.length} is shorter than one step of {args.timestep}.")
        return steps, timestep
    return (args.steps or default_steps), timestep


def _resolve_platform(args) -> None:
    """Replace ``--platform auto`` by the fastest platform present; keep why in ``args.platform_reason``."""
    from ..platforms import AUTO, fastest_platform

    args.platform_reason = None
    if args.platform == AUTO:
        args.platform, args.platform_reason = fastest_platform()


def _platform_line(args) -> str:
    """Return the line that says which platform ``--platform auto`` chose and why ("" if it was given)."""
    return f"\nplatform {args.platform_reason}; --platform chooses another" if args.platform_reason else ""


def _run_options(args, default_steps: int = DEFAULTS.steps) -> RunOptions:
    """Return the :class:`~openmm_alphaprk.runs.RunOptions` of ``run`` and ``compare``."""
    _resolve_platform(args)
    steps, timestep = _steps(args, default_steps)
    return RunOptions(
        steps=steps,
        timestep=timestep,
        platform=args.platform,
        precision=args.precision,
        constraint_tolerance=args.constraint_tolerance,
        energy_interval=args.energy_interval,
        trajectory_interval=args.trajectory_interval,
        velocity_interval=args.velocity_interval,
        checkpoint_interval=args.checkpoint_interval,
        controller_interval=args.controller_interval,
        checkpoint_seconds=args.checkpoint_seconds,
        cache_dir=args.cache_dir,
        progress=not args.quiet,
    )


def cmd_systems(args) -> int:
    from ..systems import find_shipped_state, is_cached, list_systems, load_definition

    if args.rebuild and not args.build:
        raise InputError("--rebuild needs the systems to build: alphaprk systems --build NAME ... --rebuild")
    if args.build:
        for name in args.build:
            _print_prepared(_prepare(name, args, rebuild=args.rebuild))
        return 0
    print(f"{'system':<14} {'start':<9} description")
    for name in list_systems():
        definition = load_definition(name)
        if find_shipped_state(definition) is not None:
            start = "shipped"
        else:
            start = "cached" if is_cached(definition, args.cache_dir) else "to build"
        print(f"{name:<14} {start:<9} {definition.description}")
    return 0


def _prepare(name: str, args, rebuild: bool, specs=()):
    """Return ``prepare_system(name)`` with the CLI's cache and progress, checked against ``specs``."""
    from ..runs.integrator_names import check_compatible
    from ..systems import prepare_system

    platform = getattr(args, "platform", "CPU")
    label = repr(str(getattr(args, "system", name)))
    return prepare_system(
        name,
        cache_dir=args.cache_dir,
        rebuild=rebuild,
        progress=not args.quiet,
        check=lambda system: [check_compatible(spec, system, label, platform) for spec in specs],
    )


def _print_prepared(prepared) -> None:
    if prepared.source == "shipped":
        print(
            f"{prepared.name}: {prepared.n_atoms} atoms, shipped start state {prepared.path} "
            "(--rebuild builds it here)"
        )
    else:
        print(f"{prepared.name}: {prepared.n_atoms} atoms, cached in {prepared.path}")


def _system(args, specs) -> tuple[str, object]:
    """Return the system's short name and what ``run_nve``/``compare`` take: a name, or the prepared files.

    A system given as files is read and made ready for NVE here; what changed is printed.
    """
    from ..systems.arguments import check_temperature, given_file_options, system_to_prepare
    from ..systems.files import is_system_file

    if not is_system_file(args.system):
        given = [option for option in given_file_options(args) if option != "--hydrogen-mass"]
        if given:
            raise InputError(
                f"{' '.join(given)} apply to a system given as files (.prmtop, .psf, .top, .pdb, .cif, "
                f".xml), not to {args.system!r}."
            )
        check_temperature(args.system, args)
        if args.hydrogen_mass is not None:  # the named solute, repartitioned and equilibrated again
            prepared = _prepare(system_to_prepare(args.system, args), args, rebuild=args.rebuild, specs=specs)
            return prepared.name, prepared
        system = _prepare(args.system, args, rebuild=True, specs=specs) if args.rebuild else args.system
        return str(args.system).removesuffix(".toml").rpartition("/")[2], system
    definition = system_to_prepare(args.system, args)
    prepared = _prepare(definition, args, rebuild=args.rebuild, specs=specs)
    print(_changes_text(prepared, args.as_is))
    return prepared.name, prepared


def _changes_text(prepared, as_is: bool) -> str:
    """Say what was changed to make a user's files ready for NVE (or that nothing was)."""
    head = f"{prepared.name}: {prepared.n_atoms} atoms from {prepared.definition.build['files']['system']}"
    if as_is:
        return head + "; the System as the files make it (--as-is)"
    if not prepared.changes:
        return head + "; ready for NVE as read (nothing changed)"
    lines = [head + "; made ready for NVE (--as-is keeps the System untouched):"]
    return "\n".join(lines + [f"  - {change}" for change in prepared.changes])


def cmd_run(args) -> int:
    from ..runs import run_nve
    from ..runs.rundir import SUMMARY_FILE
    from ..workflows.comparison import format_comparison_table, run_directory_name

    spec = parse_integrator(args.integrator)
    options = _run_options(args)
    name, system = _system(args, [spec])
    output = args.output or f"alphaprk-run-{name}-{run_directory_name(spec)}"
    summary = run_nve(system, spec, output, options)
    if args.json:
        print(json.dumps(summary.as_dict(), indent=2))
        print(f"run directory: {output}", file=sys.stderr)
        return 0
    print(
        format_comparison_table([summary], _run_header(summary), verlet_note=spec.kind == "verlet")
        + _platform_line(args)
    )
    print(f"\nrun directory: {output}, summary: {Path(output) / SUMMARY_FILE}")
    return 0


def _run_header(summary) -> str:
    """Return the title line of ``run``'s table: system, step, length, platform, energy samples."""
    s = summary
    return (
        f"{s.system}: {s.n_atoms} atoms, {s.degrees_of_freedom} DOF, {s.timestep_fs:g} fs, {s.steps} steps "
        f"({s.simulated_ps:g} ps) NVE, platform {s.platform}; H - E_ref from {s.energy_samples} energy rows"
    )


def cmd_compare(args) -> int:
    from ..workflows.comparison import FULL_COMPARISON, MAIN_JOB, compare

    preset = FULL_COMPARISON if args.full else MAIN_JOB
    args.system = args.system or preset.system
    args.integrators = args.integrators or list(preset.integrators)
    specs = [parse_integrator(name) for name in args.integrators]
    options = _run_options(args, preset.steps)
    if args.accuracy_steps < 0:
        raise InputError(
            f"--accuracy-steps must be 0 (none) or a positive number of steps, got {args.accuracy_steps}."
        )
    name, system = _system(args, specs)
    output = args.output or f"alphaprk-compare-{name}"
    result = compare(
        system,
        args.integrators,
        output,
        options,
        plot=not args.no_plot,
        equal_cost=not args.no_equal_cost,
        accuracy_steps=args.accuracy_steps,
    )
    print(result.table + _platform_line(args))
    print(
        f"\nresults: {result.output / 'comparison.json'}"
        + (f", figure: {result.figure}" if result.figure else "")
    )
    return 0


def cmd_analyze(args) -> int:
    from ..analysis import WATER_OXYGENS
    from ..workflows.analyze import analyze_run

    rdf_max = parse_length(args.rdf_max, "--rdf-max")
    result = analyze_run(
        args.run,
        select=args.select or WATER_OXYGENS,
        rdf_bins=args.rdf_bins,
        rdf_max=rdf_max,
        plot=not args.no_plot,
        progress=not args.quiet,
    )
    _print_analysis(result)
    print(f"written: {args.run}/analysis.json" + "".join(f", {path}" for path in result["figures"].values()))
    return 0


def _print_analysis(result: dict) -> None:
    """Print one line per analysis of :func:`~openmm_alphaprk.workflows.analyze_run`, then the notes."""
    energy = result["energy"]
    drift = drift_text(energy["drift_per_dof"], energy["drift_per_dof_standard_error"], "kJ/mol/ns")
    print(
        f"energy: E_ref (total energy of the start state) {energy['e_ref']:.6g} kJ/mol; drift/DOF {drift}; "
        f"RMS |H - E_ref| {energy['rms_residual']:.3g} kJ/mol, max {energy['max_abs_residual']:.3g} kJ/mol "
        f"({energy['samples']} samples over {energy['duration_ps']:g} ps)"
    )
    if "constraints" in result:
        c = result["constraints"]
        print(
            f"constraints: max relative deviation {c['overall_max_relative_deviation']:.2e} "
            f"over {c['frames']} frames"
        )
        final = c.get("run_summary_max_relative_constraint_error")
        value = f" ({final:.2g})" if isinstance(final, float) else ""
        print(
            "  (the DCD stores float32 coordinates in A: ~1e-6 relative is its resolution limit; the run "
            f"summary's constraint error{value} is from the full-precision final state)"
        )
    if "rdf" in result:
        r = result["rdf"]
        print(f"O-O RDF: first peak g = {r['first_peak_g']:.2f} at r = {r['first_peak_r_angstrom']:.2f} A")
    if "msd" in result:
        m = result["msd"]
        first, last = m["fit_window_ps"]
        print(
            f"MSD: D = {m['diffusion_coefficient_1e-5_cm2_per_s']:.3g} "
            f"± {m['diffusion_coefficient_standard_error_1e-5_cm2_per_s']:.2g} x 1e-5 cm^2/s from "
            f"{m['frames']} frames (fit over lags {first:.3g}-{last:.3g} ps); ± = standard error over "
            f"{m['error_groups']} groups of molecules; a short run's D is not converged"
        )
    for note in result["notes"]:
        print(f"note: {note}")


def cmd_validate(args) -> int:
    from ..workflows.validate import validate

    result = validate(
        args.runs, reference=args.reference, seed=args.seed, workers=args.workers, progress=not args.quiet
    )
    print(result.text())
    print(f"written: {result.write(args.output)}")
    return 0


def cmd_sweep(args) -> int:
    from ..workflows.sweep import cell_status, load_config, run_sweep

    config = load_config(args.config)
    if args.list:
        root = Path(args.output) if args.output else config.output
        for cell in config.cells:
            row = cell_status(cell, root / cell.name)
            state = "to run" if row is None else row["status"]
            print(f"{cell.name:60s} {cell.steps:8d} steps  {state}")
        print(f"{len(config.cells)} cells -> {root}")
        return 0
    result = run_sweep(
        config,
        output=args.output,
        scheduler=args.scheduler,
        n_workers=args.workers,
        retry_failed=args.retry_failed,
        cache_dir=args.cache_dir,
        progress=not args.quiet,
    )
    print(
        f"{len(result.rows)} cells: {len(result.ran)} run now, {len(result.skipped)} finished before, "
        f"{len(result.failed)} failed -> {result.table}"
    )
    return 0  # failed cells are results (a step-size scan expects some); they are in the table


def cmd_bench(args: argparse.Namespace) -> int:
    """Run a benchmark's own command line with the remaining options."""
    import importlib

    return importlib.import_module(BENCHMARKS[args.benchmark]).main(args.options)


COMMANDS = {
    "systems": cmd_systems,
    "run": cmd_run,
    "compare": cmd_compare,
    "analyze": cmd_analyze,
    "validate": cmd_validate,
    "sweep": cmd_sweep,
    "bench": cmd_bench,
}
