"""Equilibrated systems: shipped with the package, or built once and cached as OpenMM XML.

:func:`prepare_system` returns, in this order: the shipped start state of a
definition (:mod:`.shipped`; the default systems), the state cached in
:func:`default_cache_dir` under a key of the definition's content, or a state built
now (minimized and equilibrated) and cached.
"""

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

from .build import BUILDER_VERSION, build_model, create_system, equilibrate
from .definitions import BUILT_KINDS, SystemDefinition, definition_key, load_definition
from .files import file_digests, load_files
from .shipped import ShippedState, load_shipped_state

#: Environment variable that overrides the cache folder.
CACHE_ENV = "ALPHAPRK_CACHE_DIR"


@dataclass
class PreparedSystem:
    """An equilibrated system ready for NVE: topology, System and the start State.

    Attributes
    ----------
    name : str
        Name of the definition it was built from.
    definition : SystemDefinition
        The definition it was built from.
    key : str
        Identifies the start state: for a shipped state the hash of the definition's
        content and the builder version (:func:`~.shipped.shipped_key`), for a state
        built here also of the OpenMM version (:func:`system_key`).
    topology : openmm.app.Topology
        The topology (residues, atoms, bonds).
    system : openmm.System
        The System.
    state : openmm.State
        The start state: positions, velocities and box vectors.
    path : pathlib.Path or None
        The shipped state file or the cache folder the state was read from or written
        to (None if built without a cache).
    source : {"shipped", "cache", "built"}
        ``"shipped"`` (the package's state), ``"cache"`` (read from the cache) or
        ``"built"`` (minimized and equilibrated by this call).
    changes : tuple of str
        What was changed to make a user's files ready for NVE (LJ switch, Ewald
        tolerance, forces removed, hydrogen masses), one line each; empty for the
        package's own systems, which are built ready.

    Examples
    --------
    Returned by :func:`prepare_system`:

    >>> from openmm_alphaprk.systems import prepare_system
    >>> water = prepare_system("water-cluster")
    >>> water.name, water.source, water.n_atoms, water.changes
    ('water-cluster', 'shipped', 222, ())
    >>> water.path.name
    'water-cluster.xml.gz'
    >>> water.positions.shape, water.velocities.shape  # nm, nm/ps
    ((222, 3), (222, 3))
    >>> water.system.getNumConstraints()  # rigid water: three per molecule
    222
    """

    name: str
    definition: SystemDefinition
    key: str
    topology: app.Topology
    system: mm.System
    state: mm.State
    path: Path | None = None
    source: str = "built"
    changes: tuple[str, ...] = ()

    @classmethod
    def from_shipped(cls, definition: SystemDefinition, shipped: ShippedState) -> PreparedSystem:
        """Return the system of ``definition`` started from its shipped state (``source="shipped"``)."""
        return cls(
            definition.name,
            definition,
            shipped.key,
            shipped.topology,
            shipped.system,
            shipped.state,
            shipped.path,
            source="shipped",
        )

    @property
    def from_cache(self) -> bool:
        """True if the state was read from the cache (not shipped, not built by this call)."""
        return self.source == "cache"

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

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import os
    >>> from pathlib import Path
    >>> from unittest import mock
    >>> from openmm_alphaprk.systems import CACHE_ENV, default_cache_dir
    >>> with mock.patch.dict(os.environ, {CACHE_ENV: "/scratch/alphaprk-cache"}):
    ...     default_cache_dir() == Path("/scratch/alphaprk-cache")
    True
    >>> with mock.patch.dict(os.environ, {CACHE_ENV: "", "XDG_CACHE_HOME": "/scratch/cache"}):
    ...     default_cache_dir() == Path("/scratch/cache/openmm_alphaprk")
    True
    """
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "openmm_alphaprk"


def system_key(definition: SystemDefinition) -> str:
    """Cache key: the definition's content, the OpenMM version, :data:`BUILDER_VERSION` and the files read."""
    return definition_key(definition, mm.__version__, BUILDER_VERSION, *file_digests(definition))


