"""Declarative system definitions: the ``*.toml`` files next to this module, and a user's files.

A definition has a ``description``, a ``[build]`` table (what to build with OpenMM's
``ForceField`` and ``Modeller``, or which files of a user's to read) and an
``[equilibration]`` table (the seeded minimization + Langevin protocol). Keys carry their
unit in their name (``box_edge_nm``, ``temperature_K`` …). :func:`definition_key` hashes
the content, which keys the cache of equilibrated states.

A user's system files (AMBER, CHARMM, GROMACS, PDB/PDBx with force fields, OpenMM XML)
make a definition of a file kind: :func:`file_definition` from a file recognised by its
extension and :class:`FileOptions` (the command line's options), or a definition file
that names them::

    [build]
    kind = "amber"
    files = { system = "my.prmtop", coordinates = "my.inpcrd" }   # relative to the .toml
    cutoff_nm = 0.9

:mod:`.files` reads them with OpenMM's readers.
"""

from __future__ import annotations

import copy
import hashlib
import json
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import openmm.app as app
import openmm.unit as unit

from .._units import InputError, to_float
from ..errors import AlphaPRKError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

DEFINITIONS_DIR = Path(__file__).parent

#: Built by the package from a force field; the others are the kinds of a user's files (:data:`SUFFIX_KINDS`).
BUILT_KINDS = ("water_box", "water_cluster", "pdb")
KINDS = (*BUILT_KINDS, "amber", "charmm", "gromacs", "pdb_files", "openmm_xml")
NONBONDED_METHODS = ("PME", "NoCutoff")
CONSTRAINTS = ("none", "HBonds")
#: The kinds of a user's files, by the extension of the file that names the system.
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
#: The ``constraints`` of a System a reader creates, as OpenMM spells them.
CONSTRAINT_CHOICES = {"HBonds": app.HBonds, "AllBonds": app.AllBonds, "HAngles": app.HAngles, "none": None}

#: Required keys of each table, with their types.
_BUILD_KEYS: dict[str, dict[str, type | tuple[type, ...]]] = {
    "water_box": {"water_model": str, "box_edge_nm": (int, float), "cutoff_nm": (int, float)},
    "water_cluster": {"water_model": str, "radius_nm": (int, float)},
    "pdb": {"pdb": str, "cutoff_nm": (int, float)},
}
_EQUILIBRATION_KEYS: dict[str, type | tuple[type, ...]] = {
    "seed": int,
    "temperature_K": (int, float),
    "minimize_tolerance_kJ_per_mol_nm": (int, float),
    "minimize_max_iterations": int,
    "langevin_steps": int,
    "langevin_timestep_fs": (int, float),
    "langevin_friction_per_ps": (int, float),
    "platform": str,
}


class UnknownSystemError(AlphaPRKError, KeyError):
    """Raised for a system name with no definition file.

    Examples
    --------
    >>> from openmm_alphaprk.systems import load_definition
    >>> load_definition("tip3p-9nm")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.systems.definitions.UnknownSystemError: unknown system 'tip3p-9nm'; choose one of ...
    """

    def __str__(self) -> str:
        return str(self.args[0])


class DefinitionError(InputError):
    """Raised for a definition file with missing or invalid entries.

    Examples
    --------
    >>> from openmm_alphaprk.systems import water_box_definition
    >>> water_box_definition(2.0, cutoff=1.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.systems.definitions.DefinitionError: system 'tip3p-box-2nm': cutoff_nm 1.0 must be ...
    """


