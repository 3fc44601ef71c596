"""Learning: the classifier's data, its training, a shop's own training and the model a station adopts.

- :mod:`~edc_bench.learning.dataset`: labelled features from simulated populations;
- :mod:`~edc_bench.learning.train`: the shipped models, rebuilt byte for byte;
- :mod:`~edc_bench.learning.evaluation`: accuracy and MARGINAL share of a model on labelled data;
- :mod:`~edc_bench.learning.shop_training`: a candidate trained on the shop's labelled tests;
- :mod:`~edc_bench.learning.adoption`: which model this station judges with.
"""
