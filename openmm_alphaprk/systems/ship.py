"""Write the package's shipped start states (for its maintainers, after a definition changed).

``python -m openmm_alphaprk.systems.ship NAME ...`` builds the named systems (minimize,
equilibrate) and writes ``NAME.xml.gz`` and ``NAME.json`` into ``states/``, which
:mod:`.shipped` reads.
"""

from __future__ import annotations

import argparse
import gzip
import json
import tempfile
from collections.abc import Sequence
from pathlib import Path

import openmm as mm

from .build import BUILDER_VERSION
from .cache import PreparedSystem, prepare_system
from .definitions import load_definition
from .shipped import STATES_DIR, shipped_key, topology_fingerprint


def write_shipped_state(prepared: PreparedSystem, directory: Path | None = None) -> Path:
    """Write ``prepared``'s start state as ``NAME.xml.gz`` and its record ``NAME.json`` in ``directory``.

    ``directory`` defaults to :data:`STATES_DIR`. The gzip header carries no time
    stamp, so the same state gives the same bytes. Returns the path of the
    ``.xml.gz`` file.
    """
    directory = STATES_DIR if directory is None else Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    name = prepared.definition.name
    path = directory / f"{name}.xml.gz"
    xml = mm.XmlSerializer.serialize(prepared.state).encode("utf-8")
    with tempfile.NamedTemporaryFile(dir=directory, delete=False) as raw:
        with gzip.GzipFile(filename="", mode="wb", fileobj=raw, compresslevel=9, mtime=0) as handle:
            handle.write(xml)
    Path(raw.name).chmod(0o644)  # NamedTemporaryFile makes it private; package data is world-readable
    Path(raw.name).replace(path)
    meta = {
        "name": name,
        "key": shipped_key(prepared.definition),
        "definition": prepared.definition.as_dict(),
        "builder_version": BUILDER_VERSION,
        "openmm_version": mm.__version__,
        "n_atoms": prepared.n_atoms,
        "topology_sha256": topology_fingerprint(prepared.topology),
    }
    (directory / f"{name}.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
    return path


def main(argv: Sequence[str] | None = None) -> int:
    """Build the named systems and write their shipped states (``python -m`` this module)."""
    parser = argparse.ArgumentParser(
        prog="python -m openmm_alphaprk.systems.ship",
        description="Build systems from their definitions (minimize, equilibrate) and write their start "
        "states as the package's shipped states.",
    )
    parser.add_argument("systems", nargs="+", help="system names or .toml paths")
    parser.add_argument("--output", type=Path, default=None, help=f"folder (default {STATES_DIR})")
    parser.add_argument("--cache-dir", default=None, help="cache the builds there too (default: not cached)")
    args = parser.parse_args(argv)
    for name in args.systems:
        definition = load_definition(name)
        prepared = prepare_system(
            definition,
            cache_dir=args.cache_dir,
            use_cache=args.cache_dir is not None,
            rebuild=True,
            progress=True,
        )
        path = write_shipped_state(prepared, args.output)
        print(f"{definition.name}: {prepared.n_atoms} atoms -> {path} ({path.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
