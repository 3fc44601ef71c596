"""The MARGINAL procedure: when the bench tests a valve again, and what the two tests decide together.

A MARGINAL valve is near the limit: one test cannot say on which side. The bench tests it again at once (on the
simulated rig with new sensor noise) and the variant's ``[retest]`` rule
(:class:`~edc_bench.config.models.RetestSection`) says what the pair decides, so a technician never has to weigh
two numbers. Pure: verdicts in, a decision out.
"""

from __future__ import annotations

from dataclasses import dataclass

from edc_bench.config.models import RetestSection
from edc_bench.verdict.sections import RetestSummary
from edc_bench.verdict.verdicts import Verdict

#: What each retest verdict is called in the decision's words.
_SAID = {Verdict.PASS: "then clear of it", Verdict.MARGINAL: "twice", Verdict.FAIL: "then worn",
         Verdict.INVALID: "then not judged"}
#: What the technician does on each decision.
_DO = {Verdict.PASS: "refit the valve", Verdict.FAIL: "replace the valve"}


@dataclass(frozen=True)
class Decision:
    """What a test and its retest decide together.

    Attributes
    ----------
    verdict : Verdict
        PASS (refit), FAIL (replace) or INVALID (the retest was not judged).
    words : str
        The technician's line, e.g. ``near the limit twice: replace the valve``.
    rule : str
        The variant's rule that decided, e.g. ``retest.decide.MARGINAL = FAIL``.
    """

    verdict: Verdict
    words: str
    rule: str

    def as_dict(self) -> dict[str, str]:
        """The decision as plain data (``--json``)."""
        return {"verdict": str(self.verdict), "words": self.words, "rule": self.rule}

    def record_entry(self, first_record: str, first_verdict: Verdict | str) -> RetestSummary:
        """The retest's record.json ``retest`` section: the first test's folder name and verdict, and this
        decision."""
        return RetestSummary(of_record=first_record, of_verdict=Verdict(first_verdict), decision=self.verdict,
                             words=self.words, rule=self.rule)


def retest_wanted(verdict: Verdict | str, rule: RetestSection) -> bool:
    """True when the bench tests the valve again after this verdict (a MARGINAL, unless the variant says not)."""
    return Verdict(verdict) == Verdict.MARGINAL and rule.after_marginal


def decide(second: Verdict | str, rule: RetestSection, check_words: str = "") -> Decision:
    """What a MARGINAL test and its retest decide.

    Parameters
    ----------
    second : Verdict
        The retest's verdict.
    rule : RetestSection
        The variant's ``[retest]`` section.
    check_words : str, optional
        For a retest that was not judged: what to check (its own advice, e.g. ``not judged: check the cable``).

    Returns
    -------
    Decision
    """
    second = Verdict(second)
    verdict = Verdict(rule.decide[second.value])
    head = f"near the limit {_SAID[second]}"
    if verdict == Verdict.INVALID:
        what = check_words.removeprefix("not judged: ") or "check the valve's mounting and the rig"
        words = f"{head}: {what}; then test the valve again"
    else:
        words = f"{head}: {_DO[verdict]}"
    return Decision(verdict, words, f"retest.decide.{second.value} = {verdict.value}")