@dataclass(frozen=True)
class SystemDefinition:
    """A parsed, validated system definition.

    Attributes
    ----------
    name : str
        The file stem (``tip3p-3nm``), used on the command line.
    description : str
        One line for ``alphaprk systems``.
    build, equilibration : dict
        The tables of the file, as dicts.

    Examples
    --------
    >>> from openmm_alphaprk.systems import load_definition
    >>> definition = load_definition("tip3p-2nm")
    >>> definition.description
    'Rigid TIP3P water, cubic 2 nm box (~800 atoms), PME'
    >>> definition.build["box_edge_nm"], definition.build["cutoff_nm"], definition.build["switch_distance_nm"]
    (2.0, 0.9, 0.8)
    >>> shorter = definition.with_overrides({"equilibration.langevin_steps": 10})  # another key
    >>> shorter.equilibration["langevin_steps"], shorter == definition
    (10, False)
    """

    name: str
    description: str
    build: dict[str, Any]
    equilibration: dict[str, Any]

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "build": copy.deepcopy(self.build),
            "equilibration": copy.deepcopy(self.equilibration),
        }

    def with_overrides(self, overrides: dict[str, Any] | None) -> SystemDefinition:
        """Return a copy with ``{"table.key": value}`` entries replaced (e.g. shorter equilibration).

        The overrides change :func:`definition_key`, so an overridden system is cached
        separately from the original.
        """
        if not overrides:
            return self
        data = self.as_dict()
        for dotted, value in overrides.items():
            table, _, key = dotted.partition(".")
            if table not in ("build", "equilibration") or not key:
                raise DefinitionError(f"override {dotted!r} must be 'build.<key>' or 'equilibration.<key>'.")
            data[table][key] = value
        return parse_definition(data, self.name)

    def with_hydrogen_mass(self, mass_amu: float) -> SystemDefinition:
        """Return a copy whose hydrogens bonded to heavy atoms weigh ``mass_amu`` (a ``pdb`` kind).

        The mass is taken from the heavy atom (OpenMM's ``hydrogenMass``; water's hydrogens are
        left alone) when the System is made, so the start is minimized and equilibrated with
        the new masses, and cached under its own key as ``<name>-h<mass>``.

        Raises
        ------
        DefinitionError
            For a kind with no hydrogens bonded to heavy atoms (the water boxes and the
            cluster), or a mass outside 1–4 amu.

        Examples
        --------
        >>> from openmm_alphaprk.systems import load_definition
        >>> heavy = load_definition("villin").with_hydrogen_mass(3)
        >>> heavy.name, heavy.build["hydrogen_mass_amu"]
        ('villin-h3', 3.0)
        >>> load_definition("tip3p-2nm").with_hydrogen_mass(3)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        openmm_alphaprk.systems.definitions.DefinitionError: system 'tip3p-2nm' is water only: ...
        """
        if self.build.get("kind") != "pdb":
            raise DefinitionError(
                f"system {self.name!r} is water only: rigid water's hydrogens are not repartitioned, so "
                "a hydrogen mass changes nothing; leave --hydrogen-mass out (rigid water runs 4 fs as it is)."
            )
        changed = self.with_overrides({"build.hydrogen_mass_amu": float(mass_amu)})
        return replace(changed, name=f"{self.name}-h{float(mass_amu):g}")


def list_systems() -> list[str]:
    """Names of the shipped definitions, sorted.

    Returns
    -------
    list of str

    Examples
    --------
    >>> from openmm_alphaprk.systems import list_systems
    >>> list_systems()
    ['dhfr', 'spce-3nm', 'tip3p-2nm', 'tip3p-3nm', 'tip3p-4nm', 'tip4pew-3nm', 'villin', 'water-cluster']
    """
    return sorted(path.stem for path in DEFINITIONS_DIR.glob("*.toml"))


def load_definition(name: str) -> SystemDefinition:
    """Read and validate the definition called ``name`` (or a path to a ``.toml`` file).

    Parameters
    ----------
    name : str or os.PathLike
        A name of :func:`list_systems`, the path of a ``.toml`` definition file, or
        the path of a system file (:func:`file_definition`).

    Returns
    -------
    SystemDefinition

    Raises
    ------
    UnknownSystemError
        If there is no such definition; the message lists the known names.
    DefinitionError
        If the file is invalid.

    Examples
    --------
    >>> import os, tempfile
    >>> from openmm_alphaprk.systems import load_definition
    >>> from openmm_alphaprk.systems.definitions import DEFINITIONS_DIR
    >>> load_definition("water-cluster").build["kind"]
    'water_cluster'

    A definition file of one's own, here the package's 2 nm box made smaller:

    >>> text = (DEFINITIONS_DIR / "tip3p-2nm.toml").read_text()
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "small-box.toml")
    ...     with open(path, "w") as file:
    ...         _ = file.write(text.replace("box_edge_nm = 2.0", "box_edge_nm = 1.9"))
    ...     mine = load_definition(path)
    >>> mine.name, mine.build["box_edge_nm"]
    ('small-box', 1.9)
    """
    if is_system_file(name):
        return file_definition(name)
    path = Path(name)
    if path.suffix != ".toml":
        path = DEFINITIONS_DIR / f"{name}.toml"
    if not path.is_file():
        raise UnknownSystemError(
            f"unknown system {name!r}; choose one of {', '.join(list_systems())} "
            "(`alphaprk systems` lists them), or give the path of a .toml definition file."
        )
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as error:
        raise DefinitionError(f"{path} is not valid TOML: {error}") from None
    return parse_definition(data, path.stem, base=path.parent)


