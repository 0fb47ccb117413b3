"""Comparisons at equal cost: a row of k force evaluations per step against a baseline at h/k.

One home for what ``alphaprk compare``, the energy and accuracy benchmarks and the
documentation's tables all need: k for a row (:func:`equal_cost_divisor`), which
baseline row matches it (:func:`equal_cost_baselines`), the gain (:func:`gain`: the
baseline's error over the row's) and how a gain is said (:func:`gain_text`: "3.1x
lower" where the row wins, "2x higher" where it loses, never "0.5x lower").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Container, Mapping


def equal_cost_divisor(force_evaluations_per_step: float) -> int:
    """Return k of "RATTLE at h/k costs the same": the force evaluations per step, rounded up."""
    return max(1, math.ceil(force_evaluations_per_step - 1e-9))


def equal_cost_baselines(
    evaluations: Mapping[str, float], baseline_name: Callable[[int], str], ran: Container[str]
) -> dict[str, tuple[int, str]]:
    """For each row of more than one force evaluation per step whose baseline ran: k and that baseline.

    Parameters
    ----------
    evaluations
        Force evaluations per step by row name (rows that are themselves baselines
        excluded by the caller).
    baseline_name
        The name of the baseline row at h/k, e.g. ``lambda k: f"rattle h/{k}"``.
    ran
        The names of the rows that ran.
    """
    pairs = {}
    for name, per_step in evaluations.items():
        k = equal_cost_divisor(per_step)
        if k > 1 and baseline_name(k) in ran:
            pairs[name] = (k, baseline_name(k))
    return pairs


def gain(baseline_error: float, row_error: float) -> float:
    """Return the baseline's error over the row's (above 1: the row is the more accurate), else NaN."""
    if (
        not (math.isfinite(baseline_error) and math.isfinite(row_error))
        or row_error <= 0
        or baseline_error < 0
    ):
        return float("nan")
    return baseline_error / row_error


def gain_text(ratio: float, times: str = "x", loss: str = "{}") -> str:
    """Say a gain as "3.1x lower" (the row wins) or, formatted by ``loss``, "2x higher"; "–" if undefined.

    ``times`` is the multiplication sign ("x" in plain text, "×" in Markdown);
    ``loss`` formats the losing case, e.g. ``"**{}**"`` or ``"{}: no gain at equal cost"``.
    """
    if not math.isfinite(ratio) or ratio <= 0:
        return "–"
    if ratio >= 1:
        return f"{ratio:.3g}{times} lower"
    return loss.format(f"{1 / ratio:.3g}{times} higher")
