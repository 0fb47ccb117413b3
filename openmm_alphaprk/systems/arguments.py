"""Command-line options of a system given as files, shared by ``run``, ``compare`` and the benchmarks.

The library side (:class:`~openmm_alphaprk.systems.files.FileOptions` and the readers) is
:mod:`openmm_alphaprk.systems.files`; this module only spells its options for argparse.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .._units import parse_time
from .definitions import DEFINITIONS_DIR, DefinitionError, SystemDefinition, list_systems, load_definition
from .files import CONSTRAINT_CHOICES, FileOptions, file_definition, is_system_file, velocities_file


def add_file_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of :class:`FileOptions` to a command that takes a system name or file.

    An option the command already has (a benchmark's ``--cutoff`` or ``--seed``) is
    left as it is and serves the files too.
    """
    group = parser.add_argument_group(
        "a system given as files (.prmtop/.parm7, .psf, .top, .pdb/.cif, .xml) instead of a name"
    )
    existing = set(parser._option_string_actions)

    def option(name: str, **kwargs) -> None:
        if name not in existing:
            group.add_argument(name, **kwargs)

    option(
        "--coordinates",
        help="coordinates (.inpcrd/.rst7/.ncrst, .crd, .gro, .pdb); "
        "default: the topology's stem with such an extension",
    )
    option(
        "--params", nargs="+", default=(), metavar="FILE", help="CHARMM parameter files (.prm, .rtf, .str)"
    )
    option(
        "--forcefield",
        nargs="+",
        default=(),
        metavar="XML",
        help="force-field XMLs for a PDB/PDBx file, e.g. amber14-all.xml amber14/tip3p.xml",
    )
    option("--include-dir", help="GROMACS include directory of the force-field files")
    option("--state", help="serialized openmm.State (positions, box, velocities) for a System .xml")
    option("--topology", help="PDB topology of a System .xml (for trajectories and analysis)")
    option(
        "--box",
        nargs=3,
        type=float,
        metavar=("A", "B", "C"),
        help="box edges in nm where the coordinates have none",
    )
    option(
        "--constraints",
        choices=sorted(CONSTRAINT_CHOICES),
        default=FileOptions.constraints,
        help="constraints where a reader creates the System (default HBonds, with rigid water)",
    )
    option(
        "--hydrogen-mass",
        type=float,
        metavar="AMU",
        help="hydrogen mass repartitioning (e.g. 3 for a 4 fs step), total mass kept; with a named "
        "solute (villin, dhfr) its start is equilibrated again with the new masses",
    )
    option(
        "--as-is",
        action="store_true",
        help="keep the System as the files make it (no LJ switch, Ewald tolerance, removals)",
    )
    option(
        "--temperature",
        type=float,
        default=None,
        help=f"K: velocities drawn where the files have none (default {FileOptions.temperature_K:g}); "
        "refused where the start's velocities come from the files",
    )
    option(
        "--seed", type=int, default=FileOptions.seed, help="seed of the drawn velocities and equilibration"
    )
    option(
        "--equilibrate",
        default=None,
        metavar="TIME",
        help="a seeded Langevin equilibration first, with a unit: 10ps (cached)",
    )
    option(
        "--cutoff",
        type=float,
        default=FileOptions.cutoff_nm,
        help=f"PME cutoff in nm (default {FileOptions.cutoff_nm:g})",
    )


def file_options(args: argparse.Namespace) -> FileOptions:
    """Return the :class:`FileOptions` of parsed :func:`add_file_arguments` options."""
    equilibrate = 0.0
    if args.equilibrate:
        equilibrate = parse_time(args.equilibrate, "--equilibrate")
    return FileOptions(
        coordinates=args.coordinates,
        params=tuple(args.params),
        forcefield=tuple(args.forcefield),
        include_dir=args.include_dir,
        state=args.state,
        topology=args.topology,
        box_nm=_box(args),
        constraints=args.constraints,
        hydrogen_mass_amu=args.hydrogen_mass,
        as_is=args.as_is,
        temperature_K=FileOptions.temperature_K if args.temperature is None else args.temperature,
        seed=getattr(args, "seed", FileOptions.seed),
        equilibrate_ps=equilibrate,
        cutoff_nm=getattr(args, "cutoff", FileOptions.cutoff_nm),
    )


