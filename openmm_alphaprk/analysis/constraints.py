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
    universe
        Universe (or AtomGroup of it) whose atom indices match the System's.
    pairs
        (k, 2) atom indices of the constrained pairs.
    lengths
        (k,) constraint lengths in nm.

    Attributes
    ----------
    results.max_relative_deviation
        Per frame, max |r − d| / d.
    results.rms_relative_deviation
        Per frame, RMS of (r − d) / d.
    results.max_abs_deviation_nm
        Per frame, max |r − d| in nm.
    results.overall_max_relative_deviation
        Max over all frames.
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
