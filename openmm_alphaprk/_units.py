"""Conversion of user input at the package's edges to plain numbers in OpenMM's units."""

from __future__ import annotations

import math

import openmm.unit as unit


class InputError(ValueError):
    """A value the user gave is wrong; the message names it and how to fix it."""


class InputTypeError(TypeError):
    """A value the user gave has the wrong type or units; the message names it and how to fix it."""


def to_float(value: object, unit_: unit.Unit, name: str, *, positive: bool = False) -> float:
    """Return ``value`` as a float in ``unit_``, checking units and finiteness.

    Parameters
    ----------
    value
        A plain number (taken to be in ``unit_``) or an ``openmm.unit.Quantity``
        compatible with ``unit_``.
    unit_
        OpenMM's default unit for this quantity (e.g. ``unit.picoseconds``).
    name
        Name of the argument, used in error messages.
    positive
        If true, require a value strictly greater than zero.

    Raises
    ------
    TypeError
        If ``value`` is neither a number nor a Quantity of compatible units.
    ValueError
        If ``value`` is not finite, or not positive when ``positive`` is set.

    """
    if unit.is_quantity(value):
        if not value.unit.is_compatible(unit_):
            raise InputTypeError(
                f"{name} has units of {value.unit}, which cannot be converted to {unit_}; "
                f"pass a Quantity in units compatible with {unit_} (or a plain number in {unit_})."
            )
        value = value.value_in_unit(unit_)
    return _checked_float(
        value, name, positive, "a number or an openmm.unit.Quantity", f" {unit_.get_symbol()}"
    )


def to_dimensionless(value: object, name: str, *, positive: bool = False) -> float:
    """Return a dimensionless number as a float, checking finiteness (and sign)."""
    if unit.is_quantity(value):
        if not value.unit.is_dimensionless():
            raise InputTypeError(f"{name} must be dimensionless, got units of {value.unit}.")
        value = value.value_in_unit(unit.dimensionless)
    return _checked_float(value, name, positive, "a number", "")


def _checked_float(value: object, name: str, positive: bool, expected: str, symbol: str) -> float:
    """Convert a plain value to float; reject booleans, non-numbers, non-finite and (optionally) ≤ 0."""
    if isinstance(value, bool):
        raise InputTypeError(f"{name} must be {expected}, got {value!r}.")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputTypeError(f"{name} must be {expected}, got {value!r}.") from None
    if not math.isfinite(number):
        raise InputError(f"{name} must be finite, got {number}.")
    if positive and number <= 0.0:
        raise InputError(f"{name} must be positive, got {number}{symbol}.")
    return number