def cache_path(definition: SystemDefinition, cache_dir: str | os.PathLike | None = None) -> Path:
    """Folder of the cached equilibrated state of ``definition``."""
    return _entry(definition, cache_dir, system_key(definition))


def _entry(definition: SystemDefinition, cache_dir: str | os.PathLike | None, key: str) -> Path:
    """Folder of the cache entry of ``definition`` under ``key`` (:func:`system_key`, computed once)."""
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return root / f"{definition.name}-{key[:16]}"


def prepare_system(
    name: str | SystemDefinition,
    *,
    cache_dir: str | os.PathLike | None = None,
    overrides: dict | None = None,
    use_cache: bool = True,
    rebuild: bool = False,
    progress: bool = False,
    check: Callable[[mm.System], None] | None = None,
) -> PreparedSystem:
    """Return the equilibrated system ``name``: shipped, cached, or built (and cached) now.

    Without ``rebuild``, a definition whose content has a shipped start state
    (:mod:`openmm_alphaprk.systems.shipped`; ``alphaprk systems`` lists them) starts
    from that state, the same on every machine, with its System made here from the
    definition; the cache is not consulted for it. Any other definition is read from
    the cache, or built (minimized and equilibrated) and cached.

    Parameters
    ----------
    name : str or os.PathLike or SystemDefinition
        A definition name (``alphaprk systems`` lists them), a path to a ``.toml``
        file or to a system file (:func:`~.definitions.file_definition`), or a
        :class:`SystemDefinition`.
    cache_dir : str or os.PathLike, optional
        Cache root; default :func:`default_cache_dir`.
    overrides : dict, optional
        ``{"equilibration.langevin_steps": 10, ...}``: changed entries (their own
        key: cached separately, never started from the original's shipped state).
    use_cache : bool, default True
        If false, neither read nor write the cache (a shipped state is still used).
    rebuild : bool, default False
        Build the state now even if a shipped or cached one exists; the build
        replaces the cache entry (if ``use_cache``). A definition with a shipped state
        starts from the shipped state again at the next call without ``rebuild``.
    progress : bool, default False
        Show a progress bar while equilibrating.
    check : callable, optional
        Called with the System before the (slow) equilibration, e.g. to refuse an
        integrator that cannot run it before any time is spent.

    Returns
    -------
    PreparedSystem

    Raises
    ------
    UnknownSystemError
        For an unknown name.

    Examples
    --------
    A named system starts from the state shipped with the package:

    >>> import openmm
    >>> from openmm_alphaprk.systems import prepare_system
    >>> water = prepare_system("tip3p-2nm")
    >>> water.source, water.n_atoms
    ('shipped', 774)
    >>> context = openmm.Context(water.system, openmm.VerletIntegrator(0.001))
    >>> context.setState(water.state)  # positions, velocities and the box

    ``check`` sees the System first (here it only counts its particles):

    >>> _ = prepare_system("water-cluster", check=lambda system: print(system.getNumParticles()))
    222
    """
    definition = name if isinstance(name, SystemDefinition) else load_definition(name)
    definition = definition.with_overrides(overrides)
    shipped = None if rebuild else load_shipped_state(definition)
    if shipped is not None:
        prepared = PreparedSystem.from_shipped(definition, shipped)
    else:
        key = system_key(definition)  # once: for a user's files it hashes every file read
        path = _entry(definition, cache_dir, key) if use_cache else None
        if path is None or rebuild or not (path / "state.xml").is_file():
            return _build(definition, key, path, progress, check, replace=rebuild)
        prepared = _read(path, definition, key)
    if check is not None:
        check(prepared.system)
    return prepared