def parse_definition(data: dict[str, Any], name: str, base: Path | None = None) -> SystemDefinition:
    """Validate the tables of a definition and return it.

    The files of a file kind (:func:`check_file_build`) are made absolute from ``base`` (the
    definition file's folder; default the current directory) and must exist.
    """
    for table in ("build", "equilibration"):
        if not isinstance(data.get(table), dict):
            raise DefinitionError(f"system {name!r}: missing [{table}] table.")
    build, equilibration = dict(data["build"]), dict(data["equilibration"])
    kind = build.get("kind")
    if kind not in KINDS:
        raise DefinitionError(f"system {name!r}: build.kind must be one of {KINDS}, got {kind!r}.")
    if kind in BUILT_KINDS:
        _check_built_kind(name, kind, build)
    else:
        check_file_build(name, build, Path.cwd() if base is None else base)
    _check_keys(name, "equilibration", equilibration, _EQUILIBRATION_KEYS)
    for key in ("temperature_K", "langevin_timestep_fs", "langevin_friction_per_ps"):
        if not equilibration[key] > 0:
            raise DefinitionError(f"system {name!r}: equilibration.{key} must be positive.")
    for key in ("langevin_steps", "minimize_max_iterations"):
        if equilibration[key] < 0:
            raise DefinitionError(f"system {name!r}: equilibration.{key} must not be negative.")
    equilibration.setdefault("zero_momentum", False)
    return SystemDefinition(name, str(data.get("description", "")), build, equilibration)


