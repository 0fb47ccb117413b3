"""Oxygen–oxygen radial distribution function with MDAnalysis' own ``InterRDF``."""

from __future__ import annotations

import numpy as np
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


def first_peak(
    r: object, g: object, r_min: float | None = None, r_max: float | None = None
) -> tuple[float, float]:
    """Position and height of the first peak of a g(r): the highest bin, refined by a parabola.

    Takes the highest bin of ``g`` in ``[r_min, r_max]`` (for water's O–O g(r) the first
    peak, near 2.8 Å, is the highest; pass ``r_max`` to look at one shell only) and fits the
    parabola through it and its two neighbours (``r`` evenly spaced): with spacing h and
    values g₋, g₀, g₊, the vertex is at r₀ + h (g₋ − g₊) / (2 (g₋ − 2 g₀ + g₊)) with height
    g₀ − (g₊ − g₋)² / (8 (g₋ − 2 g₀ + g₊)). Exact for a parabola; for a smooth peak sampled
    with a few bins across its width, much closer than the bin centre (error O(h²)). If the
    highest bin is the first or last of the window, or the three points are not concave,
    that bin's centre and value are returned unrefined.

    Parameters
    ----------
    r : array_like of float
        Bin centres, increasing and evenly spaced (e.g. ``InterRDF``'s ``results.bins``, Å).
    g : array_like of float
        g(r) on ``r``.
    r_min, r_max : float, optional
        The window (same unit as ``r``, inclusive); ``None``: no limit.

    Returns
    -------
    tuple of (float, float)
        The peak's position (unit of ``r``) and height.

    Raises
    ------
    InputError
        If ``r`` and ``g`` differ in shape, hold fewer than three points, ``r`` is not
        evenly spaced and increasing, or the window holds no bin.

    Examples
    --------
    A Gaussian peak at 2.79 Å on 0.1 Å bins, whose highest bin is at 2.75 Å:

    >>> import numpy as np
    >>> from openmm_alphaprk.analysis import first_peak
    >>> r = np.arange(0.05, 8.0, 0.1)
    >>> g = 1.0 + 2.0 * np.exp(-0.5 * ((r - 2.79) / 0.15) ** 2)
    >>> position, height = first_peak(r, g)
    >>> round(position, 3), round(height, 3)  # the highest bin: 2.75 Å, 2.930
    (2.788, 2.983)
    """
    r = np.asarray(r, dtype=float)
    g = np.asarray(g, dtype=float)
    if r.shape != g.shape or r.ndim != 1 or len(r) < 3:
        raise InputError(f"r {r.shape} and g {g.shape} must be equal 1-D arrays of at least 3 points.")
    spacing = np.diff(r)
    h = float(spacing.mean())
    if not (h > 0 and np.allclose(spacing, h, rtol=1e-6, atol=0.0)):
        raise InputError("r must be increasing and evenly spaced (bin centres of a histogram).")
    window = np.ones(len(r), dtype=bool)
    if r_min is not None:
        window &= r >= r_min
    if r_max is not None:
        window &= r <= r_max
    indices = np.flatnonzero(window & np.isfinite(g))
    if len(indices) == 0:
        raise InputError(f"no bin of r ({r[0]:.4g} to {r[-1]:.4g}) lies in [{r_min}, {r_max}].")
    top = int(indices[np.argmax(g[indices])])
    if top - 1 not in indices or top + 1 not in indices:
        return float(r[top]), float(g[top])
    below, centre, above = g[top - 1], g[top], g[top + 1]
    curvature = below - 2.0 * centre + above
    if not curvature < 0:
        return float(r[top]), float(g[top])
    position = r[top] + h * (below - above) / (2.0 * curvature)
    height = centre - (above - below) ** 2 / (8.0 * curvature)
    return float(position), float(height)
