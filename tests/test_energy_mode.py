"""The energy-preserving mode (AlphaRattleEnergyIntegrator): energy, invariants, controller
robustness, restarts, diagnostics and errors."""

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit
import pytest
from conftest import REFERENCE, constraint_errors, make_context, positions_of, total_energy, velocities_of

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    ControllerSettings,
    RattleIntegrator,
)
from openmm_alphaprk.reference import angular_momentum, to_openmm_system, water_cluster
from openmm_alphaprk.runs.reporters import (
    COLUMNS,
    AlphaControllerReporter,
    read_controller_csv,
    summarize_controller,
)


def _cluster_context(integrator, seed=5):
    problem, x0, v0 = water_cluster(8, spacing=0.3, seed=seed)
    ctx = make_context(to_openmm_system(problem), integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
    ctx.applyConstraints(1e-12)
    ctx.applyVelocityConstraints(1e-12)
    return problem, ctx


def _residuals(ctx, integrator, steps, e_ref):
    """H − e_ref from the context after every step, and the integrator's own residuals."""
    measured, claimed, fell_back = [], [], []
    for _ in range(steps):
        integrator.step(1)
        measured.append(total_energy(ctx) - e_ref)
        if getattr(integrator, "energy_mode", False):
            claimed.append(integrator.energy_residual.value_in_unit(unit.kilojoules_per_mole))
            fell_back.append(integrator.fell_back)
    return np.array(measured), np.array(claimed), np.array(fell_back, dtype=bool)


@pytest.mark.parametrize("order", [2, 4])
def test_energy_mode_keeps_angular_momentum_to_round_off_by_default_without_a_box(order):
    """Without a periodic box the default midpoint tolerance keeps L (the defaults left 5e-8 at order 2)."""
    integrator = AlphaRattleEnergyIntegrator(0.002, order=order, constraint_tolerance=1e-12)
    problem, ctx = _cluster_context(integrator)
    integrator.check_context(ctx)
    l0 = angular_momentum(problem, positions_of(ctx).ravel(), velocities_of(ctx).ravel())
    integrator.step(200)
    change = angular_momentum(problem, positions_of(ctx).ravel(), velocities_of(ctx).ravel()) - l0
    assert np.linalg.norm(change) / np.linalg.norm(l0) < 1e-10
    assert integrator.midpoint_tolerance.value_in_unit(unit.nanometers) == 1e-13


def test_totals_give_the_rms_and_maximum_of_every_step():
    integrator = AlphaRattleEnergyIntegrator(0.002, composition="triple-jump", constraint_tolerance=1e-12)
    _, ctx = _cluster_context(integrator)
    assert np.isnan(integrator.controller_totals()["rms_residual"])
    measured, _, _ = _residuals(ctx, integrator, 40, total_energy(ctx))
    totals = integrator.controller_totals()
    assert totals["rms_residual"] == pytest.approx(np.sqrt(np.mean(measured**2)), rel=1e-6, abs=1e-9)
    assert totals["max_abs_residual"] == pytest.approx(np.max(np.abs(measured)), rel=1e-6, abs=1e-9)
    assert totals["max_abs_residual"] > 0
    for count in ("within_tolerance", "fallen_back", "at_bound"):
        assert totals[f"fraction_{count}"] == totals[f"steps_{count}"] / 40
    assert totals["steps_within_tolerance"] + totals["steps_fallen_back"] == 40


def test_a_chosen_midpoint_tolerance_is_kept_without_a_box():
    integrator = AlphaRattleEnergyIntegrator(0.002, composition="triple-jump", midpoint_tolerance=1e-7)
    _, ctx = _cluster_context(integrator)
    integrator.check_context(ctx)
    integrator.step(1)
    assert integrator.midpoint_tolerance.value_in_unit(unit.nanometers) == pytest.approx(1e-7)
    integrator.midpoint_tolerance = 1e-8
    assert integrator.getGlobalVariableByName("midpoint_tolerance_automatic") == 0
    del ctx


def test_energy_mode_on_a_water_cluster_holds_energy_and_keeps_momenta():
    tight = {"constraint_tolerance": 1e-12}
    rattle = RattleIntegrator(0.002, **tight)
    _, ctx = _cluster_context(rattle)
    rattle_residuals, _, _ = _residuals(ctx, rattle, 300, total_energy(ctx))

    integrator = AlphaRattleEnergyIntegrator(
        0.002, midpoint_tolerance=1e-12, **tight, controller=ControllerSettings(energy_tolerance=0.01)
    )
    problem, ctx = _cluster_context(integrator)
    e_ref = total_energy(ctx)
    x, v = positions_of(ctx).ravel(), velocities_of(ctx).ravel()
    l0 = angular_momentum(problem, x, v)
    masses = problem.masses.reshape(-1, 3)[:, 0]
    l_err = p_err = 0.0
    measured, claimed, fell_back = [], [], []
    for _ in range(30):
        r, c, f = _residuals(ctx, integrator, 10, e_ref)
        measured += list(r)
        claimed += list(c)
        fell_back += list(f)
        x, v = positions_of(ctx), velocities_of(ctx)
        l_err = max(l_err, np.linalg.norm(angular_momentum(problem, x.ravel(), v.ravel()) - l0))
        p_err = max(p_err, np.linalg.norm(masses @ v))
    measured, claimed, fell_back = np.array(measured), np.array(claimed), np.array(fell_back)
    tolerance = integrator.energy_tolerance.value_in_unit(unit.kilojoules_per_mole)

    assert integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole) == pytest.approx(
        e_ref, abs=1e-9
    )
    # the integrator's residual is the context's energy, and its verdict is honest
    assert np.max(np.abs(measured - claimed)) < 1e-8
    assert np.all(np.abs(measured[~fell_back]) <= tolerance)
    # measured: 56% of steps within 0.01 kJ/mol, RMS 1/7 of RATTLE's (0.060 vs 0.42); with the
    # design doc's bounds (-1, 3) and no slope damping 71% and 0.041 here, but worse on water boxes
    assert np.mean(~fell_back) > 0.5
    rms = np.sqrt(np.mean(measured**2))
    assert rms < 0.2 * np.sqrt(np.mean(rattle_residuals**2))
    # no drift: the second half is no further from E_ref than the first
    assert np.sqrt(np.mean(measured[150:] ** 2)) < 2 * np.sqrt(np.mean(measured[:150] ** 2)) + 0.01
    # each step is a member of the family: momenta kept (measured |ΔL| 4e-11, RATTLE 8e-12)
    assert np.linalg.norm(l0) > 1.0
    assert l_err < 1e-9
    assert p_err < 1e-10


