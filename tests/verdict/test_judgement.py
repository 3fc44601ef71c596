"""The judgement of a test: an INVALID test is never classified."""

from __future__ import annotations

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant


def test_invalid_tests_are_never_classified() -> None:
    from edc_bench.config import parse_variant

    data = load_variant().model_dump()
    data["excitation"]["shape"] = "sine"
    result = run_simulated_test(parse_variant(data), "new", 1, check_gains=False)
    assert result.verdict == "INVALID"
    assert result.classification is None