def _check_built_kind(name: str, kind: str, build: dict[str, Any]) -> None:
    """Validate the ``[build]`` table of a kind the package builds, in place (defaults set)."""
    _check_keys(name, "build", build, {"forcefield": list, **_BUILD_KEYS[kind]})
    method = build.setdefault("nonbonded_method", "PME")
    if method not in NONBONDED_METHODS:
        raise DefinitionError(f"system {name!r}: build.nonbonded_method must be one of {NONBONDED_METHODS}.")
    if kind == "water_cluster" and method != "NoCutoff":
        raise DefinitionError(
            f"system {name!r}: a water cluster in vacuum needs nonbonded_method 'NoCutoff'."
        )
    if build.setdefault("constraints", "none") not in CONSTRAINTS:
        raise DefinitionError(f"system {name!r}: build.constraints must be one of {CONSTRAINTS}.")
    for key in ("box_edge_nm", "cutoff_nm", "radius_nm"):
        if key in build and not build[key] > 0:
            raise DefinitionError(f"system {name!r}: build.{key} must be positive, got {build[key]}.")
    for key in ("switch_distance_nm", "ewald_error_tolerance"):
        if key in build:
            value = build[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise DefinitionError(
                    f"system {name!r}: build.{key} must be a positive number, got {value!r}."
                )
    if build.get("hydrogen_mass_amu") is not None and kind != "pdb":
        raise DefinitionError(
            f"system {name!r}: build.hydrogen_mass_amu applies to a 'pdb' kind (a solute's hydrogens); "
            f"a {kind!r} is water only, whose rigid hydrogens are left alone."
        )
    _check_hydrogen_mass(name, build.get("hydrogen_mass_amu"))
    if "switch_distance_nm" in build and not build["switch_distance_nm"] < build.get("cutoff_nm", 0):
        raise DefinitionError(
            f"system {name!r}: build.switch_distance_nm must be below cutoff_nm (and needs a cutoff)."
        )
    if kind == "water_box" and build["cutoff_nm"] >= build["box_edge_nm"] / 2:
        raise DefinitionError(
            f"system {name!r}: cutoff_nm {build['cutoff_nm']} must be below half the box edge "
            f"({build['box_edge_nm'] / 2} nm); use a larger box or a shorter cutoff."
        )


def _check_hydrogen_mass(name: str, mass: object) -> None:
    """Refuse a ``build.hydrogen_mass_amu`` that is not a number of 1–4 amu (None: none asked)."""
    if mass is None:
        return
    if isinstance(mass, bool) or not isinstance(mass, (int, float)) or not 1.0 <= mass <= 4.0:
        raise DefinitionError(
            f"system {name!r}: hydrogen mass {mass!r} amu is outside 1–4 amu (3 or 4 is usual for a 4 fs "
            "step)."
        )


def _check_keys(name: str, table: str, values: dict, required: dict[str, Any]) -> None:
    for key, types in required.items():
        if key not in values:
            raise DefinitionError(f"system {name!r}: missing {table}.{key}.")
        value = values[key]
        if isinstance(value, bool) or not isinstance(value, types):
            raise DefinitionError(f"system {name!r}: {table}.{key} has the wrong type ({value!r}).")


def definition_key(definition: SystemDefinition, *extra: str) -> str:
    """SHA-256 of the definition's content (canonical JSON) and ``extra`` strings (versions)."""
    content = json.dumps(
        {"build": definition.build, "equilibration": definition.equilibration, "extra": extra},
        sort_keys=True,
    )
    return hashlib.sha256(content.encode()).hexdigest()


# ---------------------------------------------------------------- a user's files
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

    Parameters
    ----------
    path : str or os.PathLike
        The file that names the system: AMBER ``.prmtop``/``.parm7``, CHARMM ``.psf``,
        GROMACS ``.top``, PDB/PDBx ``.pdb``/``.cif``/``.pdbx`` or OpenMM System ``.xml``
        (:data:`SUFFIX_KINDS`).
    options : FileOptions, optional
        Companion files and how to prepare the System (the command line's options);
        default :class:`FileOptions`'s defaults.

    Returns
    -------
    SystemDefinition
        Named after the file's stem; :func:`~openmm_alphaprk.systems.prepare_system`
        reads and prepares it (and caches the start).

    Raises
    ------
    DefinitionError
        For a missing file, a missing companion file (coordinates, parameters, force
        field, state) or an option the format does not take, naming the fix.

    Examples
    --------
    An OpenMM System XML with its State (here the shipped cluster written out):

    >>> import os, tempfile, openmm
    >>> from openmm_alphaprk.systems import prepare_system
    >>> from openmm_alphaprk.systems.definitions import FileOptions, file_definition
    >>> water = prepare_system("water-cluster")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     for name, obj in (("cluster.xml", water.system), ("state.xml", water.state)):
    ...         with open(os.path.join(folder, name), "w") as file:
    ...             _ = file.write(openmm.XmlSerializer.serialize(obj))
    ...     definition = file_definition(os.path.join(folder, "cluster.xml"),
    ...                                  FileOptions(state=os.path.join(folder, "state.xml")))
    ...     mine = prepare_system(definition, use_cache=False)
    >>> definition.name, definition.description, sorted(definition.build["files"])
    ('cluster', 'cluster.xml (openmm_xml)', ['state', 'system'])
    >>> mine.n_atoms, mine.source, mine.changes  # ready for NVE as it was
    (222, 'built', ())

    A companion file missing:

    >>> file_definition("cluster.prmtop")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.systems.definitions.DefinitionError: system 'cluster': system file ... not found.
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
        "temperature_K": _temperature(options.temperature_K),
        "minimize_tolerance_kJ_per_mol_nm": 10.0,
        "minimize_max_iterations": 500 if equilibrate else 0,
        "langevin_steps": round(options.equilibrate_ps / 0.002) if equilibrate else 0,
        "langevin_timestep_fs": 2.0,
        "langevin_friction_per_ps": 1.0,
        "platform": "CPU",
    }
    data = {"description": f"{path.name} ({kind})", "build": build, "equilibration": equilibration}
    return parse_definition(data, path.stem)


def _temperature(value: object) -> float:
    """Return ``FileOptions.temperature_K`` in K, refusing a temperature that is not above 0 K."""
    kelvin = to_float(value, unit.kelvin, "temperature_K (--temperature)")
    if not kelvin > 0:
        raise DefinitionError(
            f"--temperature {kelvin:g} K: a temperature must be above 0 K (in kelvin, e.g. --temperature "
            f"{FileOptions.temperature_K:g}); the start's velocities are drawn at it where the files have "
            "none, and --equilibrate equilibrates at it."
        )
    return kelvin


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
    _check_hydrogen_mass(name, build.get("hydrogen_mass_amu"))
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


def _same_stem(path: Path, suffixes: tuple[str, ...]) -> Path | None:
    for suffix in suffixes:
        candidate = path.with_suffix(suffix)
        if candidate.is_file():
            return candidate
    return None


def _resolve(path: str, base: Path | None) -> Path:
    p = Path(path).expanduser()
    return p if p.is_absolute() or base is None else (base / p)