def test_energy_mode_on_a_water_box_beats_rattle_and_keeps_constraints(
    water_box, rattle_residuals_on_the_water_box
):
    n = 60
    rattle_rms = np.sqrt(np.mean(rattle_residuals_on_the_water_box[:n] ** 2))  # the session's RATTLE run

    integrator = AlphaRattleEnergyIntegrator(0.002, controller=ControllerSettings(energy_tolerance=0.01))
    ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
    measured, claimed, fell_back = _residuals(ctx, integrator, n, total_energy(ctx))
    tolerance = integrator.energy_tolerance.value_in_unit(unit.kilojoules_per_mole)
    assert np.max(np.abs(measured - claimed)) < 1e-7
    assert np.all(np.abs(measured[~fell_back]) <= tolerance)
    # measured on this (smooth) box over 60 steps: RMS 0.18 vs RATTLE's 0.92, 6.23 force
    # evaluations per step; one α often cannot reach E_ref (68% of steps fall back)
    assert np.sqrt(np.mean(measured**2)) < 0.3 * rattle_rms
    pos_err, vel_err = constraint_errors(water_box.system, positions_of(ctx), velocities_of(ctx))
    assert pos_err < 1e-6
    assert vel_err < 1e-6
    lo, hi = integrator.alpha_bounds
    assert lo <= integrator.alpha <= hi
    # 6.23 force evaluations per step before the α = 0 trial; 7.13 with it (2026-11-27: a missed
    # step that ends as the α = 0 step or in its best α trial pays one more evaluation)
    assert integrator.force_evaluations_per_step <= 7.5, integrator.force_evaluations_per_step


