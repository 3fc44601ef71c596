"""``edc-bench perf``: timing and speed, measured next to the reference each figure should approach.

Six groups (see :mod:`edc_bench.perf.suite`): tick compute, codec, the
simulated bench test, the real-time loop against the rig process,
throughput and start-up, and the session's latency from a test's safe stop
to its decision on screen and to its report. Benchmarks print figures; no test asserts one.
"""

#: The groups, in the order they run (here, not in the suite: the command line lists them without importing it).
GROUPS = ("tick", "codec", "simulated", "realtime", "throughput", "session")

