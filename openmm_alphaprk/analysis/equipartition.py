"""Equipartition of the kinetic energy with physical_validation (Merz & Shirts, PLOS ONE 13 (2018) e0202764).

:class:`Equipartition` reads positions and velocities frame by frame (an MDAnalysis
``AnalysisBase``), splits each molecule's kinetic energy into translation, rotation and
internal motion with ``physical_validation.util.kinetic_energy.calc_molec_kinetic_energy``
and hands the result, in ``physical_validation``'s data classes, to its
``kinetic_energy.equipartition``. The temperature of each partition (whole system,
solute, solvent, random halves of the molecules) and its standard error are
``physical_validation``'s own estimate (``util.kinetic_energy.check_mean_std``: burn-in
and correlated frames dropped with pymbar, bootstrap error); see
:func:`partition_temperature`. Nothing of ``physical_validation`` is re-implemented
here, and nothing is read from or written to files.

``physical_validation`` is an optional dependency (``pip install
"openmm-alphaprk[validate]"``), imported when an analysis runs.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import warnings
from collections.abc import Sequence

import numpy as np
import openmm as mm
import openmm.unit as unit
from MDAnalysis.analysis.base import AnalysisBase
from MDAnalysis.analysis.results import ResultsGroup
from MDAnalysis.lib.distances import minimize_vectors

from .._units import InputError

#: physical_validation's names of the partitions of a molecule's kinetic energy.
PARTITIONS = ("total", "translational", "rotational and internal", "rotational", "internal")
#: Residue names of water: molecules made of them are the solvent, the others the solute.
SOLVENT_RESIDUES = ("HOH", "WAT", "SOL")
#: A deviation is flagged when as unlikely as 3 standard errors of a normal distribution (two-sided).
FLAG_SIGMAS = 3.0
#: Fewest frames with positions and velocities the temperature estimates are made from.
MIN_FRAMES = 20
#: Reference temperatures (K) below and above any partition's, at which
#: ``check_mean_std``'s distances give back its T(mu) and standard error.
_BRACKET_K = (1.0e-3, 1.0e5)
INSTALL_HINT = 'pip install "openmm-alphaprk[validate]"'


def import_physical_validation():
    """Return the ``physical_validation`` module, imported quietly (pymbar's notes on import silenced).

    Raises
    ------
    ImportError
        In one line naming ``pip install "openmm-alphaprk[validate]"`` when it is not installed.
    """
    pymbar_logger = logging.getLogger("pymbar")
    level = pymbar_logger.level
    pymbar_logger.setLevel(logging.ERROR)  # "JAX NOT FOUND", the timeseries module's warning on import
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import physical_validation
            import physical_validation.integrator  # noqa: F401
            import physical_validation.kinetic_energy  # noqa: F401
            import physical_validation.util.integrator  # noqa: F401
            import physical_validation.util.kinetic_energy  # noqa: F401
    except ImportError as error:
        raise ImportError(
            f"the physics validation needs physical_validation ({error}); install it with {INSTALL_HINT}."
        ) from None
    finally:
        pymbar_logger.setLevel(level)
    return physical_validation


def molecules_of(system: mm.System) -> list[list[int]]:
    """Return the System's molecules (atom indices), as OpenMM groups them (bonds and constraints).

    Parameters
    ----------
    system : openmm.System
        The System; its molecules are read from a Reference-platform Context.

    Examples
    --------
    >>> from openmm_alphaprk.systems import prepare_system
    >>> molecules = molecules_of(prepare_system("water-cluster", progress=False).system)
    >>> len(molecules), molecules[0]
    (74, [0, 1, 2])
    """
    context = mm.Context(system, mm.VerletIntegrator(0.001), mm.Platform.getPlatformByName("Reference"))
    try:
        return [sorted(molecule) for molecule in context.getMolecules()]
    finally:
        del context


def constraints_per_molecule(system: mm.System, molecules: Sequence[Sequence[int]]) -> np.ndarray:
    """Return how many of the System's constraints lie within each molecule."""
    owner = np.empty(system.getNumParticles(), dtype=np.intp)
    for index, molecule in enumerate(molecules):
        owner[list(molecule)] = index
    counts = np.zeros(len(molecules), dtype=int)
    for k in range(system.getNumConstraints()):
        i, _, _ = system.getConstraintParameters(k)
        counts[owner[i]] += 1
    return counts


def solvent_mask(resnames: Sequence[str], molecules: Sequence[Sequence[int]]) -> np.ndarray:
    """Return, per molecule, whether all its atoms are in water residues (:data:`SOLVENT_RESIDUES`)."""
    names = np.asarray(resnames)
    return np.array([bool(np.all(np.isin(names[list(m)], SOLVENT_RESIDUES))) for m in molecules], dtype=bool)


def random_halves(n_molecules: int, seed: int) -> tuple[list[int], list[int]]:
    """Return two halves of ``range(n_molecules)``, drawn with ``seed`` (the first has the odd one out)."""
    order = np.random.default_rng(seed).permutation(n_molecules)
    half = (n_molecules + 1) // 2
    return sorted(order[:half].tolist()), sorted(order[half:].tolist())


def partition_temperature(kinetic: Sequence[float], dof: float, bootstrap_seed: int) -> tuple[float, float]:
    """Return physical_validation's temperature T(mu) of a kinetic-energy series and its standard error (K).

    ``physical_validation.util.kinetic_energy.check_mean_std`` drops the burn-in and the
    correlated frames (pymbar), computes T(mu) = 2⟨K⟩/(N k_B) and its bootstrap error σ,
    and returns |T_ref − T(mu)| / σ. Called with the same bootstrap seed at two reference
    temperatures below and above any partition's, T_low and T_high, the two distances
    d_low, d_high give σ = (T_high − T_low) / (d_low + d_high) and T(mu) = T_low + d_low σ.

    Parameters
    ----------
    kinetic : sequence of float
        Kinetic energy of the partition per frame (kJ/mol).
    dof : float
        Its degrees of freedom.
    bootstrap_seed : int
        Seed of the bootstrap (numpy's global generator, which ``physical_validation`` seeds).

    Returns
    -------
    tuple of float
        T(mu) and its standard error (K); the error is NaN when too few uncorrelated frames remain.

    Examples
    --------
    Kinetic energies of 100 degrees of freedom at 300 K, drawn independently (χ², 2K/(k_B T) ~ χ²₁₀₀):

    >>> import numpy as np
    >>> kb = 0.0083144626  # kJ/mol/K
    >>> kinetic = 0.5 * kb * 300.0 * np.random.default_rng(1).chisquare(100, size=400)
    >>> temperature, error = partition_temperature(kinetic, 100, bootstrap_seed=0)
    >>> bool(abs(temperature - 300.0) < 3 * error), bool(0.5 < error < 3.0)  # σ ≈ 300 √(2/100) / √400 = 2.1
    (True, True)
    """
    pv = import_physical_validation()
    kb = pv.data.UnitData.units("GROMACS").kb
    low, high = _BRACKET_K
    distances = []
    with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a constant series: 0/0
        for reference in (low, high):
            distances.append(
                pv.util.kinetic_energy.check_mean_std(
                    kin=np.asarray(kinetic, dtype=float),
                    temp=reference,
                    ndof=dof,
                    kb=kb,
                    verbosity=0,
                    bs_repetitions=200,
                    bootstrap_seed=bootstrap_seed,
                    screen=False,
                    filename=None,
                    ene_unit=None,
                    temp_unit=None,
                    data_is_uncorrelated=False,
                )[0]
            )
    d_low, d_high = distances
    if not (np.isfinite(d_low) and np.isfinite(d_high)) or d_low + d_high <= 0:
        mean = 2.0 * float(np.mean(kinetic)) / (dof * kb)
        return mean, float("nan")
    sigma = (high - low) / (d_low + d_high)
    return float(low + d_low * sigma), float(sigma)


class Equipartition(AnalysisBase):
    """Temperature of each partition of the kinetic energy, with ``physical_validation``.

    Per frame, ``physical_validation.util.kinetic_energy.calc_molec_kinetic_energy``
    splits each molecule's kinetic energy into ``total``, ``translational``,
    ``rotational and internal``, ``rotational`` and ``internal`` (its names,
    :data:`PARTITIONS`); molecules are made whole across a periodic box first. At the end
    the per-molecule energies and degrees of freedom
    (``util.kinetic_energy.calc_ndof``) go into a ``physical_validation.data.SimulationData``
    (``UnitData.units("GROMACS")``: nm, ps, kJ/mol, K — OpenMM's; ``SystemData``,
    ``TrajectoryData``, ``ObservableData``, ``EnsembleData``) and
    ``physical_validation.kinetic_energy.equipartition`` is run on it; the temperature
    of each partition of each group and its error come from :func:`partition_temperature`.

    NVE runs have no thermostat temperature; physical_validation's equipartition check
    needs one, so the data are given as ``"NVT"`` at ``temperature`` (default: the whole
    system's own kinetic temperature, T(mu) of its ``total`` partition).

    Parameters
    ----------
    universe : MDAnalysis.Universe or MDAnalysis.AtomGroup
        A Universe whose trajectory has velocities (e.g. a TRR file), atoms in the System's order.
    masses : array_like of float
        Masses (amu) of the atoms.
    molecules : sequence of sequence of int
        Atom indices of each molecule (:func:`molecules_of`).
    constraints : array_like of int
        Constraints within each molecule (:func:`constraints_per_molecule`).
    groups : dict of str to list of int, optional
        Named groups of molecules (indices into ``molecules``) whose partitions are also
        tested, e.g. ``{"solute": [...], "solvent": [...]}``. The whole system is always tested.
    translation_removed : bool, default True
        Whether the centre-of-mass motion is not thermal (a ``CMMotionRemover``, or no
        external force: momentum conserved): 3 degrees of freedom less.
    rotation_removed : bool, default False
        Whether the overall rotation is not thermal (a cluster in vacuum: angular
        momentum conserved): 3 degrees of freedom less.
    temperature : float, optional
        Reference temperature (K) of the distances; default the system's own.
    bootstrap_seed : int, default 0
        Seed of physical_validation's bootstrap (reproducible errors).
    **kwargs
        Passed on to ``AnalysisBase`` (e.g. ``verbose``).

    Attributes
    ----------
    results.kinetic_energy_per_molecule : list of dict
        Per frame, physical_validation's per-molecule kinetic energies (kJ/mol) by partition.
    results.temperatures : dict
        ``{group: {partition: {"temperature_K", "standard_error_K", "dof",
        "frame_mean_temperature_K"}}}``: physical_validation's T(mu) and its error, and
        2⟨K⟩/(N k_B) over every frame; group ``"system"`` first; partitions without degrees
        of freedom are left out.
    results.temperature_K : float
        The reference temperature used (K).
    results.distances : dict
        ``{group: {partition: [d_mu, d_sigma]}}``, what ``kinetic_energy.equipartition``
        returned: |T_ref − T(mu)| and |T_ref − T(sigma)| in its standard errors.
    results.frames : int
        Frames read.

    Raises
    ------
    InputError
        If the trajectory has no velocities, the masses do not match the atoms, or there are
        fewer than :data:`MIN_FRAMES` frames.

    Examples
    --------
    Velocities of a short RATTLE run of the water cluster, kept in memory:

    >>> import MDAnalysis as mda, numpy as np, openmm as mm, openmm.unit as unit
    >>> from MDAnalysis.coordinates.memory import MemoryReader
    >>> from openmm_alphaprk import RattleIntegrator
    >>> from openmm_alphaprk.systems import prepare_system
    >>> prepared = prepare_system("water-cluster", progress=False)
    >>> reference = mm.Platform.getPlatformByName("Reference")
    >>> context = mm.Context(prepared.system, RattleIntegrator(0.002), reference)
    >>> context.setState(prepared.state)
    >>> frames = []
    >>> for _ in range(40):
    ...     context.getIntegrator().step(10)
    ...     state = context.getState(getPositions=True, getVelocities=True)
    ...     frames.append((state.getPositions(asNumpy=True).value_in_unit(unit.angstrom),
    ...                    state.getVelocities(asNumpy=True).value_in_unit(unit.angstrom / unit.picosecond)))
    >>> universe = mda.Universe.empty(prepared.n_atoms, trajectory=True)
    >>> universe.load_new(np.array([p for p, _ in frames]), velocities=np.array([v for _, v in frames]),
    ...                   format=MemoryReader)  # doctest: +ELLIPSIS
    <Universe with 222 atoms>
    >>> check = Equipartition.from_system(universe, prepared.system, resnames=["HOH"] * 222).run()
    >>> sorted(check.results.temperatures)
    ['half 1', 'half 2', 'system']
    >>> sorted(check.results.temperatures["system"])
    ['rotational', 'rotational and internal', 'total', 'translational']
    >>> t = check.results.temperatures["system"]["total"]
    >>> bool(200 < t["temperature_K"] < 300), round(t["dof"], 6)  # 3 x 222 - 222 constraints - 3 - 3
    (True, 438.0)
    """

    _analysis_algorithm_is_parallelizable = True

    @classmethod
    def get_supported_backends(cls) -> tuple[str, ...]:
        return ("serial", "multiprocessing")

    def __init__(
        self,
        universe,
        masses: Sequence[float],
        molecules: Sequence[Sequence[int]],
        constraints: Sequence[int],
        *,
        groups: dict[str, Sequence[int]] | None = None,
        translation_removed: bool = True,
        rotation_removed: bool = False,
        temperature: float | None = None,
        bootstrap_seed: int = 0,
        **kwargs,
    ):
        super().__init__(universe.universe.trajectory, **kwargs)
        self._atoms = universe.universe.atoms
        self._masses_all = np.asarray(masses, dtype=float)
        if len(self._masses_all) != len(self._atoms):
            raise InputError(
                f"{len(self._masses_all)} masses for {len(self._atoms)} atoms: the System and the "
                "trajectory do not match."
            )
        molecules = [list(m) for m in molecules]
        # physical_validation takes molecules as runs of consecutive atoms: order the atoms so
        self._order = np.array([i for m in molecules for i in m], dtype=np.intp)
        sizes = np.array([len(m) for m in molecules], dtype=np.intp)
        self._first = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp)
        self._owner_first = np.repeat(self._first, sizes)
        self._masses = self._masses_all[self._order]
        self._constraints = np.asarray(constraints, dtype=float)
        self._groups = {name: sorted(int(i) for i in group) for name, group in (groups or {}).items()}
        self._translation = 3.0 if translation_removed else 0.0
        self._rotation = 3.0 if rotation_removed else 0.0
        self._temperature = temperature
        self._seed = bootstrap_seed
        self._n_molecules = len(molecules)

    @classmethod
    def from_system(
        cls,
        universe,
        system: mm.System,
        *,
        resnames: Sequence[str] | None = None,
        halves_seed: int | None = 0,
        **kwargs,
    ) -> Equipartition:
        """Take masses, molecules and constraints from an OpenMM System, and build the groups.

        Groups: ``solute`` and ``solvent`` (molecules all of whose residues are water,
        :data:`SOLVENT_RESIDUES`; only when there is a solute and a solvent), and two random
        halves of the molecules (``half 1``, ``half 2``; ``halves_seed`` None: none).
        ``resnames``: the atoms' residue names (default: the universe's). Without a periodic
        box the overall rotation is taken as not thermal (angular momentum conserved).
        """
        molecules = molecules_of(system)
        masses = [
            system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())
        ]
        names = list(universe.universe.atoms.resnames) if resnames is None else list(resnames)
        solvent = solvent_mask(names, molecules)
        groups: dict[str, list[int]] = {}
        if solvent.any() and not solvent.all():
            groups["solute"] = np.flatnonzero(~solvent).tolist()
            groups["solvent"] = np.flatnonzero(solvent).tolist()
        if halves_seed is not None and len(molecules) >= 2:
            groups["half 1"], groups["half 2"] = random_halves(len(molecules), halves_seed)
        kwargs.setdefault("rotation_removed", not system.usesPeriodicBoundaryConditions())
        return cls(
            universe, masses, molecules, constraints_per_molecule(system, molecules), groups=groups, **kwargs
        )

    def _prepare(self):
        if not self._trajectory.ts.has_velocities:
            raise InputError("the trajectory has no velocities; give one with velocities (e.g. a TRR file).")
        self.results.kinetic_energy_per_molecule = []

    def _single_frame(self):
        pv = import_physical_validation()
        positions = self._atoms.positions[self._order].astype(float) / 10.0  # Å -> nm
        velocities = self._atoms.velocities[self._order].astype(float) / 10.0  # Å/ps -> nm/ps
        box = self._ts.dimensions
        if box is not None and np.all(box[:3] > 0):  # each molecule whole, around its first atom
            anchor = positions[self._owner_first]
            box_nm = np.concatenate([box[:3] / 10.0, box[3:]]).astype(np.float32)
            shift = minimize_vectors((positions - anchor).astype(np.float32), box_nm).astype(float)
            positions = anchor + shift
        self.results.kinetic_energy_per_molecule.append(
            pv.util.kinetic_energy.calc_molec_kinetic_energy(
                positions, velocities, self._masses, self._first, len(self._masses), self._n_molecules
            )
        )

    def _get_aggregator(self) -> ResultsGroup:
        return ResultsGroup(lookup={"kinetic_energy_per_molecule": ResultsGroup.flatten_sequence})

    def _conclude(self):
        pv = import_physical_validation()
        util = pv.util.kinetic_energy
        kinetic = self.results.kinetic_energy_per_molecule
        if len(kinetic) < MIN_FRAMES:  # here, after the workers' frames are joined
            raise InputError(
                f"{len(kinetic)} frames with velocities; the equipartition estimates need at least "
                f"{MIN_FRAMES} (more frames, or a smaller velocity interval)."
            )
        n_atoms, n_molecules = len(self._masses), self._n_molecules
        kb = pv.data.UnitData.units("GROMACS").kb
        dof_per_molecule = util.calc_ndof(
            n_atoms, n_molecules, self._first, self._constraints, self._translation, self._rotation
        )
        groups = {"system": None} | self._groups
        temperatures: dict[str, dict[str, dict[str, float]]] = {}
        for name, group in groups.items():
            dofs = util.group_ndof(dof_per_molecule, n_molecules, group)
            series = [util.group_kinetic_energy(frame, n_molecules, group) for frame in kinetic]
            temperatures[name] = {}
            for key in PARTITIONS:
                if dofs[key] < 1e-9:
                    continue
                values = [s[key] for s in series]
                t, error = partition_temperature(values, dofs[key], self._seed)
                temperatures[name][key] = {
                    "temperature_K": t,
                    "standard_error_K": error,
                    "dof": float(dofs[key]),
                    "frame_mean_temperature_K": 2.0 * float(np.mean(values)) / (dofs[key] * kb),
                }
        reference = self._temperature
        if reference is None:
            reference = temperatures["system"]["total"]["temperature_K"]
        self.results.temperatures = temperatures
        self.results.temperature_K = float(reference)
        self.results.frames = len(kinetic)
        self.results.distances = self._physical_validation_distances(
            pv, kinetic, dof_per_molecule, reference, temperatures
        )

    def _physical_validation_distances(self, pv, kinetic, dof_per_molecule, reference, temperatures) -> dict:
        """Run physical_validation's ``kinetic_energy.equipartition`` on the data; return its distances."""
        units = pv.data.UnitData.units("GROMACS")
        system = pv.data.SystemData(
            natoms=len(self._masses),
            nconstraints=float(np.sum(self._constraints)),
            ndof_reduction_tra=self._translation,
            ndof_reduction_rot=self._rotation,
            mass=self._masses,
            molecule_idx=self._first,
            nconstraints_per_molecule=self._constraints,
        )
        system.ndof_per_molecule = dof_per_molecule
        observables = pv.data.ObservableData()
        observables.kinetic_energy_per_molecule = kinetic
        # positions and velocities are not read again: the per-molecule energies above are passed in
        empty = np.zeros((1, len(self._masses), 3))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # NVT "with undefined volume"
            ensemble = pv.data.EnsembleData("NVT", natoms=len(self._masses), temperature=reference)
        data = pv.data.SimulationData(
            units=units,
            system=system,
            ensemble=ensemble,
            observables=observables,
            trajectory=pv.data.TrajectoryData(position=empty, velocity=empty),
        )
        names = list(self._groups)
        with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            flat = pv.kinetic_energy.equipartition(
                data,
                strict=False,
                molec_groups=[list(self._groups[name]) for name in names] or None,
                verbosity=0,
                bootstrap_seed=self._seed,
            )
        distances: dict[str, dict[str, list[float]]] = {}
        values = iter(flat)
        for name in ["system", *names]:
            distances[name] = {key: [float(d) for d in next(values)] for key in temperatures[name]}
        return distances