def test_controller_recovers_from_a_bad_starting_alpha():
    settings = {
        "constraint_tolerance": 1e-12,
        "midpoint_tolerance": 1e-10,
        "controller": ControllerSettings(energy_tolerance=0.01),
    }
    normal = AlphaRattleEnergyIntegrator(0.002, **settings)
    _, ctx = _cluster_context(normal)
    e_ref = total_energy(ctx)
    normal_residuals = _residuals(ctx, normal, 40, e_ref)[0]

    bad = AlphaRattleEnergyIntegrator(0.002, **settings)
    bad.alpha = 50.0  # far outside the bounds: clipped to them, then the controller must find its way back
    _, ctx = _cluster_context(bad)
    bad_residuals = _residuals(ctx, bad, 40, e_ref)[0]
    assert abs(bad_residuals[0]) > 0.0
    assert bad.alpha_bounds == pytest.approx((-0.5, 1.5))  # order 2's defaults
    assert -0.5 <= bad.alpha <= 1.5
    # after a few steps the bad start is forgotten: same quality as a normal start
    assert np.sqrt(np.mean(bad_residuals[10:] ** 2)) < 2 * np.sqrt(np.mean(normal_residuals[10:] ** 2)) + 0.01


@pytest.mark.parametrize("order", [2, 4])
def test_checkpoint_and_xml_restarts_continue_the_same_trajectory(water_box, order):
    integrator = AlphaRattleEnergyIntegrator(0.002, order=order)
    ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
    integrator.step(3)
    checkpoint = ctx.createCheckpoint()
    integrator_xml = mm.XmlSerializer.serialize(integrator)
    state_xml = mm.XmlSerializer.serialize(ctx.getState(getPositions=True, getVelocities=True))
    integrator.step(3)
    expected = positions_of(ctx), integrator.alpha, integrator.reference_energy, integrator.energy_residual

    fresh = AlphaRattleEnergyIntegrator(0.002, order=order)
    ctx2 = mm.Context(water_box.system, fresh, REFERENCE)
    ctx2.loadCheckpoint(checkpoint)
    fresh.step(3)
    assert np.array_equal(positions_of(ctx2), expected[0])
    assert (fresh.alpha, fresh.reference_energy, fresh.energy_residual) == expected[1:]

    from openmm_alphaprk import restore_integrator

    restored = restore_integrator(mm.XmlSerializer.deserialize(integrator_xml))
    ctx3 = mm.Context(water_box.system, restored, REFERENCE)
    ctx3.setState(mm.XmlSerializer.deserialize(state_xml))
    restored.step(3)
    assert restored.controller_totals()["reference_resets"] == 1  # E_ref kept, not retaken
    assert restored.reference_energy == expected[2]
    assert np.max(np.abs(positions_of(ctx3) - expected[0])) < 1e-9


def test_reference_energy_is_retaken_when_the_state_is_changed(water_box):
    integrator = AlphaRattleEnergyIntegrator(0.002)
    ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
    assert np.isnan(integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole))
    integrator.step(2)
    first = integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole)
    assert first == pytest.approx(
        total_energy(ctx) - integrator.energy_residual.value_in_unit(unit.kilojoules_per_mole), abs=1e-8
    )
    ctx.setVelocities(1.1 * velocities_of(ctx))
    heated = total_energy(ctx)
    integrator.step(1)
    assert integrator.controller_totals()["reference_resets"] == 2
    assert integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole) == pytest.approx(
        heated, abs=1e-8
    )
    integrator.reset_reference_energy()
    now = total_energy(ctx)
    integrator.step(1)
    assert integrator.controller_totals()["reference_resets"] == 3
    assert integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole) == pytest.approx(now, abs=1e-8)


