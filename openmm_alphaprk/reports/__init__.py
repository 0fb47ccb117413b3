"""Reports: regenerate the numbers, tables and figures of docs/validation.md and docs/benchmarks.md.

Run them as ``python -m openmm_alphaprk.reports.validation`` and
``python -m openmm_alphaprk.reports.md_benchmark``. They sit at the top of the
package, next to the command line: nothing else in the package imports this
subpackage.
"""
