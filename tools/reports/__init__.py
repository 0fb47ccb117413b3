"""Reports: regenerate the numbers, tables and figures of docs/validation.md and docs/benchmarks.md.

Run them from the repository's root as ``python -m tools.reports.validation`` and
``python -m tools.reports.md_benchmark``. They are not part of the installed package;
they import it.
"""
