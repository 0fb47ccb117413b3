"""Reading a user's own system files: AMBER, CHARMM, GROMACS, PDB/PDBx with force fields, OpenMM XML.

What the files are and how to read them is a definition of a file kind
(:func:`~.definitions.file_definition` from a file recognised by its extension and
:class:`~.definitions.FileOptions`, or a ``*.toml`` definition, see
:mod:`.definitions`), which :func:`~.cache.prepare_system` prepares like the named
systems: the same :class:`~.cache.PreparedSystem`, cached under a key of the definition
*and the files' content* (:func:`file_digests`). :func:`load_files` reads the files with
OpenMM's own readers (``AmberPrmtopFile``, ``CharmmPsfFile`` with ``CharmmParameterSet``,
``GromacsTopFile``, ``PDBFile``/``PDBxFile`` with ``ForceField``, ``XmlSerializer``) and,
unless the definition says ``prepare_for_nve = false``, makes the System ready for NVE
with :func:`~openmm_alphaprk.nve.prepare_for_nve`, recording each change. A file a
reader rejects is refused naming the file and the format it must be in.

The definition side is re-exported here (``from openmm_alphaprk.systems.files import
FileOptions, file_definition``), where the user's files are.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit

from ..nve import prepare_for_nve
from .definitions import (
    CONSTRAINT_CHOICES,
    FILE_KINDS,
    DefinitionError,
    FileOptions,
    SystemDefinition,
    file_definition,
    is_system_file,
)

__all__ = [
    "CONSTRAINT_CHOICES",
    "HYDROGEN_MASS_LIMIT",
    "FileOptions",
    "LoadedFiles",
    "file_definition",
    "file_digests",
    "is_system_file",
    "load_files",
    "repartition_hydrogen_mass",
    "velocities_file",
]

#: Below this mass (amu) a particle bonded to one other is a hydrogen (repartitioned ones included).
HYDROGEN_MASS_LIMIT = 4.5


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
        For a file a reader rejects (one of another format, or cut short: the message
        names the file, the format it must be in and the reader's own message), files
        that disagree in atom count, a periodic system without a box, or a System the
        reader cannot make from them.
    """
    build = definition.build
    reader = _READERS[build["kind"]]
    try:
        topology, system, positions, velocities = reader(definition.name, build)
    except DefinitionError:
        raise  # a file a reader rejected, named with the format it must be in
    except (ValueError, KeyError, IndexError, mm.OpenMMException) as error:  # making the System
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
        changes += prepare_for_nve(system)
    return LoadedFiles(topology, system, np.asarray(positions, dtype=float), velocities, changes)


def velocities_file(definition: SystemDefinition) -> str | None:
    """Return the file of a file-kind definition that carries velocities, or None.

    An AMBER restart (``.rst7``, ``.inpcrd`` with velocities) or a serialized State
    with velocities: the start keeps them unless it is equilibrated (see
    :func:`~.build.equilibrate`), where other files' starts get velocities drawn at
    ``temperature_K``. Reads only that file.

    Raises
    ------
    DefinitionError
        For a coordinate or state file its reader rejects.
    """
    build, name = definition.build, definition.name
    files = build.get("files", {})
    if build.get("kind") == "amber":
        carries = _read_inpcrd(name, files["coordinates"]).velocities is not None
        return files["coordinates"] if carries else None
    if build.get("kind") == "openmm_xml":
        try:
            _read_state(name, files["state"]).getVelocities()
        except mm.OpenMMException:  # a State serialized without velocities
            return None
        return files["state"]
    return None


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


def _parsed(name: str, path: str | Path, expected: str, read: Callable[[], Any], *, fix: str, of: str = ""):
    """Return ``read()`` (an OpenMM reader of ``path``); a file it rejects is refused as not ``expected``.

    OpenMM's readers fail on a file of another format, or one cut short, with whatever
    their parsing meets (``IndexError``, ``TypeError``, a bare ``Exception``): the
    message names the file, the format it must be in (``expected``, ``of`` what it
    must be the coordinates of), the reader's own words and the ``fix``.
    """
    try:
        return read()
    except Exception as error:  # noqa: BLE001 - whatever a parser raises, the file is not what it reads
        said = " ".join(str(error).split()).rstrip(".") or type(error).__name__
        if len(said) > 200:
            said = said[:200] + "…"
        raise DefinitionError(
            f"system {name!r}: {Path(path).name}: not {expected}{of}, or cut short "
            f"(OpenMM's reader: {said}); give {fix}."
        ) from None


