"""Start states shipped with the package, so that a named system starts from the same state everywhere.

A system's start state comes from a seeded minimization and Langevin equilibration on
the CPU platform, whose multithreaded force sums are not bitwise reproducible: two
machines that build the same definition get start states that differ in the last
digits, and the runs from them part ways. The package therefore ships the
equilibrated states of its default systems in ``states/`` next to this module:
``NAME.xml.gz`` (the OpenMM ``State`` of ``XmlSerializer``: positions, velocities and
box vectors, gzipped) and ``NAME.json`` (the key and the record of how it was built).

Only the State is shipped. The System and the topology are made again from the
definition by ForceField and Modeller (:func:`~.build.build_model`,
:func:`~.build.create_system`), which take no random input, so they do not depend on
where they are made, and a System XML written by one OpenMM version is not
guaranteed to load in another. The shipped key hashes the definition's content and
the builder version but not the OpenMM version: the state is positions and
velocities, valid under any OpenMM that builds the same atoms. Before it is used, the
topology built here is compared with the one the state was built for (atom count and
the SHA-256 of every atom's residue, name and element); if they differ, the state is
not used and :func:`load_shipped_state` warns (:class:`ShippedStateWarning`).

A changed definition has another key and finds no shipped state: it is built, never
started from a stale state. The writer of these files is :mod:`.ship`
(``python -m openmm_alphaprk.systems.ship NAME ...``, for the package's maintainers,
after a definition changed).
"""

from __future__ import annotations

import gzip
import hashlib
import json
import os
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import openmm as mm
import openmm.app as app

from ..errors import AlphaPRKWarning
from .build import BUILDER_VERSION, build_model, create_system
from .definitions import SystemDefinition, definition_key

#: Folder of the shipped states (package data).
STATES_DIR = Path(__file__).parent / "states"


class ShippedStateWarning(AlphaPRKWarning):
    """A shipped start state matches a definition but not the topology OpenMM builds here.

    Examples
    --------
    A record that claims 3 atoms more than OpenMM builds from the definition (as after a
    change of OpenMM's Modeller):

    >>> import json, os, tempfile, warnings
    >>> from openmm_alphaprk.systems import find_shipped_state, load_definition
    >>> from openmm_alphaprk.systems.shipped import load_shipped_state
    >>> definition = load_definition("tip3p-2nm")
    >>> record = json.loads(find_shipped_state(definition).read_text())
    >>> record["n_atoms"] += 3
    >>> with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     with open(os.path.join(folder, "tip3p-2nm.json"), "w") as file:
    ...         json.dump(record, file)
    ...     print(load_shipped_state(definition, folder))  # not used: the system is built instead
    None
    >>> caught[0].category.__name__
    'ShippedStateWarning'
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    the shipped start state of 'tip3p-2nm' (tip3p-2nm.xml.gz) was built with OpenMM ... for 777 atoms; ...
    """


@dataclass
class ShippedState:
    """A shipped start state with the System and topology made here from its definition."""

    key: str
    topology: app.Topology
    system: mm.System
    state: mm.State
    path: Path


def shipped_key(definition: SystemDefinition) -> str:
    """Key of a shipped state: the definition's content and :data:`~.build.BUILDER_VERSION`.

    Unlike the cache key it leaves out the OpenMM version (the state is positions,
    velocities and box, valid under any version that builds the same atoms).
    """
    return definition_key(definition, "shipped", BUILDER_VERSION)


def topology_fingerprint(topology: app.Topology) -> str:
    """SHA-256 of every atom's residue name, atom name and element, in order."""
    lines = (
        f"{atom.residue.name} {atom.name} {atom.element.symbol if atom.element is not None else '-'}"
        for atom in topology.atoms()
    )
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


def find_shipped_state(definition: SystemDefinition, directory: Path | None = None) -> Path | None:
    """Return the ``.json`` record of the shipped state whose key is ``definition``'s, or None.

    Parameters
    ----------
    definition : SystemDefinition
        The definition; its content (and :data:`~.build.BUILDER_VERSION`) makes the key.
    directory : str or os.PathLike, optional
        Where to look (default :data:`STATES_DIR`).

    Returns
    -------
    pathlib.Path or None

    Examples
    --------
    >>> from openmm_alphaprk.systems import find_shipped_state, load_definition, water_box_definition
    >>> find_shipped_state(load_definition("tip3p-2nm")).name
    'tip3p-2nm.json'
    >>> print(find_shipped_state(water_box_definition(2.0)))  # another content: none shipped
    None
    """
    key = shipped_key(definition)
    for record in sorted((STATES_DIR if directory is None else Path(directory)).glob("*.json")):
        if json.loads(record.read_text(encoding="utf-8")).get("key") == key:
            return record
    return None


def load_shipped_state(definition: SystemDefinition, directory: Path | None = None) -> ShippedState | None:
    """Return the shipped start state of ``definition`` with its System and topology made here.

    ``directory``: where to look (default :data:`STATES_DIR`). Returns None if no
    state is shipped for this definition's content. Warns (:class:`ShippedStateWarning`)
    and returns None if one is, but the topology built here from the definition
    differs from the one the state was built for.
    """
    record = find_shipped_state(definition, directory)
    if record is None:
        return None
    meta = json.loads(record.read_text(encoding="utf-8"))
    topology, _, forcefield = build_model(definition)
    fingerprint = topology_fingerprint(topology)
    if (topology.getNumAtoms(), fingerprint) != (meta["n_atoms"], meta["topology_sha256"]):
        warnings.warn(
            f"the shipped start state of {definition.name!r} ({record.with_suffix('.xml.gz').name}) was "
            f"built with OpenMM {meta['openmm_version']} for {meta['n_atoms']} atoms; OpenMM "
            f"{mm.__version__} builds {topology.getNumAtoms()} atoms"
            + (" in another order" if topology.getNumAtoms() == meta["n_atoms"] else "")
            + " from the same definition, so the shipped state is not used and the system is built here "
            "(its numbers will differ from the README's). Use the OpenMM version named above to start "
            "from the shipped state.",
            ShippedStateWarning,
            stacklevel=_stacklevel_outside_package(),
        )
        return None
    path = record.with_suffix(".xml.gz")
    with gzip.open(path, "rt", encoding="utf-8") as handle:
        state = mm.XmlSerializer.deserialize(handle.read())
    system = create_system(definition, topology, forcefield)
    return ShippedState(meta["key"], topology, system, state, path)


_PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep


def _stacklevel_outside_package() -> int:
    """Return the ``stacklevel`` (1: the caller of this function) of the first frame outside the package."""
    frame, level = sys._getframe(1), 1
    while frame.f_back is not None and os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE_DIR):
        frame, level = frame.f_back, level + 1
    return level
