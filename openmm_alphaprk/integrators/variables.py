"""Names of the step programs' global variables that are read or set from outside a program.

Reporters, scripts and the integrators' own properties read these by name
(``integrator.getGlobalVariableByName(RESIDUAL)``); every other variable is private to
the program that declares it (``integrator.program_listing()`` shows them all).
"""

import zlib

#: Identifies the integrator class in serialized form (:func:`~.restore.restore_integrator`):
#: :func:`program_kind` of the class.
KIND_VARIABLE = "alphaprk_kind"


def program_kind(cls: type) -> int:
    """Return the number a program of class ``cls`` keeps in :data:`KIND_VARIABLE`: its name's CRC-32.

    Taken to 24 bits, so that the global (a double) holds it exactly; the same for the
    same class name in every version, so that restoring needs no table of numbers.
    """
    return zlib.crc32(cls.__name__.encode()) & 0xFFFFFF


# ---------------------------------------------------------------- every program
STEPS_TAKEN = "steps_taken"
FORCE_EVALUATIONS = "force_evaluations"
STEP_FORCE_EVALUATIONS = "step_force_evaluations"
HOST_SYNCS = "host_syncs"
#: Degrees of freedom the program moves: 3 × the particles with mass (set by the system check).
NDOF = "ndof"
#: Particles of the System, with or without mass (set from Python before the first step).
N_PARTICLES = "n_particles"
#: What the system check at the next step does: 0 nothing, 1 check and refuse a System with
#: particles without mass, 2 check and allow them (set from Python before each ``step()``).
CHECK_SYSTEM = "check_system"
#: 1 if the system check refused the step, which then does nothing.
REFUSED = "refused"

# ---------------------------------------------------------------- α-RATTLE
ALPHA = "alpha"
MIDPOINT_CHANGE = "midpoint_change"
MIDPOINT_ITERATIONS = "midpoint_iterations"

# ---------------------------------------------------------------- the energy mode
REFERENCE_ENERGY = "reference_energy"
RESIDUAL = "residual"
TRIALS = "trials"
FELL_BACK = "fell_back"
ALPHA_AT_BOUND = "alpha_at_bound"
SLOPE = "slope"
SLOPE_SCALE = "slope_scale"
PREDICTED_D0 = "predicted_d0"
PREDICTED_SLOPE = "predicted_slope"

# ---------------------------------------------------------------- RATTLE + velocity rescaling
#: s, the factor the last step scaled the velocities relative to the rigid-body motion by.
VELOCITY_SCALE = "velocity_scale"
#: H − E_ref after the last RATTLE step, before its velocities were scaled.
RATTLE_RESIDUAL = "rattle_residual"
#: 1 if a step found no real scale factor: it and the rest of the ``step()`` call did nothing.
RESCALE_HALTED = "rescale_halted"