def _atoms_of(topology: app.Topology, path: str | Path) -> str:
    return f" for the {topology.getNumAtoms():,} atoms of {Path(path).name}"


def _read_amber(name: str, build: dict[str, Any]):
    files = build["files"]
    prmtop = _read_prmtop(name, files["system"])
    inpcrd = _read_inpcrd(name, files["coordinates"], _atoms_of(prmtop.topology, files["system"]))
    periodic = prmtop.topology.getPeriodicBoxVectors() is not None or inpcrd.boxVectors is not None
    if periodic:
        box = _box_vectors(name, build, inpcrd.boxVectors, Path(files["coordinates"]).name)
        prmtop.topology.setPeriodicBoxVectors(box)
    system = prmtop.createSystem(**_create_kwargs(build, periodic))
    if periodic:
        system.setDefaultPeriodicBoxVectors(*box)
    velocities = None if inpcrd.velocities is None else _nm_per_ps(inpcrd.velocities)
    return prmtop.topology, system, _nm(inpcrd.positions), velocities


def _read_prmtop(name: str, path: str) -> app.AmberPrmtopFile:
    return _parsed(
        name,
        path,
        "an AMBER topology file (.prmtop/.parm7)",
        lambda: app.AmberPrmtopFile(path),
        fix="the system as an AMBER .prmtop/.parm7 file (tleap's or ParmEd's)",
    )


def _read_inpcrd(name: str, path: str, of: str = "") -> app.AmberInpcrdFile:
    return _parsed(
        name,
        path,
        "an AMBER coordinate file (.inpcrd/.rst7/.ncrst)",
        lambda: app.AmberInpcrdFile(path),
        fix="this topology's coordinates, complete, with --coordinates FILE.inpcrd (or .rst7)",
        of=of,
    )


def _read_charmm(name: str, build: dict[str, Any]):
    files = build["files"]
    psf = _parsed(
        name,
        files["system"],
        "a CHARMM PSF file (.psf)",
        lambda: app.CharmmPsfFile(files["system"]),
        fix="the system as a CHARMM .psf file",
    )
    coordinates, of = files["coordinates"], _atoms_of(psf.topology, files["system"])
    fix = "this PSF's coordinates, complete, with --coordinates FILE.crd (or .pdb)"
    if coordinates.lower().endswith(".pdb"):
        pdb = _parsed(
            name, coordinates, "a PDB file (.pdb)", lambda: app.PDBFile(coordinates), fix=fix, of=of
        )
        positions, from_file = pdb.positions, pdb.topology.getPeriodicBoxVectors()
    else:
        crd = _parsed(
            name,
            coordinates,
            "a CHARMM coordinate file (.crd)",
            lambda: app.CharmmCrdFile(coordinates),
            fix=fix,
            of=of,
        )
        positions, from_file = crd.positions, None
    box = _box_vectors(name, build, from_file, Path(coordinates).name)
    lengths = [box[i][i].value_in_unit(unit.nanometers) for i in range(3)]
    psf.setBox(*(length * unit.nanometers for length in lengths))
    params = _parsed(
        name,
        ", ".join(Path(p).name for p in files["params"]),
        "CHARMM parameter and topology files (.prm/.par, .rtf/.top, .str, told apart by extension)",
        lambda: app.CharmmParameterSet(*files["params"]),
        fix="the force field's files with --params FILE.prm FILE.rtf (or .str)",
    )
    system = psf.createSystem(params, **_create_kwargs(build, True))
    return psf.topology, system, _nm(positions), None


