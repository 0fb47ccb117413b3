"""Constraint-length deviation per frame (an MDAnalysis ``AnalysisBase``)."""

from __future__ import annotations

import numpy as np
import openmm as mm
from MDAnalysis.analysis.base import AnalysisBase
from MDAnalysis.lib.distances import calc_bonds

from .._units import InputError
from ..observables import system_constraints


class ConstraintDeviation(AnalysisBase):
    """Deviation of constrained distances from their lengths, frame by frame.

    The lengths are the ones OpenMM enforces: the System's constraints (for water,
    the force field's rigid geometry; for ``HBonds``, the bond lengths). Distances use
    the minimum image when the frame has a box. DCD files store single-precision
    Ångström coordinates, which limits what can be resolved to ~1e-6 relative.

    Parameters
    ----------
    universe : MDAnalysis.Universe or MDAnalysis.AtomGroup
        Universe (or AtomGroup of it) whose atom indices match the System's.
    pairs : array_like of int
        (k, 2) atom indices of the constrained pairs.
    lengths : array_like of float
        (k,) constraint lengths in nm.
    **kwargs
        Passed on to ``AnalysisBase`` (e.g. ``verbose``).

    Attributes
    ----------
    results.max_relative_deviation : numpy.ndarray
        Per frame, max |r − d| / d.
    results.rms_relative_deviation : numpy.ndarray
        Per frame, RMS of (r − d) / d.
    results.max_abs_deviation_nm : numpy.ndarray
        Per frame, max |r − d| in nm.
    results.overall_max_relative_deviation : float
        Max over all frames.

    Examples
    --------
    The constraints of the 2 nm water box over a short RATTLE run:

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import run_nve
    >>> from openmm_alphaprk.runs.rundir import open_universe
    >>> folder = tempfile.TemporaryDirectory()
    >>> run = os.path.join(folder.name, "run")
    >>> _ = run_nve("tip3p-2nm", "rattle", run, steps=20, trajectory_interval=2, progress=False)
    >>> universe = open_universe(run)  # topology.pdb and trajectory.dcd: 10 frames
    >>> from openmm_alphaprk.analysis import ConstraintDeviation
    >>> from openmm_alphaprk.systems import prepare_system
    >>> deviation = ConstraintDeviation.from_system(universe, prepare_system("tip3p-2nm").system).run()
    >>> deviation.results.max_relative_deviation.shape
    (10,)
    >>> bool(deviation.results.overall_max_relative_deviation < 1e-5)  # float32 DCD: ~1e-6 resolved
    True
    >>> folder.cleanup()
    """

    def __init__(self, universe, pairs: np.ndarray, lengths: np.ndarray, **kwargs):
        super().__init__(universe.universe.trajectory, **kwargs)
        self._atoms = universe.universe.atoms
        self._pairs = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
        self._lengths = np.asarray(lengths, dtype=float)
        if len(self._pairs) != len(self._lengths):
            raise InputError(f"{len(self._pairs)} pairs but {len(self._lengths)} lengths.")
        if len(self._pairs) and self._pairs.max() >= len(self._atoms):
            raise InputError(
                f"constraint atom index {self._pairs.max()} is beyond the {len(self._atoms)} atoms of the "
                "universe: the System and the trajectory do not match."
            )

    @classmethod
    def from_system(cls, universe, system: mm.System, **kwargs) -> ConstraintDeviation:
        """Take the constraints of an OpenMM System."""
        return cls(universe, *system_constraints(system), **kwargs)

    def _prepare(self):
        self.results.max_relative_deviation = np.zeros(self.n_frames)
        self.results.rms_relative_deviation = np.zeros(self.n_frames)
        self.results.max_abs_deviation_nm = np.zeros(self.n_frames)

    def _single_frame(self):
        if not len(self._pairs):
            return
        positions = self._atoms.positions
        distances = (
            calc_bonds(positions[self._pairs[:, 0]], positions[self._pairs[:, 1]], box=self._ts.dimensions)
            / 10.0
        )
        deviation = distances - self._lengths
        relative = deviation / self._lengths
        self.results.max_relative_deviation[self._frame_index] = np.max(np.abs(relative))
        self.results.rms_relative_deviation[self._frame_index] = np.sqrt(np.mean(relative**2))
        self.results.max_abs_deviation_nm[self._frame_index] = np.max(np.abs(deviation))

    def _conclude(self):
        values = self.results.max_relative_deviation
        self.results.overall_max_relative_deviation = float(values.max()) if len(values) else float("nan")