def test_controller_reporter_writes_every_step_as_it_goes(water_box, tmp_path):
    integrator = AlphaRattleEnergyIntegrator(0.002)
    simulation = app.Simulation(water_box.topology, water_box.system, integrator, REFERENCE)
    simulation.context.setPositions(water_box.positions)
    simulation.context.setVelocities(water_box.velocities)
    path = tmp_path / "controller.csv"
    reporter = AlphaControllerReporter(str(path))
    simulation.reporters.append(reporter)
    simulation.step(4)
    assert path.read_text(encoding="utf-8").splitlines()[0] == ",".join(COLUMNS)
    rows = read_controller_csv(path)
    assert rows.shape == (4, len(COLUMNS))
    assert rows[-1, 2] == integrator.alpha
    assert rows[-1, 3] == integrator.energy_residual.value_in_unit(unit.kilojoules_per_mole)
    assert list(rows[:, 0]) == [1, 2, 3, 4]
    assert np.sum(rows[:, 6]) == integrator.force_evaluations
    summary = summarize_controller(rows)
    assert summary.steps == 4
    assert summary.force_evaluations_per_step == pytest.approx(integrator.force_evaluations_per_step)
    assert summary.fraction_fallen_back == pytest.approx(
        integrator.controller_totals()["fraction_fallen_back"]
    )
    assert (
        summary.alpha_percentiles["p1"]
        <= summary.alpha_percentiles["p50"]
        <= summary.alpha_percentiles["p99"]
    )
    # every step reported: the rows and the integrator's every-step totals agree
    from_totals = summarize_controller(rows, totals=integrator.controller_totals())
    assert reporter.summary().as_dict() == from_totals.as_dict()
    assert from_totals.residuals_over == "every step"
    for key in ("rms_residual", "max_abs_residual", "fraction_fallen_back", "force_evaluations_per_step"):
        assert getattr(from_totals, key) == pytest.approx(getattr(summary, key), rel=1e-9), key

    # a resumed run appends rows under the same header
    again = AlphaControllerReporter(str(path), append=True)
    simulation.reporters[:] = [again]
    simulation.step(2)
    assert read_controller_csv(path).shape == (6, len(COLUMNS))

    other = app.Simulation(water_box.topology, water_box.system, RattleIntegrator(0.002), REFERENCE)
    other.context.setPositions(water_box.positions)
    other.reporters.append(AlphaControllerReporter(str(tmp_path / "x.csv")))
    with pytest.raises(TypeError, match="energy mode"):
        other.step(1)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"alpha_bounds": (1.0, 1.0)}, ValueError, "low < high"),
        ({"alpha_bounds": (2.0, -1.0)}, ValueError, "empty or inverted"),
        ({"alpha_bounds": (float("nan"), 1.0)}, ValueError, "finite"),
        ({"alpha_bounds": 3.0}, TypeError, "pair"),
        ({"energy_tolerance": 0.0}, ValueError, "energy_tolerance must be positive"),
        ({"energy_tolerance": -1e-3}, ValueError, "energy_tolerance must be positive"),
        ({"energy_tolerance": 1 * unit.nanometers}, TypeError, "cannot be converted"),
        ({"max_trials": 0}, ValueError, "positive integer"),
        # measured: one trial per step kept α at 0 at both orders (RATTLE / triple jump at a higher cost)
        ({"max_trials": 1}, ValueError, "never moves alpha.*max_trials >= 2"),
        ({"max_trials": 2.5}, ValueError, "positive integer"),
        ({"max_alpha_change": 0}, ValueError, "max_alpha_change must be positive"),
        ({"alpha_probe": -0.1}, ValueError, "alpha_probe must be positive"),
        ({"slope_damping": -0.5}, ValueError, "slope_damping must be >= 0"),
    ],
)
def test_bad_energy_mode_settings_give_clear_errors(kwargs, error, match):
    """The controller's settings are checked when made, before any integrator."""
    with pytest.raises(error, match=match):
        ControllerSettings(**kwargs)


