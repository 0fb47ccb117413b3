"""Declarative system definitions: the ``*.toml`` files next to this module.

A definition has a ``description``, a ``[build]`` table (what to build with OpenMM's
``ForceField`` and ``Modeller``) and an ``[equilibration]`` table (the seeded
minimization + Langevin protocol). Keys carry their unit in their name
(``box_edge_nm``, ``temperature_K`` …). :func:`definition_key` hashes the content,
which keys the cache of equilibrated states.
"""

from __future__ import annotations

import copy
import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._units import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

DEFINITIONS_DIR = Path(__file__).parent

#: Built by the package from a force field; the kinds of a user's files are in :mod:`.files`.
BUILT_KINDS = ("water_box", "water_cluster", "pdb")
KINDS = (*BUILT_KINDS, "amber", "charmm", "gromacs", "pdb_files", "openmm_xml")
NONBONDED_METHODS = ("PME", "NoCutoff")
CONSTRAINTS = ("none", "HBonds")

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


class UnknownSystemError(KeyError):
    """Raised for a system name with no definition file."""

    def __str__(self) -> str:
        return str(self.args[0])


class DefinitionError(InputError):
    """Raised for a definition file with missing or invalid entries."""


@dataclass(frozen=True)
class SystemDefinition:
    """A parsed, validated system definition.

    Attributes
    ----------
    name
        The file stem (``tip3p-3nm``), used on the command line.
    description
        One line for ``alphaprk systems``.
    build, equilibration
        The tables of the file, as dicts.
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


def list_systems() -> list[str]:
    """Names of the shipped definitions, sorted."""
    return sorted(path.stem for path in DEFINITIONS_DIR.glob("*.toml"))


def load_definition(name: str) -> SystemDefinition:
    """Read and validate the definition called ``name`` (or a path to a ``.toml`` file).

    Raises
    ------
    UnknownSystemError
        If there is no such definition; the message lists the known names.
    DefinitionError
        If the file is invalid.
    """
    from .files import file_definition, is_system_file

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

    The files of a file kind (:mod:`.files`) are made absolute from ``base`` (the
    definition file's folder; default the current directory) and must exist.
    """
    for table in ("build", "equilibration"):
        if not isinstance(data.get(table), dict):
            raise DefinitionError(f"system {name!r}: missing [{table}] table.")
    build, equilibration = dict(data["build"]), dict(data["equilibration"])
    kind = build.get("kind")
    if kind not in KINDS:
        raise DefinitionError(f"system {name!r}: build.kind must be one of {KINDS}, got {kind!r}.")
    if kind not in BUILT_KINDS:
        from .files import check_file_build

        check_file_build(name, build, Path.cwd() if base is None else base)
        _check_keys(name, "equilibration", equilibration, _EQUILIBRATION_KEYS)
        equilibration.setdefault("zero_momentum", False)
        return SystemDefinition(name, str(data.get("description", "")), build, equilibration)
    _check_keys(name, "build", build, {"forcefield": list, **_BUILD_KEYS[kind]})
    _check_keys(name, "equilibration", equilibration, _EQUILIBRATION_KEYS)
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
    if "switch_distance_nm" in build and not build["switch_distance_nm"] < build.get("cutoff_nm", 0):
        raise DefinitionError(
            f"system {name!r}: build.switch_distance_nm must be below cutoff_nm (and needs a cutoff)."
        )
    if kind == "water_box" and build["cutoff_nm"] >= build["box_edge_nm"] / 2:
        raise DefinitionError(
            f"system {name!r}: cutoff_nm {build['cutoff_nm']} must be below half the box edge "
            f"({build['box_edge_nm'] / 2} nm); use a larger box or a shorter cutoff."
        )
    for key in ("temperature_K", "langevin_timestep_fs", "langevin_friction_per_ps"):
        if not equilibration[key] > 0:
            raise DefinitionError(f"system {name!r}: equilibration.{key} must be positive.")
    for key in ("langevin_steps", "minimize_max_iterations"):
        if equilibration[key] < 0:
            raise DefinitionError(f"system {name!r}: equilibration.{key} must not be negative.")
    equilibration.setdefault("zero_momentum", False)
    return SystemDefinition(name, str(data.get("description", "")), build, equilibration)


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