def _read_gromacs(name: str, build: dict[str, Any]):
    files = build["files"]
    kwargs = {"includeDir": files["include_dir"]} if files.get("include_dir") else {}
    top = _parsed(
        name,
        files["system"],
        "a GROMACS topology file (.top)",
        lambda: app.GromacsTopFile(files["system"], **kwargs),
        fix="the system as a GROMACS .top file, with --include-dir where its #include files are",
    )
    gro = _parsed(
        name,
        files["coordinates"],
        "a GROMACS coordinate file (.gro)",
        lambda: app.GromacsGroFile(files["coordinates"]),
        fix="this topology's coordinates, complete, with --coordinates FILE.gro",
        of=_atoms_of(top.topology, files["system"]),
    )
    box = _box_vectors(name, build, gro.getPeriodicBoxVectors(), Path(files["coordinates"]).name)
    top.topology.setPeriodicBoxVectors(box)
    system = top.createSystem(**_create_kwargs(build, True))
    return top.topology, system, _nm(gro.positions), None


def _read_pdb(name: str, build: dict[str, Any]):
    path = build["files"]["system"]
    if Path(path).suffix.lower() in (".cif", ".pdbx"):
        expected, read = "a PDBx/mmCIF file (.cif/.pdbx)", app.PDBxFile
    else:
        expected, read = "a PDB file (.pdb)", app.PDBFile
    structure = _parsed(
        name, path, expected, lambda: read(path), fix="the system as a PDB (.pdb) or PDBx/mmCIF (.cif) file"
    )
    topology = structure.topology
    box = _box_vectors(name, build, topology.getPeriodicBoxVectors(), Path(path).name)
    topology.setPeriodicBoxVectors(box)
    forcefield = _parsed(
        name,
        " ".join(build["forcefield"]),
        "OpenMM force-field XML files",
        lambda: app.ForceField(*build["forcefield"]),
        fix="OpenMM's force-field names or paths of your XMLs, e.g. --forcefield amber14-all.xml "
        "amber14/tip3p.xml",
    )
    system = forcefield.createSystem(topology, **_create_kwargs(build, True))
    return topology, system, _nm(structure.positions), None


def _read_openmm_xml(name: str, build: dict[str, Any]):
    files = build["files"]
    system = _parsed(
        name,
        files["system"],
        "a serialized OpenMM System (XmlSerializer XML)",
        lambda: _deserialized(files["system"], mm.System),
        fix="the System as openmm.XmlSerializer.serialize(system) writes it",
    )
    state = _read_state(
        name,
        files["state"],
        f" for the {system.getNumParticles():,} particles of {Path(files['system']).name}",
    )
    positions = _nm(state.getPositions())
    try:
        velocities = _nm_per_ps(state.getVelocities())
    except mm.OpenMMException:
        velocities = None
    if system.usesPeriodicBoundaryConditions():
        box = state.getPeriodicBoxVectors()
        system.setDefaultPeriodicBoxVectors(*box)
    if "topology" in files:
        topology = _parsed(
            name,
            files["topology"],
            "a PDB file (.pdb)",
            lambda: app.PDBFile(files["topology"]),
            fix="this System's topology as a PDB file with --topology (or none: one is made from the masses)",
        ).topology
    else:
        topology = _topology_from_masses(system)
    if system.usesPeriodicBoundaryConditions():
        vectors = system.getDefaultPeriodicBoxVectors()
        topology.setPeriodicBoxVectors([v.value_in_unit(unit.nanometers) for v in vectors] * unit.nanometers)
    return topology, system, positions, velocities


def _read_state(name: str, path: str, of: str = "") -> mm.State:
    return _parsed(
        name,
        path,
        "a serialized OpenMM State (XmlSerializer XML)",
        lambda: _deserialized(path, mm.State),
        fix="the State as openmm.XmlSerializer.serialize(context.getState(getPositions=True, "
        "getVelocities=True)) writes it, with --state",
        of=of,
    )


def _deserialized(path: str, kind: type):
    """Return the object serialized in ``path``; TypeError if it is not a ``kind``."""
    found = mm.XmlSerializer.deserialize(Path(path).read_text(encoding="utf-8"))
    if not isinstance(found, kind):
        raise TypeError(f"it holds a serialized {type(found).__name__}")
    return found


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


def _nm(positions) -> np.ndarray:
    return np.asarray(positions.value_in_unit(unit.nanometers) if unit.is_quantity(positions) else positions)


def _nm_per_ps(velocities) -> np.ndarray:
    velocity = unit.nanometers / unit.picoseconds
    return np.asarray(velocities.value_in_unit(velocity) if unit.is_quantity(velocities) else velocities)
