"""``edc-bench perf``: timing and speed, measured next to the reference each figure should approach.

Five groups (see :mod:`edc_bench.perf.suite`): tick compute, codec, the
simulated bench test, the real-time loop against the rig process, and
throughput and start-up. Benchmarks print figures; no test asserts one.
"""

#: The groups, in the order they run (here, not in the suite: the command line lists them without importing it).
GROUPS = ("tick", "codec", "simulated", "realtime", "throughput")
