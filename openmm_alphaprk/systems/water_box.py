"""Water boxes of any size, built by the same builder as the named systems (not cached).

:func:`water_box_definition` turns its arguments into a ``water_box`` definition and
:func:`build_water_box` runs it through :func:`~openmm_alphaprk.systems.prepare_system`
without the cache: the
boxes of the tests and benchmarks and the named boxes (``tip3p-3nm`` …) come from one
builder, ForceField + Modeller, :func:`~openmm_alphaprk.make_smooth`'s settings and
the same minimization and Langevin protocol.
"""

from __future__ import annotations

import openmm.unit as unit

from .._units import InputError, to_float
from .cache import PreparedSystem, prepare_system
from .definitions import SystemDefinition, parse_definition

#: Equilibration of :func:`build_water_box` (seed, temperature, steps and platform: its arguments).
EQUILIBRATION = {
    "minimize_tolerance_kJ_per_mol_nm": 10.0,
    "minimize_max_iterations": 500,
    "langevin_timestep_fs": 2.0,
    "langevin_friction_per_ps": 5.0,
}


def build_water_box(box_size: unit.Quantity | float = 3.0, **options: object) -> PreparedSystem:
    """Build, minimize and briefly equilibrate a cubic box of rigid water with PME.

    The box of :func:`water_box_definition` with the same arguments (``box_size``,
    ``model``, ``cutoff``, ``switch_distance``, ``ewald_error_tolerance``,
    ``temperature``, ``equilibration_steps``, ``seed``, ``platform``), built without
    the cache.

    Parameters
    ----------
    box_size : openmm.unit.Quantity or float, default 3.0
        Edge of the cubic box (nm).
    **options
        The keyword arguments of :func:`water_box_definition`.

    Returns
    -------
    PreparedSystem
        With ``removeCMMotion=False`` (NVE bookkeeping), constrained positions and
        velocities satisfying the velocity constraints (``.positions`` in nm and
        ``.velocities`` in nm/ps as arrays).

    Notes
    -----
    The defaults make the forces smooth at the cutoff, as an energy-conservation
    study needs (with OpenMM's defaults the energy error of a water box is pairs
    crossing the cutoff, not the integrator's; see :mod:`openmm_alphaprk.smooth_forces`).

    Examples
    --------
    A 1.5 nm box with a 0.7 nm cutoff, 10 Langevin steps after the minimization (2–4 s
    on two cores, nearly all of it the minimization):

    >>> import openmm.unit as unit
    >>> from openmm_alphaprk import smoothness_problems
    >>> from openmm_alphaprk.systems import build_water_box
    >>> box = build_water_box(1.5 * unit.nanometers, cutoff=0.7, equilibration_steps=10)
    >>> box.name, box.source, box.n_atoms
    ('tip3p-box-1.5nm', 'built', 306)
    >>> smoothness_problems(box.system)
    []
    """
    return prepare_system(water_box_definition(box_size, **options), use_cache=False)


def water_box_definition(
    box_size: unit.Quantity | float = 3.0,
    *,
    model: str = "tip3p",
    cutoff: unit.Quantity | float = 0.9,
    switch_distance: unit.Quantity | float | None = "auto",
    ewald_error_tolerance: float = 1e-5,
    temperature: unit.Quantity | float = 300.0,
    equilibration_steps: int = 500,
    seed: int = 2024,
    platform: str = "CPU",
) -> SystemDefinition:
    """Return the definition of a cubic PME box of rigid water, named ``MODEL-box-EDGEnm``.

    :func:`build_water_box` builds it; with the definition alone a caller can look for a
    stored start state of the box (:func:`~openmm_alphaprk.systems.shipped.load_shipped_state`
    with a folder) before spending the minimization and equilibration.

    Parameters
    ----------
    box_size : openmm.unit.Quantity or float, default 3.0
        Edge of the cubic box (nm).
    model : str, default "tip3p"
        Water model known to OpenMM's ForceField and Modeller ('tip3p', 'spce', 'tip4pew').
    cutoff : openmm.unit.Quantity or float, default 0.9
        Direct-space cutoff (nm); must be below half the box edge.
    switch_distance : openmm.unit.Quantity or float or "auto" or None, default "auto"
        Where the Lennard-Jones switching function starts (nm); ``"auto"`` (the
        default) is cutoff − 0.1 nm, ``None`` switches it off (plain truncation).
    ewald_error_tolerance : float, default 1e-5
        PME's ``setEwaldErrorTolerance`` (OpenMM's default is 5e-4).
    temperature : openmm.unit.Quantity or float, default 300.0
        Langevin equilibration temperature (K).
    equilibration_steps : int, default 500
        2 fs Langevin steps after minimization (friction 5/ps).
    seed : int, default 2024
        Seed of the velocity initialisation and the Langevin thermostat.
    platform : str, default "CPU"
        OpenMM platform used for the set-up.

    Returns
    -------
    SystemDefinition

    Raises
    ------
    InputError
        For a non-positive length, temperature or tolerance, or a ``switch_distance``
        that is no length, None or "auto"; its subclass
        :class:`~openmm_alphaprk.systems.DefinitionError` for a cutoff of half the edge
        or more, or a switch at or beyond the cutoff.

    Examples
    --------
    >>> import openmm.unit as unit
    >>> from openmm_alphaprk.systems import water_box_definition
    >>> definition = water_box_definition(2.5 * unit.nanometers, model="spce", equilibration_steps=1000)
    >>> definition.name
    'spce-box-2.5nm'
    >>> definition.build["cutoff_nm"], definition.build["switch_distance_nm"]
    (0.9, 0.8)
    >>> definition.equilibration["langevin_steps"], definition.equilibration["temperature_K"]
    (1000, 300.0)
    """
    edge = to_float(box_size, unit.nanometers, "box_size", positive=True)
    rc = to_float(cutoff, unit.nanometers, "cutoff", positive=True)
    # the ranges (cutoff below half the edge, switch below the cutoff) are parse_definition's checks
    build = _build_table(model, edge, rc, _switch_distance(switch_distance, rc), ewald_error_tolerance)
    kelvin = to_float(temperature, unit.kelvin, "temperature", positive=True)
    equilibration = {**EQUILIBRATION, "seed": int(seed), "temperature_K": kelvin, "platform": platform}
    equilibration["langevin_steps"] = int(equilibration_steps)
    return parse_definition({"build": build, "equilibration": equilibration}, f"{model}-box-{edge:g}nm")


def _build_table(model: str, edge: float, cutoff: float, switch: float | None, ewald: object) -> dict:
    """Return the ``[build]`` table of a PME water box definition."""
    build = {
        "kind": "water_box",
        "forcefield": [f"{model}.xml"],
        "water_model": model,
        "box_edge_nm": edge,
        "nonbonded_method": "PME",
        "cutoff_nm": cutoff,
        "ewald_error_tolerance": to_float(ewald, unit.dimensionless, "ewald_error_tolerance", positive=True),
        "constraints": "HBonds",
    }
    if switch is not None:
        build["switch_distance_nm"] = switch
    return build


def _switch_distance(switch_distance: object, cutoff: float) -> float | None:
    """Return the LJ switch distance (nm) for ``"auto"`` (cutoff − 0.1 nm), a length, or None."""
    if isinstance(switch_distance, str):
        if switch_distance != "auto":
            raise InputError(f"switch_distance must be a length, None or 'auto', got {switch_distance!r}.")
        return max(cutoff - 0.1, 0.5 * cutoff)
    if switch_distance is None:
        return None
    return to_float(switch_distance, unit.nanometers, "switch_distance")