def test_the_controller_settings_take_the_orders_defaults_where_left_unset():
    """A field left None is the order's default (CONTROLLER_DEFAULTS, scaled on a composition)."""
    from openmm_alphaprk.integrators.compositions import composition
    from openmm_alphaprk.integrators.energy_settings import CONTROLLER_DEFAULTS, alpha_scale_of

    def globals_of(integrator):
        return {
            name: integrator.getGlobalVariableByName(name)
            for name in (
                "alpha_min",
                "alpha_max",
                "max_trials",
                "max_alpha_change",
                "alpha_probe",
                "slope_damping",
            )
        }

    for order, scale in ((2, 1.0), (4, alpha_scale_of(composition("suzuki5")))):
        defaults = CONTROLLER_DEFAULTS[order]
        expected = {
            "alpha_min": scale * defaults.alpha_bounds[0],
            "alpha_max": scale * defaults.alpha_bounds[1],
            "max_trials": defaults.max_trials,
            "max_alpha_change": scale * defaults.max_alpha_change,
            "alpha_probe": scale * defaults.alpha_probe,
            "slope_damping": 0.5,
        }
        for controller in (None, ControllerSettings()):
            assert globals_of(AlphaRattleEnergyIntegrator(0.002, order=order, controller=controller)) == (
                pytest.approx(expected)
            )
        partial = AlphaRattleEnergyIntegrator(0.002, order=order, controller=ControllerSettings(max_trials=6))
        assert globals_of(partial) == pytest.approx({**expected, "max_trials": 6})
    with pytest.raises(ValueError, match="low < high"):
        ControllerSettings(alpha_bounds=(0.3, 0.1))
    with pytest.raises(TypeError, match="ControllerSettings"):
        AlphaRattleEnergyIntegrator(0.002, controller={"max_trials": 3})
    with pytest.raises(TypeError, match="alpha_bounds"):  # a controller option is not a keyword of its own
        AlphaRattleEnergyIntegrator(0.002, alpha_bounds=(-0.1, 0.1))


def test_energy_mode_settings_are_checked_later_too_and_need_the_mode():
    tolerance = ControllerSettings(energy_tolerance=0.02 * unit.kilojoule_per_mole)
    integrator = AlphaRattleEnergyIntegrator(0.002, controller=tolerance)
    assert integrator.energy_tolerance == 0.02 * unit.kilojoules_per_mole
    with pytest.raises(ValueError, match="low < high"):
        integrator.alpha_bounds = (0.5, 0.1)
    with pytest.raises(ValueError, match="energy_tolerance must be positive"):
        integrator.energy_tolerance = 0
    integrator.alpha_bounds = (0.0, 1.0)
    assert integrator.alpha_bounds == (0.0, 1.0)
    assert repr(integrator) == "AlphaRattleEnergyIntegrator(timestep=0.002 ps)"
    fixed = AlphaRattleIntegrator(0.002, alpha=0.5)
    assert not fixed.energy_mode
    with pytest.raises(AttributeError, match="reset_reference_energy"):
        fixed.reset_reference_energy()
    with pytest.raises(AttributeError, match="energy_residual"):
        _ = fixed.energy_residual


