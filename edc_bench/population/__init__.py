"""The population engine: many simulated valves at once, for baselines, training data and studies.

- :mod:`~edc_bench.population.valves`: valves drawn from a variant's wear population;
- :mod:`~edc_bench.population.batch`: the vectorised simulator and bench (thousands of tests in lockstep), with
  :mod:`~edc_bench.population.batch_link` for an adapter's timing; the plant's step of each valve is the
  simulated rig's own (:mod:`edc_bench.sim.kernels`);
- :mod:`~edc_bench.population.calibrate`: a variant's baseline from simulated new valves.

It simulates, so it sits above :mod:`edc_bench.sim`; it identifies and trusts with the same code as a bench test
(:mod:`edc_bench.identification`).
"""
