"""Reports: every generated block of the documentation's pages, from the data under docs/data/.

``python -m tools.reports`` writes them (``--check`` compares, ``--figures`` also draws);
see :mod:`tools.reports.__main__`. Not part of the installed package; it imports it.
"""
