"""Studies that run the bench's whole test path (the loop, the period fit, the verdict, the part diagnosis) over
simulated pumps, in simulated time: above the bench in the layers, where :mod:`edc_bench.experiments` runs the
batch path below it."""
