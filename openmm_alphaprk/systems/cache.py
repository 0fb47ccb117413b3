"""Equilibrated systems, built once and cached as OpenMM XML keyed on the definition's content."""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit

from .build import build_model, create_system, equilibrate
from .definitions import SystemDefinition, definition_key, load_definition

#: Environment variable that overrides the cache folder.
CACHE_ENV = "ALPHAPRK_CACHE_DIR"
#: Bumped when the build code changes what a definition produces (invalidates old entries).
BUILDER_VERSION = "1"


@dataclass
class PreparedSystem:
    """An equilibrated system ready for NVE: topology, System and the start State.

    Attributes
    ----------
    name, definition
        Which definition it was built from.
    key
        Content hash of the definition, OpenMM version and builder version.
    topology, system, state
        The OpenMM objects; ``state`` holds positions, velocities and box vectors.
    path
        Cache folder the files were read from (None if built without a cache).
    from_cache
        True if this call read it from the cache instead of building it.
    """

    name: str
    definition: SystemDefinition
    key: str
    topology: app.Topology
    system: mm.System
    state: mm.State
    path: Path | None = None
    from_cache: bool = False

    @property
    def n_atoms(self) -> int:
        return self.system.getNumParticles()

    @property
    def positions(self) -> np.ndarray:
        """Start positions (nm), shape (N, 3)."""
        return self.state.getPositions(asNumpy=True).value_in_unit(unit.nanometers)

    @property
    def velocities(self) -> np.ndarray:
        """Start velocities (nm/ps), shape (N, 3)."""
        return self.state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)


def default_cache_dir() -> Path:
    """Return the cache root.

    ``$ALPHAPRK_CACHE_DIR``, else ``$XDG_CACHE_HOME/openmm_alphaprk``, else ``~/.cache/openmm_alphaprk``.
    """
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "openmm_alphaprk"


def system_key(definition: SystemDefinition) -> str:
    """Cache key: the definition's content, the OpenMM version and :data:`BUILDER_VERSION`."""
    return definition_key(definition, mm.__version__, BUILDER_VERSION)


def cache_path(definition: SystemDefinition, cache_dir: str | os.PathLike | None = None) -> Path:
    """Folder of the cached equilibrated state of ``definition``."""
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return root / f"{definition.name}-{system_key(definition)[:16]}"


def prepare_system(
    name: str | SystemDefinition,
    *,
    cache_dir: str | os.PathLike | None = None,
    overrides: dict | None = None,
    use_cache: bool = True,
    progress: bool = False,
    check: Callable[[mm.System], None] | None = None,
) -> PreparedSystem:
    """Return the equilibrated system ``name``, from the cache or built (and cached) now.

    Parameters
    ----------
    name
        A definition name (``alphaprk systems`` lists them), a path to a ``.toml``
        file, or a :class:`SystemDefinition`.
    cache_dir
        Cache root; default :func:`default_cache_dir`.
    overrides
        ``{"equilibration.langevin_steps": 10, ...}``: changed entries (cached under
        their own key).
    use_cache
        If false, build without reading or writing the cache.
    progress
        Show a progress bar while equilibrating.
    check
        Called with the System before the (slow) equilibration, e.g. to refuse an
        integrator that cannot run it before any time is spent.

    Raises
    ------
    UnknownSystemError
        For an unknown name.
    """
    definition = name if isinstance(name, SystemDefinition) else load_definition(name)
    definition = definition.with_overrides(overrides)
    key = system_key(definition)
    path = cache_path(definition, cache_dir)
    if use_cache and (path / "state.xml").is_file():
        prepared = _read(path, definition, key)
        if check is not None:
            check(prepared.system)
        return prepared
    prepared = _build(definition, key, path if use_cache else None, progress, check)
    if use_cache:
        prepared.path = path
    return prepared


def _build(
    definition: SystemDefinition,
    key: str,
    path: Path | None,
    progress: bool,
    check: Callable[[mm.System], None] | None,
) -> PreparedSystem:
    """Build and equilibrate ``definition``; write it into the cache folder ``path`` unless None."""
    topology, positions, forcefield = build_model(definition)
    system = create_system(definition, topology, forcefield)
    if check is not None:
        check(system)
    if progress:
        where = f"; cached in {path}" if path is not None else ""
        print(
            f"building {definition.name} ({system.getNumParticles()} atoms): minimizing and equilibrating, "
            f"once{where}",
            file=sys.stderr,
            flush=True,
        )
    start = time.perf_counter()
    state = equilibrate(definition, system, positions, progress=progress)
    prepared = PreparedSystem(definition.name, definition, key, topology, system, state)
    if path is not None:
        _write(prepared, path, build_seconds=time.perf_counter() - start)
    return prepared


def _write(prepared: PreparedSystem, path: Path, build_seconds: float) -> None:
    """Write into a temporary sibling folder, then rename it into place (atomic)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        (tmp / "system.xml").write_text(mm.XmlSerializer.serialize(prepared.system), encoding="utf-8")
        with open(tmp / "topology.pdb", "w") as handle:
            app.PDBFile.writeFile(prepared.topology, prepared.state.getPositions(), handle, keepIds=True)
        meta = {
            "name": prepared.name,
            "key": prepared.key,
            "definition": prepared.definition.as_dict(),
            "openmm_version": mm.__version__,
            "builder_version": BUILDER_VERSION,
            "n_atoms": prepared.n_atoms,
            "equilibration_seconds": round(build_seconds, 2),
        }
        (tmp / "definition.json").write_text(json.dumps(meta, indent=2), encoding="utf-8")
        # state.xml last: its presence marks a complete entry
        (tmp / "state.xml").write_text(mm.XmlSerializer.serialize(prepared.state), encoding="utf-8")
        try:
            os.replace(tmp, path)
        except OSError:  # another process cached the same key first; keep theirs
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _read(path: Path, definition: SystemDefinition, key: str) -> PreparedSystem:
    meta = json.loads((path / "definition.json").read_text(encoding="utf-8"))
    if meta.get("key") != key:
        raise RuntimeError(
            f"cache entry {path} holds key {meta.get('key')!r}, expected {key!r}; delete the folder "
            "and run again."
        )
    system = mm.XmlSerializer.deserialize((path / "system.xml").read_text(encoding="utf-8"))
    state = mm.XmlSerializer.deserialize((path / "state.xml").read_text(encoding="utf-8"))
    topology = app.PDBFile(str(path / "topology.pdb")).topology
    if topology.getNumAtoms() != system.getNumParticles():
        raise RuntimeError(
            f"cache entry {path} is inconsistent (topology and system sizes differ); delete it."
        )
    return PreparedSystem(definition.name, definition, key, topology, system, state, path, from_cache=True)


def is_cached(definition: SystemDefinition, cache_dir: str | os.PathLike | None = None) -> bool:
    """Return True if the equilibrated state of ``definition`` is in the cache."""
    return (cache_path(definition, cache_dir) / "state.xml").is_file()