def flag_threshold(segments: int) -> float:
    """Return the |deviation| / error above which a partition is flagged, for ``segments`` segments.

    One segment: :data:`FLAG_SIGMAS` (a normal distribution). Several: the Student-t
    quantile with ``segments - 1`` degrees of freedom of the same two-sided probability
    (0.27 %), since the error is then estimated from the spread of a few segments.

    Examples
    --------
    >>> flag_threshold(1), round(flag_threshold(6), 2), round(flag_threshold(1000), 2)
    (3.0, 5.51, 3.01)
    """
    from scipy.stats import norm, t

    if segments < 2:
        return FLAG_SIGMAS
    return float(t.ppf(norm.cdf(FLAG_SIGMAS), segments - 1))


def combine_segments(temperatures: Sequence[dict], frames: Sequence[int] | None = None) -> dict:
    """Combine the partition temperatures of independent segments of one setting, with their errors.

    Each partition's deviation is its temperature minus the whole system's (``"system"``,
    ``"total"``) in the same segment. With several segments, a segment's temperature is
    2⟨K⟩/(N k_B) over all its frames (``frame_mean_temperature_K``, where given: every
    partition from the same frames, so they add up to the whole), the temperature and the
    deviation are means over the segments and their errors the standard errors of those
    means (the spread between segments); with one, they are physical_validation's T(mu)
    and its error (from the decorrelated frames it keeps, which it chooses for each
    partition on its own; the deviation's error: both in quadrature, which overstates it
    a little, the partition being part of the whole).

    Parameters
    ----------
    temperatures : sequence of dict
        ``results.temperatures`` of an :class:`Equipartition` per segment.
    frames : sequence of int, optional
        Frames of each segment, kept in the result.

    Returns
    -------
    dict
        ``segments``, ``error_source`` (``"segments"`` or ``"physical_validation"``),
        ``flag_threshold`` (:func:`flag_threshold`), ``frames`` and ``groups``:
        ``{group: {partition: {"temperature_K", "standard_error_K", "dof", "deviation_K",
        "deviation_error_K", "deviation_in_errors", "segment_temperatures_K"}}}``.

    Examples
    --------
    >>> one = {"system": {"total": {"temperature_K": 300.0, "standard_error_K": 1.0, "dof": 9.0},
    ...                   "rotational": {"temperature_K": 310.0, "standard_error_K": 2.0, "dof": 3.0}}}
    >>> two = {"system": {"total": {"temperature_K": 302.0, "standard_error_K": 1.0, "dof": 9.0},
    ...                   "rotational": {"temperature_K": 314.0, "standard_error_K": 2.0, "dof": 3.0}}}
    >>> rotation = combine_segments([one, two])["groups"]["system"]["rotational"]
    >>> [rotation[key] for key in ("temperature_K", "standard_error_K", "deviation_K", "deviation_error_K")]
    [312.0, 2.0, 11.0, 1.0]
    """
    if not temperatures:
        raise InputError("no segments to combine.")
    n = len(temperatures)
    groups: dict[str, dict[str, dict]] = {}
    for group, partitions in temperatures[0].items():
        groups[group] = {}
        for partition, first in partitions.items():
            key = (
                "frame_mean_temperature_K"
                if n > 1 and "frame_mean_temperature_K" in first
                else "temperature_K"
            )
            values = np.array([t[group][partition][key] for t in temperatures])
            whole = np.array([t["system"]["total"][key] for t in temperatures])
            deviations = values - whole
            if n > 1:
                error = float(np.std(values, ddof=1) / np.sqrt(n))
                deviation_error = float(np.std(deviations, ddof=1) / np.sqrt(n))
            else:
                error = float(first["standard_error_K"])
                whole_error = float(temperatures[0]["system"]["total"]["standard_error_K"])
                deviation_error = (
                    0.0 if (group, partition) == ("system", "total") else math.hypot(error, whole_error)
                )
            deviation = float(np.mean(deviations))
            if deviation_error > 0:
                in_errors = deviation / deviation_error
            else:  # the whole system against itself: 0
                in_errors = 0.0 if deviation == 0 else float("nan")
            groups[group][partition] = {
                "temperature_K": float(np.mean(values)),
                "standard_error_K": error,
                "dof": float(first["dof"]),
                "deviation_K": deviation,
                "deviation_error_K": deviation_error,
                "deviation_in_errors": in_errors,
                "segment_temperatures_K": values.tolist(),
            }
    return {
        "segments": n,
        "error_source": "segments" if n > 1 else "physical_validation",
        "flag_threshold": flag_threshold(n),
        "frames": list(frames) if frames is not None else None,
        "groups": groups,
    }


