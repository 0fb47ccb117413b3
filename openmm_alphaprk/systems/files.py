"""A user's own system files: AMBER, CHARMM, GROMACS, PDB/PDBx with force fields, OpenMM XML.

:func:`file_definition` turns a file (recognised by its extension) and
:class:`FileOptions` into a :class:`~.definitions.SystemDefinition` of a file kind, so
that :func:`~.cache.prepare_system` prepares it like the named systems: the same
:class:`~.cache.PreparedSystem`, cached under a key of the definition *and the files'
content*. :func:`load_files` reads the files with OpenMM's own readers
(``AmberPrmtopFile``, ``CharmmPsfFile`` with ``CharmmParameterSet``, ``GromacsTopFile``,
``PDBFile``/``PDBxFile`` with ``ForceField``, ``XmlSerializer``) and, unless the
definition says ``prepare_for_nve = false``, makes the System ready for NVE with
:func:`~openmm_alphaprk.nve.prepare_for_nve`, recording each change.

A definition file (``*.toml``) may name the same kinds::

    [build]
    kind = "amber"
    files = { prmtop = "my.prmtop", coordinates = "my.inpcrd" }   # relative to the .toml
    cutoff_nm = 0.9
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit

from .definitions import DefinitionError, SystemDefinition, parse_definition

#: The file kinds, by the extension of the file that names the system.
SUFFIX_KINDS = {
    ".prmtop": "amber",
    ".parm7": "amber",
    ".psf": "charmm",
    ".top": "gromacs",
    ".pdb": "pdb_files",
    ".cif": "pdb_files",
    ".pdbx": "pdb_files",
    ".xml": "openmm_xml",
}
FILE_KINDS = tuple(sorted(set(SUFFIX_KINDS.values())))
#: Coordinate files looked for beside a topology of the same stem, in this order.
COORDINATE_SUFFIXES = {"amber": (".inpcrd", ".rst7", ".ncrst", ".rst", ".crd"), "gromacs": (".gro",)}
CONSTRAINT_CHOICES = {"HBonds": app.HBonds, "AllBonds": app.AllBonds, "HAngles": app.HAngles, "none": None}
#: Below this mass (amu) a particle bonded to one other is a hydrogen (repartitioned ones included).
HYDROGEN_MASS_LIMIT = 4.5


@dataclass(frozen=True)
class FileOptions:
    """How to read a user's system files and make them ready for NVE (the command line's options).

    Attributes
    ----------
    coordinates
        Coordinate file (AMBER ``.inpcrd``/``.rst7``/``.ncrst``, CHARMM ``.crd``/``.pdb``,
        GROMACS ``.gro``); default: the topology's stem with a known extension.
    params
        CHARMM parameter files (``.prm``, ``.rtf``, ``.str``).
    forcefield
        Force-field XML names for a PDB/PDBx file (e.g. ``amber14-all.xml amber14/tip3p.xml``).
    include_dir
        GROMACS include directory for the force-field files.
    state, topology
        For an OpenMM System XML: a serialized State (positions, box, velocities) and a
        PDB topology (for trajectories and analysis; without it one is made from masses).
    box_nm
        Box edges (nm) where the coordinates have none (e.g. a CHARMM ``.crd``).
    constraints
        ``HBonds`` (default, with rigid water), ``AllBonds``, ``HAngles`` or ``none``.
    hydrogen_mass_amu
        Hydrogen mass repartitioning: hydrogens bonded to heavy atoms get this mass, taken
        from the heavy atom (water's hydrogens are left alone).
    as_is
        Keep the System exactly as the files make it (no :func:`prepare_for_nve`).
    temperature_K, seed
        Velocities drawn where the files have none, and the equilibration's.
    equilibrate_ps
        A seeded Langevin equilibration of the prepared System first (minimized before).
    cutoff_nm
        Nonbonded cutoff of PME where a reader creates the System.
    """

    coordinates: str | None = None
    params: tuple[str, ...] = ()
    forcefield: tuple[str, ...] = ()
    include_dir: str | None = None
    state: str | None = None
    topology: str | None = None
    box_nm: tuple[float, float, float] | None = None
    constraints: str = "HBonds"
    hydrogen_mass_amu: float | None = None
    as_is: bool = False
    temperature_K: float = 300.0
    seed: int = 2024
    equilibrate_ps: float = 0.0
    cutoff_nm: float = 0.9


def is_system_file(name: str | Path) -> bool:
    """Tell whether ``name`` names a system by a file of a known extension (not a ``.toml`` definition)."""
    return Path(name).suffix.lower() in SUFFIX_KINDS


def file_definition(path: str | Path, options: FileOptions | None = None) -> SystemDefinition:
    """Return the definition of the system in ``path`` (kind by extension) read with ``options``.

    Raises
    ------
    DefinitionError
        For a missing file, a missing companion file (coordinates, parameters, force
        field, state) or an option the format does not take, naming the fix.
    """
    options = options or FileOptions()
    path = Path(path)
    kind = SUFFIX_KINDS.get(path.suffix.lower())
    if kind is None:
        raise DefinitionError(
            f"{path}: unknown system file extension {path.suffix!r}; give one of {sorted(SUFFIX_KINDS)} "
            "or a .toml definition"
        )
    files: dict[str, Any] = {"system": str(path)}
    if options.coordinates:
        files["coordinates"] = options.coordinates
    elif kind in COORDINATE_SUFFIXES:
        found = _same_stem(path, COORDINATE_SUFFIXES[kind])
        if found is not None:
            files["coordinates"] = str(found)
    if options.params:
        files["params"] = list(options.params)
    if options.state:
        files["state"] = options.state
    if options.topology:
        files["topology"] = options.topology
    if options.include_dir:
        files["include_dir"] = options.include_dir
    build: dict[str, Any] = {
        "kind": kind,
        "files": files,
        "forcefield": list(options.forcefield),
        "cutoff_nm": float(options.cutoff_nm),
        "constraints": options.constraints,
        "prepare_for_nve": not options.as_is,
    }
    if options.box_nm is not None:
        build["box_nm"] = [float(edge) for edge in options.box_nm]
    if options.hydrogen_mass_amu is not None:
        build["hydrogen_mass_amu"] = float(options.hydrogen_mass_amu)
    equilibrate = options.equilibrate_ps > 0
    equilibration = {
        "seed": int(options.seed),
        "temperature_K": float(options.temperature_K),
        "minimize_tolerance_kJ_per_mol_nm": 10.0,
        "minimize_max_iterations": 500 if equilibrate else 0,
        "langevin_steps": round(options.equilibrate_ps / 0.002) if equilibrate else 0,
        "langevin_timestep_fs": 2.0,
        "langevin_friction_per_ps": 1.0,
        "platform": "CPU",
    }
    data = {"description": f"{path.name} ({kind})", "build": build, "equilibration": equilibration}
    return parse_definition(data, path.stem)


def check_file_build(name: str, build: dict[str, Any], base: Path | None = None) -> None:
    """Validate a file kind's ``[build]`` table in place; relative paths become absolute from ``base``."""
    files = build.get("files")
    if not isinstance(files, dict) or "system" not in files:
        raise DefinitionError(
            f"system {name!r}: build.files must be a table with at least 'system' (a path)."
        )
    for key, value in list(files.items()):
        paths = value if isinstance(value, list) else [value]
        resolved = [str(_resolve(p, base)) for p in paths]
        files[key] = resolved if isinstance(value, list) else resolved[0]
        if key == "include_dir":
            continue
        for p in resolved:
            if not Path(p).is_file():
                raise DefinitionError(f"system {name!r}: {key} file {p} not found.")
    build.setdefault("forcefield", [])
    build.setdefault("cutoff_nm", 0.9)
    build.setdefault("constraints", "HBonds")
    build.setdefault("prepare_for_nve", True)
    if build["constraints"] not in CONSTRAINT_CHOICES:
        raise DefinitionError(
            f"system {name!r}: constraints {build['constraints']!r}; "
            f"choose one of {sorted(CONSTRAINT_CHOICES)}."
        )
    mass = build.get("hydrogen_mass_amu")
    if mass is not None and not 1.0 <= float(mass) <= 4.0:
        raise DefinitionError(
            f"system {name!r}: hydrogen mass {mass} amu is outside 1–4 amu (3 or 4 is usual for a 4 fs step)."
        )
    box = build.get("box_nm")
    if box is not None and (len(box) != 3 or not all(float(edge) > 0 for edge in box)):
        raise DefinitionError(f"system {name!r}: box_nm must be three positive edges in nm, got {box!r}.")
    kind = build["kind"]
    needs = {
        "charmm": (
            "coordinates",
            "params",
            "--coordinates FILE.crd and --params FILE.prm FILE.rtf (or .str)",
        ),
        "amber": ("coordinates", None, "--coordinates FILE.inpcrd (or a .inpcrd/.rst7 of the same stem)"),
        "gromacs": ("coordinates", None, "--coordinates FILE.gro (or a .gro of the same stem)"),
        "openmm_xml": ("state", None, "--state STATE.xml (a serialized openmm.State)"),
    }
    if kind in needs:
        first, second, how = needs[kind]
        missing = [key for key in (first, second) if key is not None and key not in files]
        if missing:
            raise DefinitionError(
                f"system {name!r}: no {' or '.join(missing)} file for {Path(files['system']).name}; "
                f"give {how}."
            )
    if kind == "pdb_files" and not build["forcefield"]:
        raise DefinitionError(
            f"system {name!r}: a PDB/PDBx file needs force-field XMLs; give --forcefield, e.g. "
            "--forcefield amber14-all.xml amber14/tip3p.xml"
        )
    if kind == "openmm_xml" and build["constraints"] != "HBonds":
        raise DefinitionError(
            f"system {name!r}: a serialized System keeps its own constraints; --constraints applies to "
            "files a reader turns into a System (prmtop, psf, top, pdb)."
        )


def file_digests(definition: SystemDefinition) -> list[str]:
    """SHA-256 of every file a file-kind definition reads (part of its cache key); empty for other kinds."""
    if definition.build.get("kind") not in FILE_KINDS:
        return []
    digests = []
    for key, value in sorted(definition.build["files"].items()):
        for path in value if isinstance(value, list) else [value]:
            if Path(path).is_file():
                digests.append(f"{key}:{hashlib.sha256(Path(path).read_bytes()).hexdigest()}")
    return digests


@dataclass
class LoadedFiles:
    """What :func:`load_files` read: the topology, the System ready for NVE, positions, maybe velocities."""

    topology: app.Topology
    system: mm.System
    positions: np.ndarray
    velocities: np.ndarray | None
    changes: list[str] = field(default_factory=list)


def load_files(definition: SystemDefinition) -> LoadedFiles:
    """Read a file-kind definition's files with OpenMM's readers and prepare the System for NVE.

    Raises
    ------
    DefinitionError
        For files that disagree in atom count, a periodic system without a box, or a
        file a reader rejects (its message included).
    """
    build = definition.build
    reader = _READERS[build["kind"]]
    try:
        topology, system, positions, velocities = reader(definition.name, build)
    except (ValueError, KeyError, IndexError, mm.OpenMMException) as error:
        raise DefinitionError(
            f"system {definition.name!r}: reading {build['files']['system']} failed: {error}"
        ) from None
    if system.getNumParticles() != len(positions):
        raise DefinitionError(
            f"system {definition.name!r}: the files disagree: the System has {system.getNumParticles()} "
            f"particles, the coordinates {len(positions)} atoms; give the coordinates of this topology."
        )
    if topology.getNumAtoms() != system.getNumParticles():
        raise DefinitionError(
            f"system {definition.name!r}: the topology has {topology.getNumAtoms()} atoms and the System "
            f"{system.getNumParticles()} particles; give the topology (PDB) of this System."
        )
    changes = []
    mass = build.get("hydrogen_mass_amu")
    if mass is not None and build["kind"] == "openmm_xml":
        changes += repartition_hydrogen_mass(system, float(mass), topology)
    elif mass is not None:
        count = sum(
            abs(system.getParticleMass(i).value_in_unit(unit.dalton) - float(mass)) < 1e-9
            for i in range(system.getNumParticles())
        )
        changes.append(
            f"hydrogen mass repartitioned (the reader's hydrogenMass): {count} hydrogens set to "
            f"{float(mass):g} amu, taken from their heavy atoms"
        )
    if build["prepare_for_nve"]:
        from ..nve import prepare_for_nve

        changes += prepare_for_nve(system)
    return LoadedFiles(topology, system, np.asarray(positions, dtype=float), velocities, changes)


def repartition_hydrogen_mass(
    system: mm.System, mass: float, topology: app.Topology | None = None
) -> list[str]:
    """Give each hydrogen bonded to a heavy atom ``mass`` amu, taken from that atom, in place.

    The bonds come from the ``topology`` if it has any, else from the System's
    constraints and ``HarmonicBondForce`` terms. Water's hydrogens (an oxygen bonded to
    two hydrogens and nothing else) are left alone, as OpenMM's ``hydrogenMass`` does with
    rigid water. The total mass is kept. Returns one line saying what changed.
    """
    pairs = _bonds(system, topology)
    masses = np.array(
        [system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())]
    )
    partners: dict[int, list[int]] = {}
    for i, j in pairs:
        partners.setdefault(i, []).append(j)
        partners.setdefault(j, []).append(i)

    def hydrogen(i: int) -> bool:
        return 0 < masses[i] < HYDROGEN_MASS_LIMIT and len(partners.get(i, [])) == 1

    changed = 0
    for h in range(len(masses)):
        if not hydrogen(h):
            continue
        heavy = partners[h][0]
        if hydrogen(heavy) or masses[heavy] <= 0:
            continue
        heavy_partners = partners.get(heavy, [])
        if len(heavy_partners) == 2 and all(hydrogen(p) for p in heavy_partners):
            continue  # water
        moved = mass - masses[h]
        if masses[heavy] - moved <= 1.0:
            raise DefinitionError(
                f"hydrogen mass {mass} amu would leave particle {heavy} with "
                f"{masses[heavy] - moved:.2f} amu; give a smaller --hydrogen-mass."
            )
        masses[h] += moved
        masses[heavy] -= moved
        system.setParticleMass(h, masses[h])
        system.setParticleMass(heavy, masses[heavy])
        changed += 1
    if changed == 0:
        return [f"hydrogen mass {mass:g} amu: no hydrogen bonded to a heavy atom found (nothing changed)"]
    return [
        f"hydrogen mass repartitioned: {changed} hydrogens set to {mass:g} amu, taken from their heavy atoms"
    ]


