"""Identification: what a test's trace says about the valve, and how far to trust it (pure numerics).

- :mod:`~edc_bench.identification.period_fit`: af and a1 by least squares over whole excitation periods;
- :mod:`~edc_bench.identification.analysis`: a finished trace's identification and its model fit;
- :mod:`~edc_bench.identification.coil_check`: the coil's resistance against its spec;
- :mod:`~edc_bench.identification.trust`: the one trust rule, vectorised (one test or 10,000).
- :mod:`~edc_bench.identification.student_t`: Student's t quantiles for the early stop's interval.

Imports nothing that runs a test (no bus, clock, simulator) and nothing that judges the valve.
"""