def unknown_systems(names: list[str]) -> list[str]:
    """Return the names that are neither a known system, a ``.toml`` definition nor a system file."""
    known = set(list_systems())
    return [n for n in names if n not in known and not n.endswith(".toml") and not is_system_file(n)]


def system_to_prepare(name: str, args: argparse.Namespace) -> str | SystemDefinition:
    """Return what ``prepare_system`` takes for ``name``: the name, or the definition of its files.

    A named solute with ``--hydrogen-mass`` becomes its definition with the hydrogens
    repartitioned (:meth:`~.definitions.SystemDefinition.with_hydrogen_mass`), whose start is
    equilibrated again with the new masses and cached under its own key.

    Raises
    ------
    DefinitionError
        For ``--temperature`` where no velocities are drawn at it (:func:`check_temperature`).
    """
    if is_system_file(name):
        system = file_definition(name, file_options(args))
        check_temperature(system, args)
        return system
    check_temperature(name, args)  # a named system: its start's velocities are its definition's
    if getattr(args, "hydrogen_mass", None) is not None:
        return load_definition(name).with_hydrogen_mass(args.hydrogen_mass)
    return name


def check_temperature(system: str | SystemDefinition, args: argparse.Namespace) -> None:
    """Refuse a ``--temperature`` that would be ignored: the start's velocities are not drawn at it.

    A named system starts from its equilibrated state, velocities included; files that
    carry velocities (an AMBER restart, a serialized State) start from those unless
    ``--equilibrate`` draws new ones. Without ``--temperature`` nothing is checked.

    Raises
    ------
    DefinitionError
        Naming where the velocities come from and how to start at the temperature given.
    """
    kelvin = getattr(args, "temperature", None)
    if kelvin is None:
        return
    if not isinstance(system, SystemDefinition):
        definition = load_definition(system)
        toml = Path(system) if str(system).endswith(".toml") else DEFINITIONS_DIR / f"{system}.toml"
        raise DefinitionError(
            f"--temperature {kelvin:g} K does not apply to {system!r}: a named system starts from the state "
            f"its definition makes (equilibration.temperature_K = "
            f"{definition.equilibration['temperature_K']:g} K), velocities included; --temperature sets "
            "the velocities drawn for a system given as files that carry none. Leave --temperature out, "
            f"or run a copy of {toml} with another equilibration.temperature_K (its start is built and "
            "cached at that temperature)."
        )
    if getattr(args, "equilibrate", None):
        return  # velocities drawn at the temperature, then equilibrated at it
    carrier = velocities_file(system)
    if carrier is not None:
        other = "--state STATE.xml" if system.build["kind"] == "openmm_xml" else "--coordinates FILE.inpcrd"
        raise DefinitionError(
            f"--temperature {kelvin:g} K would be ignored: {Path(carrier).name} carries velocities and the "
            f"run starts from them. Leave --temperature out to start from them, or draw new velocities at "
            f"{kelvin:g} K: add --equilibrate TIME (e.g. --equilibrate 10ps; minimized, then Langevin "
            f"dynamics at {kelvin:g} K), or give {other} without velocities."
        )


def given_file_options(args: argparse.Namespace) -> list[str]:
    """Return the file options given on a command line (to refuse them with a system name)."""
    defaults = FileOptions()
    given = []
    for option, value, default in (
        ("--coordinates", args.coordinates, None),
        ("--params", tuple(args.params), ()),
        ("--forcefield", tuple(args.forcefield), ()),
        ("--include-dir", args.include_dir, None),
        ("--state", args.state, None),
        ("--topology", args.topology, None),
        ("--box", _box(args), None),
        ("--constraints", args.constraints, defaults.constraints),
        ("--hydrogen-mass", args.hydrogen_mass, None),
        ("--as-is", args.as_is, False),
        ("--equilibrate", args.equilibrate, None),
    ):
        if value not in (default, None, ()):
            given.append(option)
    return given


def _box(args: argparse.Namespace) -> tuple[float, float, float] | None:
    """Return the edges of ``--box A B C``; None without (or where ``--box`` is a water box's edge)."""
    box = getattr(args, "box", None)
    return tuple(box) if isinstance(box, (list, tuple)) else None