# ---------------------------------------------------------------- readers
def _create_kwargs(build: dict[str, Any], periodic: bool) -> dict[str, Any]:
    kwargs: dict[str, Any] = {
        "nonbondedMethod": app.PME if periodic else app.NoCutoff,
        "constraints": CONSTRAINT_CHOICES[build["constraints"]],
        "rigidWater": build["constraints"] != "none",
    }
    if periodic:
        kwargs["nonbondedCutoff"] = float(build["cutoff_nm"]) * unit.nanometers
    if build.get("hydrogen_mass_amu") is not None:
        kwargs["hydrogenMass"] = float(build["hydrogen_mass_amu"]) * unit.amu
    return kwargs


def _box_vectors(name: str, build: dict[str, Any], from_file, where: str):
    """Return the box: ``box_nm`` if given, else the coordinates' own; refuse a periodic one without."""
    if build.get("box_nm") is not None:
        a, b, c = (float(edge) for edge in build["box_nm"])
        return (mm.Vec3(a, 0, 0), mm.Vec3(0, b, 0), mm.Vec3(0, 0, c)) * unit.nanometers
    if from_file is not None:
        return from_file
    raise DefinitionError(
        f"system {name!r}: {where} has no periodic box, and PME needs one; give the box edges in nm with "
        "--box A B C (or coordinates that carry the box)."
    )


