"""The verdicts a bench test can end with.

A leaf module (no imports from edc_bench), so every layer that shows or
stores a verdict (the record, the report, the history, the screens) names
them from here.
"""

from __future__ import annotations

import enum


class Verdict(enum.StrEnum):
    """What a bench test says about the valve.

    Members compare equal to their names as strings, which is how records
    and the history store them.
    """

    #: reusable
    PASS = "PASS"
    #: near the decision boundary: test again
    MARGINAL = "MARGINAL"
    #: worn: replace the valve
    FAIL = "FAIL"
    #: the test itself is not to be trusted; the classifier was not asked
    INVALID = "INVALID"
    #: a trustworthy test that was not classified (baseline calibration); never reported as PASS
    UNCLASSIFIED = "UNCLASSIFIED"

    @property
    def judges_the_valve(self) -> bool:
        """True for PASS, MARGINAL and FAIL: the classifier judged the valve."""
        return self in (Verdict.PASS, Verdict.MARGINAL, Verdict.FAIL)
