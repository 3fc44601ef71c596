"""Experiments and studies: the paper's experiment, time to verdict, the gain sweep, the decision boundary's
trade-off, the drift test's critical values (:mod:`~edc_bench.experiments.studies`). Nothing the bench needs to
judge a valve imports them."""
