"""The one schema of the benchmarks' rows: every row names its integrator as the registry does.

A row written to a benchmark's JSON file is a dict of its measurements with ``name`` (the
label a table shows), ``integrator`` (the registry's canonical name,
``parse_integrator(name).name``) and ``divisor`` (k of a row run at h/k; 1 otherwise), so
that the documentation's tables find a row by the integrator's name, not by its label.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence

from ..runs.integrator_names import label, parse_integrator


def keyed_rows(rows: Iterable[Mapping], names: Sequence[str]) -> list[dict]:
    """Return ``rows`` (dicts with a ``name`` label) with ``integrator`` and ``divisor`` added.

    Parameters
    ----------
    rows : iterable of mapping
        The rows, each with the label it was run under as ``name``.
    names : sequence of str
        The integrator names the rows were run from; a row labelled ``LABEL h/k`` is the
        integrator of ``LABEL`` at h/k.

    Returns
    -------
    list of dict
        The rows with ``integrator`` (None for a label of none of ``names``) and ``divisor``.

    Examples
    --------
    >>> [(row["integrator"], row["divisor"]) for row in keyed_rows([{"name": "RATTLE h/9"}], ["rattle"])]
    [('rattle', 9)]
    """
    by_label = {label(name): parse_integrator(name).name for name in names}
    keyed = []
    for row in rows:
        found = re.fullmatch(r"(?P<label>.+) h/(?P<k>\d+)", row["name"])
        base, divisor = (found["label"], int(found["k"])) if found else (row["name"], 1)
        keyed.append({**row, "integrator": by_label.get(base), "divisor": divisor})
    return keyed