def _read_amber(name: str, build: dict[str, Any]):
    files = build["files"]
    prmtop = app.AmberPrmtopFile(files["system"])
    inpcrd = app.AmberInpcrdFile(files["coordinates"])
    periodic = prmtop.topology.getPeriodicBoxVectors() is not None or inpcrd.boxVectors is not None
    if periodic:
        box = _box_vectors(name, build, inpcrd.boxVectors, Path(files["coordinates"]).name)
        prmtop.topology.setPeriodicBoxVectors(box)
    system = prmtop.createSystem(**_create_kwargs(build, periodic))
    if periodic:
        system.setDefaultPeriodicBoxVectors(*box)
    velocities = None if inpcrd.velocities is None else _nm_per_ps(inpcrd.velocities)
    return prmtop.topology, system, _nm(inpcrd.positions), velocities


def _read_charmm(name: str, build: dict[str, Any]):
    files = build["files"]
    psf = app.CharmmPsfFile(files["system"])
    coordinates = files["coordinates"]
    if coordinates.lower().endswith(".pdb"):
        pdb = app.PDBFile(coordinates)
        positions, from_file = pdb.positions, pdb.topology.getPeriodicBoxVectors()
    else:
        positions, from_file = app.CharmmCrdFile(coordinates).positions, None
    box = _box_vectors(name, build, from_file, Path(coordinates).name)
    lengths = [box[i][i].value_in_unit(unit.nanometers) for i in range(3)]
    psf.setBox(*(length * unit.nanometers for length in lengths))
    params = app.CharmmParameterSet(*files["params"])
    system = psf.createSystem(params, **_create_kwargs(build, True))
    return psf.topology, system, _nm(positions), None


