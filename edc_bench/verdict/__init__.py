"""The verdict: what the identified valve is, against what, and when it is certain.

- :mod:`~edc_bench.verdict.verdicts`: the verdicts' names (PASS, MARGINAL, FAIL, INVALID, UNCLASSIFIED);
- :mod:`~edc_bench.verdict.baseline`: the variant's new-valve baseline;
- :mod:`~edc_bench.verdict.classifier`: the shipped or adopted ONNX classifier (``models/``);
- :mod:`~edc_bench.verdict.judgement`: a finished run's verdict, its reasons and its problems as values;
- :mod:`~edc_bench.verdict.early_stop`: the stop rule the loop asks after each period (is the verdict certain?).

Imports nothing that runs a test: the loop hands it a trace and an outcome.
"""
