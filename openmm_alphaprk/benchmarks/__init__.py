"""Benchmarks: cost (time per step against RATTLE) and energy (H − E_ref against RATTLE).

Run them as ``alphaprk bench cost …`` and ``alphaprk bench energy …``. Nothing else
in the package imports this subpackage.
"""