def _read_gromacs(name: str, build: dict[str, Any]):
    files = build["files"]
    gro = app.GromacsGroFile(files["coordinates"])
    box = _box_vectors(name, build, gro.getPeriodicBoxVectors(), Path(files["coordinates"]).name)
    kwargs = {"periodicBoxVectors": box}
    if files.get("include_dir"):
        kwargs["includeDir"] = files["include_dir"]
    top = app.GromacsTopFile(files["system"], **kwargs)
    system = top.createSystem(**_create_kwargs(build, True))
    return top.topology, system, _nm(gro.positions), None


def _read_pdb(name: str, build: dict[str, Any]):
    path = build["files"]["system"]
    structure = app.PDBxFile(path) if Path(path).suffix.lower() in (".cif", ".pdbx") else app.PDBFile(path)
    topology = structure.topology
    box = _box_vectors(name, build, topology.getPeriodicBoxVectors(), Path(path).name)
    topology.setPeriodicBoxVectors(box)
    forcefield = app.ForceField(*build["forcefield"])
    system = forcefield.createSystem(topology, **_create_kwargs(build, True))
    return topology, system, _nm(structure.positions), None


def _read_openmm_xml(name: str, build: dict[str, Any]):
    files = build["files"]
    system = mm.XmlSerializer.deserialize(Path(files["system"]).read_text(encoding="utf-8"))
    state = mm.XmlSerializer.deserialize(Path(files["state"]).read_text(encoding="utf-8"))
    if not isinstance(system, mm.System) or not isinstance(state, mm.State):
        raise DefinitionError(
            f"system {name!r}: {files['system']} must hold a serialized System and {files['state']} a State."
        )
    positions = _nm(state.getPositions())
    try:
        velocities = _nm_per_ps(state.getVelocities())
    except mm.OpenMMException:
        velocities = None
    if system.usesPeriodicBoundaryConditions():
        box = state.getPeriodicBoxVectors()
        system.setDefaultPeriodicBoxVectors(*box)
    topology = (
        app.PDBFile(files["topology"]).topology if "topology" in files else _topology_from_masses(system)
    )
    if system.usesPeriodicBoundaryConditions():
        vectors = system.getDefaultPeriodicBoxVectors()
        topology.setPeriodicBoxVectors([v.value_in_unit(unit.nanometers) for v in vectors] * unit.nanometers)
    return topology, system, positions, velocities


