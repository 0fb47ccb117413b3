"""Checks and conversion of user input at the package's edges: plain numbers in OpenMM's units.

Quantities as Python objects (:func:`to_float`), dimensionless numbers
(:func:`to_dimensionless`), counts (:func:`positive_int`) and text with a unit, as command
lines write them (:func:`parse_time`: ``2fs``, :func:`parse_length`: ``8A``). The errors
(:class:`InputError`, :class:`InputTypeError`) name the value and how to fix it.
"""

from __future__ import annotations

import math
import numbers
import re

import openmm.unit as unit

from .errors import InputError, InputTypeError  # defined there; importable from here too


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


def positive_int(value: object, name: str) -> int:
    """Return ``value`` as an int if it is a whole number ≥ 1 (integral floats too), else raise InputError."""
    numeric = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not numeric or not math.isfinite(value) or value != int(value) or value < 1:
        raise InputError(f"{name} must be a positive integer, got {value!r}.")
    return int(value)


# ---------------------------------------------------------------- quantities written as text
_TIME_UNITS = {"fs": 1e-3, "ps": 1.0, "ns": 1e3}
_LENGTH_UNITS = {"a": 1.0, "å": 1.0, "angstrom": 1.0, "nm": 10.0}


class QuantityError(InputError):
    """A command-line quantity with a missing or wrong unit."""


def parse_time(text: str, option: str) -> float:
    """Parse ``2fs``, ``2 fs``, ``0.002ps`` or ``1ns`` into picoseconds."""
    return _parse(text, option, _TIME_UNITS, "a time", "fs, ps or ns")


def parse_length(text: str, option: str) -> float:
    """Parse ``8A``, ``8 Å`` or ``0.8nm`` into Ångström."""
    return _parse(text, option, _LENGTH_UNITS, "a length", "A (Ångström) or nm")


def _parse(text: str, option: str, units: dict[str, float], what: str, allowed: str) -> float:
    match = re.fullmatch(r"\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*([^\s0-9]*)\s*", str(text))
    if not match:
        raise QuantityError(f"{option} {text!r} is not a number with a unit; write e.g. 2fs or 0.8nm.")
    value, symbol = float(match.group(1)), match.group(2)
    if not symbol:
        raise QuantityError(f"{option} {text!r} has no unit; give {what} with a unit ({allowed}), e.g. 2fs.")
    factor = units.get(symbol.lower())
    if factor is None:
        raise QuantityError(f"{option} {text!r}: {symbol!r} is not a unit of {what}; use {allowed}.")
    if not value > 0:
        raise QuantityError(f"{option} must be positive, got {text!r}.")
    return value * factor
