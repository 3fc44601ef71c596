"""What ``edc-bench test --json`` prints of a test: a typed value built once from the test's result.

The summary holds the record's own sections (the classification, the coil's finding, the stop, the tick timing...)
as they are; :meth:`TestSummary.as_json` is its one serialisation, so a script reads the same figures under the
same names as record.json gives them.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from edc_bench.engine.tick_timing import TickTiming
    from edc_bench.identification.sections import CoilFinding, ModelFitSummary
    from edc_bench.records.advice import Advice
    from edc_bench.records.record import BenchResult
    from edc_bench.records.schema import EscalationSummary, StopSummary
    from edc_bench.section import FeaturePair
    from edc_bench.verdict.retest import Decision
    from edc_bench.verdict.part_sections import PartDiagnosis
    from edc_bench.verdict.sections import ClassificationSummary, ParameterEstimate
    from edc_bench.verdict.verdicts import Verdict


@dataclasses.dataclass(frozen=True)
class TestSummary:
    """One test as ``test --json`` prints it (a retest's also holds its first test's, ``first_test``).

    Attributes
    ----------
    verdict, advice, reasons
        The verdict, what the technician does next, and why.
    valve_id, variant
        Which valve, on which pump variant.
    features, features_volt
        af and a1 as judged (referred to the reference coil), and with this test's coil.
    coil
        The coil's resistance and warming, measured during the test.
    parameters
        Every identified parameter; its truth and error only on a simulated rig.
    converged, settle_s, condition_number, model_fit
        How the estimate converged, and how well the pump's model fits (None where the test did not identify).
    classification
        The classifier's judgement, naming the model.
    stop, timing, clock
        Why and when the test ended, how the loop kept time, and on which clock.
    record_dir
        The record folder (None: not written).
    truth
        The simulated plant's parameters (a simulated rig only; left out otherwise).
    decision
        A retest's: what it and the MARGINAL before it decide (left out otherwise).
    escalation
        The same valve INVALID twice: it may be seized (None otherwise).
    part
        Which part of the module is at fault (the valve, the rack, the rack-travel sensor), with every signature's
        figure against its limit (None where the test identified nothing).
    first_test
        A retest's: the first test's summary (left out otherwise).
    """

    __test__ = False  # not a pytest class, whatever its name

    verdict: Verdict
    advice: Advice
    reasons: list[str]
    valve_id: str
    variant: str
    features: FeaturePair
    features_volt: FeaturePair
    coil: CoilFinding | None
    parameters: dict[str, ParameterEstimate]
    converged: bool | None
    classification: ClassificationSummary | None
    settle_s: float | None
    condition_number: float | None
    model_fit: ModelFitSummary | None
    stop: StopSummary | None
    timing: TickTiming
    clock: str
    record_dir: str | None
    truth: dict[str, float] | None = None
    decision: Decision | None = None
    escalation: EscalationSummary | None = None
    part: PartDiagnosis | None = None
    first_test: TestSummary | None = None

    @classmethod
    def of(cls, result: BenchResult, record_dir: Path | None, decision: Decision | None = None) -> TestSummary:
        """The summary of ``result``, written to ``record_dir`` (``decision``: a retest's)."""
        from edc_bench.records.escalation_link import recorded_escalation

        ident = result.identification
        return cls(
            verdict=result.verdict, advice=result.advice, reasons=list(result.reasons), part=result.judgement.part,
            valve_id=result.valve_id,
            variant=result.variant.name, features=result.features, features_volt=result.judgement.features_volt,
            coil=result.judgement.coil, parameters=dict(result.parameters), converged=result.converged,
            classification=result.classification,
            settle_s=None if ident is None else ident.settle_s,
            condition_number=None if ident is None else ident.condition_number,
            model_fit=None if ident is None or ident.model_fit is None else ident.model_fit.summary(),
            stop=result.stop, timing=result.timing, clock=result.clock,
            record_dir=str(record_dir) if record_dir else None,
            truth=None if result.truth is None else result.truth._asdict(),
            decision=decision, escalation=recorded_escalation(record_dir))

    def as_json(self) -> dict[str, Any]:
        """The ``--json`` output (JSON-safe: no NaN); ``truth``, ``decision`` and ``first_test`` only where given."""
        from edc_bench.records.writer import json_safe

        out: dict[str, Any] = {}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if field.name in ("truth", "decision", "first_test") and value is None:
                continue
            out[field.name] = value
        out["advice"] = {"action": self.advice.action, "words": self.advice.words}
        # truth and its error only where there is one (a simulated rig), as the JSON always gave them
        out["parameters"] = {name: p.model_dump(exclude=None if p.truth is not None else {"truth", "error_rel"})
                             for name, p in self.parameters.items()}
        if self.decision is not None:
            out["decision"] = self.decision.as_dict()
        if self.escalation is not None:
            out["escalation"] = self.escalation.model_dump()
        if self.first_test is not None:
            out["first_test"] = self.first_test.as_json()
        return json_safe(out)
