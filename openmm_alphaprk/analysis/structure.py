"""Oxygen–oxygen radial distribution function with MDAnalysis' own ``InterRDF``."""

from __future__ import annotations

from MDAnalysis.analysis.rdf import InterRDF

from .._units import InputError

#: Water oxygens in topologies written by OpenMM (TIP3P, SPC/E, TIP4P-Ew, Amber's HOH).
WATER_OXYGENS = "resname HOH WAT SOL and name O OW"


def oxygen_rdf(universe, select: str = WATER_OXYGENS, nbins: int = 100, r_max: float = 8.0) -> InterRDF:
    """Run ``InterRDF`` between water oxygens (same-molecule pairs excluded); distances in Å.

    Raises
    ------
    ValueError
        If the trajectory has no periodic box (an RDF needs a volume) or the selection is empty.
    """
    if universe.dimensions is None:
        raise InputError("the trajectory has no periodic box; an RDF needs a volume (skip it for clusters).")
    oxygens = universe.select_atoms(select)
    if len(oxygens) < 2:
        raise InputError(f"selection {select!r} matches {len(oxygens)} atom(s); need water oxygens.")
    half_box = 0.5 * min(universe.dimensions[:3])
    return InterRDF(
        oxygens, oxygens, nbins=nbins, range=(0.0, min(r_max, half_box)), exclusion_block=(1, 1)
    ).run()
