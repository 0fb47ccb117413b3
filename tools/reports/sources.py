"""Where the documentation's numbers come from: the files under ``docs/data/`` and their provenance.

Every measured number of a page is read from a file of ``docs/data/<page>/``;
``docs/data/provenance.toml`` gives each file the day and commit it was added at and the
machine it ran on, which the generators print beside the numbers they take.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from functools import cache
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # the package depends on tomli there
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
DATA = DOCS / "data"
PROVENANCE = DATA / "provenance.toml"
#: Files of docs/data/ that are about the data, not data.
NOT_DATA = ("provenance.toml", "README.md")


@dataclass(frozen=True)
class Source:
    """One data file: its path under docs/data/, the day and commit it was added at, the machine."""

    path: str
    date: str
    commit: str
    machine: str

    def cite(self) -> str:
        """Return how a page names it: ``docs/data/PATH, measured DATE (commit COMMIT)``."""
        return f"`docs/data/{self.path}`, {self.date} (commit {self.commit})"


@cache
def provenance() -> dict:
    """Return docs/data/provenance.toml as read."""
    return tomllib.loads(PROVENANCE.read_text(encoding="utf-8"))


def data_files() -> list[str]:
    """Return every data file under docs/data/, as a path relative to it."""
    return sorted(
        path.relative_to(DATA).as_posix()
        for path in DATA.rglob("*")
        if path.is_file() and path.name not in NOT_DATA
    )


def source(path: str) -> Source:
    """Return the provenance of the data file ``path`` (relative to docs/data/)."""
    table = provenance()
    entry = table[path]
    return Source(path, entry["date"], entry["commit"], table["machines"][entry["machine"]])


def load(path: str) -> tuple[dict, Source]:
    """Return the JSON file ``path`` (relative to docs/data/) and its provenance."""
    return json.loads((DATA / path).read_text(encoding="utf-8")), source(path)