def compare_settings(setting: dict, reference: dict) -> dict:
    """Return each partition temperature of ``setting`` minus the ``reference``'s, with the combined error.

    Both are :func:`combine_segments` results; partitions present in both are compared:
    ``{group: {partition: {"difference_K", "error_K", "in_errors"}}}``.

    Parameters
    ----------
    setting : dict
        The setting's :func:`combine_segments` result.
    reference : dict
        The reference's, the same way.

    Examples
    --------
    >>> a = {"groups": {"system": {"total": {"temperature_K": 303.0, "standard_error_K": 3.0}}}}
    >>> b = {"groups": {"system": {"total": {"temperature_K": 299.0, "standard_error_K": 4.0}}}}
    >>> compare_settings(a, b)
    {'system': {'total': {'difference_K': 4.0, 'error_K': 5.0, 'in_errors': 0.8}}}
    """
    out: dict[str, dict[str, dict[str, float]]] = {}
    for group, partitions in setting["groups"].items():
        for partition, value in partitions.items():
            ref = reference["groups"].get(group, {}).get(partition)
            if ref is None:
                continue
            difference = value["temperature_K"] - ref["temperature_K"]
            error = math.hypot(value["standard_error_K"], ref["standard_error_K"])
            out.setdefault(group, {})[partition] = {
                "difference_K": difference,
                "error_K": error,
                "in_errors": difference / error if error > 0 else float("nan"),
            }
    return out
