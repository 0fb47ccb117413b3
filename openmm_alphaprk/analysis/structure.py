"""Oxygen–oxygen radial distribution function with MDAnalysis' own ``InterRDF``."""

from __future__ import annotations

from MDAnalysis.analysis.rdf import InterRDF

from .._units import InputError

#: Water oxygens in topologies written by OpenMM (TIP3P, SPC/E, TIP4P-Ew, Amber's HOH).
WATER_OXYGENS = "resname HOH WAT SOL and name O OW"


def oxygen_rdf(universe, select: str = WATER_OXYGENS, nbins: int = 100, r_max: float = 8.0) -> InterRDF:
    """Run ``InterRDF`` between water oxygens (same-molecule pairs excluded); distances in Å.

    Parameters
    ----------
    universe : MDAnalysis.Universe
        A trajectory with a periodic box.
    select : str, default WATER_OXYGENS
        The oxygens (:data:`WATER_OXYGENS`: those of the water models OpenMM writes).
    nbins : int, default 100
        Histogram bins.
    r_max : float, default 8.0
        Largest distance (Å); at most half the shortest box edge.

    Returns
    -------
    MDAnalysis.analysis.rdf.InterRDF
        Run: ``results.bins`` (Å) and ``results.rdf``.

    Raises
    ------
    ValueError
        If the trajectory has no periodic box (an RDF needs a volume) or the selection is empty.

    Examples
    --------
    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import run_nve
    >>> from openmm_alphaprk.runs.rundir import open_universe
    >>> folder = tempfile.TemporaryDirectory()
    >>> run = os.path.join(folder.name, "run")
    >>> _ = run_nve("tip3p-2nm", "rattle", run, steps=20, trajectory_interval=2, progress=False)
    >>> universe = open_universe(run)  # topology.pdb and trajectory.dcd: 10 frames
    >>> from openmm_alphaprk.analysis import oxygen_rdf
    >>> rdf = oxygen_rdf(universe, nbins=50)
    >>> rdf.results.bins.shape, round(float(rdf.results.bins[-1]), 2)  # bin centres, Å
    ((50,), 7.92)
    >>> peak = rdf.results.bins[rdf.results.rdf.argmax()]
    >>> bool(2.6 < peak < 3.0)  # the first shell of liquid water, at 2.8 Å
    True
    >>> folder.cleanup()
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
