"""The tick as a sans-I/O core: one test's frames and times in, its commands and typed outcomes out.

- :mod:`~edc_bench.engine.tick`: :class:`~edc_bench.engine.tick.TickEngine`, everything that happens at a
  tick (reply matching, controller step, command bytes, trace row, abort checks, the stop rule's hook);
- :mod:`~edc_bench.engine.outcome`: how a test ended, as values (:class:`~edc_bench.engine.outcome.Abort`,
  :class:`~edc_bench.engine.outcome.StopReason`), and the one place their sentences are made; an abort's figures
  typed per kind in :mod:`~edc_bench.engine.abort_figures`;
- :mod:`~edc_bench.engine.commands`: a command the engine made, as a value (its bytes, the reply it expects, its
  tick and deadlines);
- :mod:`~edc_bench.engine.problems`: what stands between a test and a verdict, as bits
  (:class:`~edc_bench.engine.problems.Problem`), a leaf every layer may name;
- :mod:`~edc_bench.engine.replies`, :mod:`~edc_bench.engine.trace`, :mod:`~edc_bench.engine.tracking`: the
  bookkeeping it keeps (replies in flight, the preallocated trace and frame log, the rack off its reference).

Pure: no bus, no clock, no files. The real-time and simulated loops
(:mod:`edc_bench.runtime.loop`) and replay (:mod:`edc_bench.replay`) drive it.
"""