def _build(
    definition: SystemDefinition,
    key: str,
    path: Path | None,
    progress: bool,
    check: Callable[[mm.System], None] | None,
    replace: bool = False,
) -> PreparedSystem:
    """Build and equilibrate ``definition``; write it into the cache folder ``path`` unless None.

    With ``replace`` an existing entry at ``path`` is replaced, else it is kept.
    """
    velocities, changes = None, []
    if definition.build["kind"] in BUILT_KINDS:
        topology, positions, forcefield = build_model(definition)
        system = create_system(definition, topology, forcefield)
    else:
        loaded = load_files(definition)
        topology, system, positions = loaded.topology, loaded.system, loaded.positions
        velocities, changes = loaded.velocities, loaded.changes
    if check is not None:
        check(system)
    if progress:
        where = f"; cached in {path}" if path is not None else ""
        print(
            f"building {definition.name} ({system.getNumParticles()} atoms): minimizing and equilibrating"
            f"{where}",
            file=sys.stderr,
            flush=True,
        )
    start = time.perf_counter()
    state = equilibrate(definition, system, positions, velocities=velocities, progress=progress)
    prepared = PreparedSystem(
        definition.name, definition, key, topology, system, state, path, changes=tuple(changes)
    )
    if path is not None:
        _write(prepared, path, build_seconds=time.perf_counter() - start, replace=replace)
    return prepared


def _write(prepared: PreparedSystem, path: Path, build_seconds: float, replace: bool = False) -> None:
    """Write into a temporary sibling folder, then rename it into place (atomic).

    An existing entry is kept (another process cached the same key first), unless
    ``replace``: then it is moved aside and removed once the new one is in place.
    """
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
            "changes": list(prepared.changes),
        }
        (tmp / "definition.json").write_text(json.dumps(meta, indent=2), encoding="utf-8")
        # state.xml last: its presence marks a complete entry
        (tmp / "state.xml").write_text(mm.XmlSerializer.serialize(prepared.state), encoding="utf-8")
        old = None
        if replace and path.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.old.", dir=path.parent))
            os.replace(path, old / "entry")
        try:
            os.replace(tmp, path)
        except OSError:  # another process cached the same key first; keep theirs
            shutil.rmtree(tmp, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
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
    return PreparedSystem(
        definition.name,
        definition,
        key,
        topology,
        system,
        state,
        path,
        source="cache",
        changes=tuple(meta.get("changes", ())),
    )


def is_cached(definition: SystemDefinition, cache_dir: str | os.PathLike | None = None) -> bool:
    """Return True if the equilibrated state of ``definition`` is in the cache.

    Parameters
    ----------
    definition : SystemDefinition
        The definition (:func:`load_definition`, :func:`~.definitions.file_definition`).
    cache_dir : str or os.PathLike, optional
        Cache root; default :func:`default_cache_dir`.

    Returns
    -------
    bool

    Examples
    --------
    A System of one's own (here the shipped cluster written as OpenMM XML) is cached
    by its first :func:`prepare_system`; the package's named systems are shipped, not
    cached:

    >>> import os, tempfile, openmm
    >>> from openmm_alphaprk.systems import is_cached, load_definition, prepare_system
    >>> from openmm_alphaprk.systems.definitions import FileOptions, file_definition
    >>> water = prepare_system("water-cluster")
    >>> with tempfile.TemporaryDirectory() as cache:
    ...     for name, obj in (("cluster.xml", water.system), ("state.xml", water.state)):
    ...         with open(os.path.join(cache, name), "w") as file:
    ...             _ = file.write(openmm.XmlSerializer.serialize(obj))
    ...     mine = file_definition(os.path.join(cache, "cluster.xml"),
    ...                            FileOptions(state=os.path.join(cache, "state.xml")))
    ...     before = is_cached(mine, cache_dir=cache)
    ...     _ = prepare_system(mine, cache_dir=cache)
    ...     after = is_cached(mine, cache_dir=cache)
    ...     shipped = is_cached(load_definition("water-cluster"), cache_dir=cache)
    >>> before, after, shipped
    (False, True, False)
    """
    return (cache_path(definition, cache_dir) / "state.xml").is_file()
