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


def link(path: str, data: str = "data/") -> str:
    """Return a Markdown link to the data file ``path``; ``data`` is the path from the page to docs/data/."""
    return f"[{path.split('/')[-1]}]({data}{path})"


def provenance_line(sources: list[Source], run: str, data: str = "data/") -> str:
    """One line a person can read: the run, where and when it ran, and a link to each data file."""
    days = sorted({s.date for s in sources})
    machines = sorted({s.machine for s in sources})
    when = days[0] if len(days) == 1 else f"{days[0]} to {days[-1]}"
    files = ", ".join(link(s.path, data) for s in sources)
    return f"{run}; {' and '.join(machines)}, {when}. Data: {files}."


# ------------------------------------------------------------------ the rows' one schema
def pick(rows: list[dict], name: str, divisor: int = 1, labelled: str | None = None, **match) -> dict:
    """Return the one row of ``rows`` of the integrator ``name`` at h/``divisor`` (and the ``match`` fields).

    A row is the integrator's if its spec parses to ``name`` in the registry or, in files written
    before the rows carried their spec, if its ``name`` is the registry's label of ``name`` (or
    ``labelled``, the label the file was written with where the registry's has changed since).
    """
    from openmm_alphaprk.runs.integrator_names import label

    wanted = parse_name(name)
    try:
        labels = {label(name), labelled}
    except ValueError:
        labels = {labelled}

    def named(row: dict) -> bool:
        spec = row.get("integrator")
        return (
            parse_name(spec) == wanted
            if isinstance(spec, str)
            else spec is None and row.get("name") in labels
        )

    found = [
        row
        for row in rows
        if named(row) and row.get("divisor", 1) == divisor and all(row.get(k) == v for k, v in match.items())
    ]
    if len(found) != 1:
        raise LookupError(f"{len(found)} rows of {name} at h/{divisor} {match or ''}")
    return found[0]


def parse_name(name: str) -> str:
    """Return the registry's spelling of ``name`` (as written if the registry no longer reads it)."""
    from openmm_alphaprk.runs.integrator_names import parse_integrator

    try:
        return parse_integrator(name).name
    except ValueError:  # a name of the day the data were written
        return name