_READERS = {
    "amber": _read_amber,
    "charmm": _read_charmm,
    "gromacs": _read_gromacs,
    "pdb_files": _read_pdb,
    "openmm_xml": _read_openmm_xml,
}


def _topology_from_masses(system: mm.System) -> app.Topology:
    """Make a topology for a System without one: a residue per particle, elements guessed from masses."""
    topology = app.Topology()
    chain = topology.addChain()
    for i in range(system.getNumParticles()):
        mass = system.getParticleMass(i).value_in_unit(unit.dalton)
        element = (
            None
            if mass <= 0
            else app.element.hydrogen
            if mass < HYDROGEN_MASS_LIMIT
            else app.Element.getByMass(mass)
        )
        residue = topology.addResidue("UNK", chain)
        topology.addAtom(element.symbol if element is not None else "EP", element, residue)
    return topology


def _bonds(system: mm.System, topology: app.Topology | None) -> list[tuple[int, int]]:
    """Bonded pairs: the topology's, else the System's constraints and harmonic bonds."""
    if topology is not None and topology.getNumBonds() > 0:
        return [(bond[0].index, bond[1].index) for bond in topology.bonds()]
    pairs = {tuple(sorted(system.getConstraintParameters(k)[:2])) for k in range(system.getNumConstraints())}
    for force in system.getForces():
        if isinstance(force, mm.HarmonicBondForce):
            pairs |= {tuple(sorted(force.getBondParameters(k)[:2])) for k in range(force.getNumBonds())}
    # a rigid water's H–H constraint is not a bond: keep pairs that include a heavy particle
    masses = [system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())]
    return [(i, j) for i, j in pairs if max(masses[i], masses[j]) >= HYDROGEN_MASS_LIMIT]


def _same_stem(path: Path, suffixes: tuple[str, ...]) -> Path | None:
    for suffix in suffixes:
        candidate = path.with_suffix(suffix)
        if candidate.is_file():
            return candidate
    return None


def _resolve(path: str, base: Path | None) -> Path:
    p = Path(path).expanduser()
    return p if p.is_absolute() or base is None else (base / p)


def _nm(positions) -> np.ndarray:
    return np.asarray(positions.value_in_unit(unit.nanometers) if unit.is_quantity(positions) else positions)


def _nm_per_ps(velocities) -> np.ndarray:
    velocity = unit.nanometers / unit.picoseconds
    return np.asarray(velocities.value_in_unit(velocity) if unit.is_quantity(velocities) else velocities)