def test_the_energy_mode_is_its_own_class_and_survives_serialization_and_copies():
    """The energy mode is its own class; XML, restore and deepcopy keep the class."""
    import copy

    from openmm_alphaprk import AlphaRattleEnergyIntegrator, restore_integrator

    energy = AlphaRattleEnergyIntegrator(0.002, composition="triple-jump")
    fixed = AlphaRattleIntegrator(0.002, alpha=0.1)
    # siblings on a private base: the energy mode is not a fixed α
    assert type(energy) is AlphaRattleEnergyIntegrator and not isinstance(energy, AlphaRattleIntegrator)
    assert type(fixed) is AlphaRattleIntegrator
    for original in (energy, fixed):
        restored = restore_integrator(mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(original)))
        assert type(restored) is type(original)
        assert restored.energy_mode == original.energy_mode
        assert type(copy.deepcopy(original)) is type(original)
    with pytest.raises(TypeError, match="alpha"):
        AlphaRattleEnergyIntegrator(0.002, alpha=0.1)
    with pytest.raises(TypeError, match="positional"):  # every option after the timestep is a keyword
        AlphaRattleEnergyIntegrator(0.002, "energy")


def test_the_energy_mode_asked_of_the_fixed_alpha_class_names_its_class():
    """``AlphaRattleIntegrator(h, alpha="energy")`` (the former factory) refuses with the replacement."""
    with pytest.raises(
        ValueError, match=r"its own class: use AlphaRattleEnergyIntegrator\(timestep, order=4"
    ):
        AlphaRattleIntegrator(0.002, alpha="energy")
    with pytest.raises(TypeError, match="positional"):  # not alpha: options after the timestep are keywords
        AlphaRattleIntegrator(0.002, 0.1)
    with pytest.raises(ValueError, match=r"AlphaRattleEnergyIntegrator"):
        AlphaRattleIntegrator(0.002, alpha="energy", order=4)
    with pytest.raises(ValueError, match="alpha must be a number"):
        AlphaRattleIntegrator(0.002, alpha="fast")


def test_energy_mode_options_with_a_fixed_alpha_are_refused():
    """An option of the energy mode is not a parameter of the fixed-α class."""
    with pytest.raises(TypeError, match="alpha_bounds"):
        AlphaRattleIntegrator(0.002, alpha=0.1, alpha_bounds=(-0.1, 0.1))
    with pytest.raises(TypeError, match="energy_tolerance"):
        AlphaRattleIntegrator(0.002, energy_tolerance=0.1, max_trials=5)
    fixed = AlphaRattleIntegrator(0.002, alpha=0.1)
    assert not hasattr(fixed, "energy_tolerance")  # the fixed α has none of the energy mode's API


def test_the_class_diagram_has_at_most_three_levels():
    """Every class below openmm.CustomIntegrator is an integrator, but the private bases; three levels.

    The private bases: ``_StepProgram`` (every program) and ``_AlphaRattleBase`` (what the
    fixed α and the energy mode share; the energy mode is not an ``AlphaRattleIntegrator``).

    Beside them only the layers of the integrators that hold the energy: the E_ref trait
    (it derives from object) and the energy mode's controller over it; neither is an
    integrator or a level.
    """
    from openmm_alphaprk import AlphaRattleEnergyIntegrator, RattleRescaleIntegrator
    from openmm_alphaprk.integrators.energy_controller import _EnergyController
    from openmm_alphaprk.integrators.reference_energy import _ReferenceEnergy

    integrators = (
        RattleIntegrator,
        RattleRescaleIntegrator,
        AlphaRattleIntegrator,
        AlphaRattleEnergyIntegrator,
    )
    for cls in integrators:
        ours = [c for c in cls.__mro__ if c.__module__.startswith("openmm_alphaprk")]
        levels = [c for c in ours if issubclass(c, mm.CustomIntegrator)]
        assert len(levels) <= 3, levels
        assert set(ours) - set(levels) <= {_ReferenceEnergy, _EnergyController}, ours
        assert _ReferenceEnergy.__bases__ == (object,)
