"""Numbers as the documentation's pages write them: significant digits, ratios, tolerances, per cent."""

from __future__ import annotations


def sig(value: float, digits: int = 2) -> str:
    """``value`` to ``digits`` significant digits: 0.53, 0.010, 1.2, 3.6e-4 (e notation below 1e-3)."""
    if value != 0 and abs(value) < 1e-3:
        mantissa, exponent = f"{value:.{digits - 1}e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    text = f"{value:#.{digits}g}"
    return text.rstrip(".") if abs(value) >= 1 else text


def times(value: float) -> str:
    """Write a ratio as the pages do: two significant digits below 10, whole numbers above (1,300)."""
    if value >= 10:
        rounded = float(f"{value:.2g}") if value >= 100 else round(value)
        return f"{rounded:,.0f}"
    return f"{value:.2g}"


def two(value: float) -> str:
    """``value`` to two significant digits, trailing zeros kept: 92, 8.0, 0.80, 0.0030."""
    return f"{value:#.2g}".rstrip(".")


def tolerance(value: float) -> str:
    """Write a tolerance as the pages do: 5e-4, 1e-5."""
    mantissa, exponent = f"{value:.0e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def percent(fraction: float) -> str:
    """Write a fraction in per cent, three significant digits at most: 87 %, 99.8 %."""
    return f"{100 * fraction:.3g} %"


def whole_percent(fraction: float) -> str:
    """Write a fraction in whole per cent: 99 %."""
    return f"{100 * fraction:.0f} %"
