"""The station's history of bench tests: the store (:mod:`edc_bench.history.store`), its URL
(:mod:`edc_bench.history.url`), the shop's teardown labels (:mod:`edc_bench.history.labels`).

Nothing is imported here: checking a history URL before a test does not import the database layer.
"""
