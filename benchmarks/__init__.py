"""Benchmarks and the generators of the measured results in docs/results/.

``python -m benchmarks.results --list`` names every result, the command that writes it and how long it takes;
``python -m benchmarks.results --only NAME`` regenerates one (:mod:`benchmarks.results`).  Every file a generator
writes carries a provenance stamp: the commit, whether the tree had changes, the command line and the date
(:mod:`benchmarks.provenance`).
"""
