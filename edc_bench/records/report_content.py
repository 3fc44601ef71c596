"""What the report's two pages say, as text made from the record alone (no drawing here).

Page 1 is the paper a shop hands to the customer: who tested what, when
(local time, with its offset from UTC), the verdict and what to do, in
words a customer reads. Page 2 is the engineer's: every figure behind the
verdict (P(faulty), the distance to the boundary, the model's digest, the
baseline, the fit, the timing), as record.json holds them.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from pathlib import Path

from edc_bench.records.advice import CUSTOMER_WORDS
from edc_bench.verdict.part_sections import Part
from edc_bench.verdict.part_words import customer_words, finding_row, part_line
from edc_bench.records.baseline_text import baseline_line
from edc_bench.records.schema import Record
from edc_bench.runtime.clock_kind import ClockKind
from edc_bench.timefmt import offset_text
from edc_bench.verdict.verdicts import Verdict

#: units of the identified parameters, as the parameter table heads them
UNITS = {"a3": "V s\u00b3/mm", "a2": "V s\u00b2/mm", "a1": "V s/mm", "a0": "V/mm", "b": "V", "af": "V"}
#: the record's clock, as the engineer's page says it
_CLOCKS = {ClockKind.SIMULATED: "simulated time", ClockKind.REAL_TIME: "real time"}
#: the parameters in the table's order: the two diagnosis features first
PARAMETER_ORDER = ("af", "a1", "a0", "a2", "b", "a3")


def local_time(started_at: str) -> str:
    """A record's start (ISO 8601 with offset) in this machine's time zone, with the offset from UTC.

    ``"2026-11-26T10:04:00+00:00"`` drawn on a machine in Central European
    time gives ``"2026-11-26 11:04 (UTC+01:00)"``; a date without an offset
    or that does not parse is shown as recorded.
    """
    try:
        when = datetime.fromisoformat(started_at)
    except ValueError:
        return started_at or "not recorded"
    if when.tzinfo is None:
        return f"{when:%Y-%m-%d %H:%M} (time zone not recorded)"
    local = when.astimezone()
    return f"{local:%Y-%m-%d %H:%M} (UTC{offset_text(local)})"


def utc_time(started_at: str) -> str:
    """A record's start in UTC to the second (the engineer's page gives both)."""
    try:
        when = datetime.fromisoformat(started_at)
    except ValueError:
        return started_at or "not recorded"
    if when.tzinfo is None:
        return f"{when:%Y-%m-%d %H:%M:%S} (time zone not recorded)"
    return f"{when.astimezone(UTC):%Y-%m-%d %H:%M:%S} UTC"


def pump_text(record: Record) -> str:
    """The pump type: the variant's name and its data sheet's description."""
    pump = (record.config or {}).get("pump")
    description = str(pump.get("description", "")).strip() if isinstance(pump, dict) else ""
    name = record.variant or "not recorded"
    return f"{name}: {description}" if description else name


def test_rows(record: Record) -> list[tuple[str, str]]:
    """Page 1's who and when: the workshop (from the station's settings, when set), the date, station and operator."""
    identity = record.identity
    workshop = ", ".join(filter(None, [identity.shop, *identity.shop_address.splitlines()]))
    # the station as the shop named it for customers; a record from before that printed what it held
    shown_station = identity.station if identity.station_shown is None else identity.station_shown
    rows = [("Workshop", workshop)] if workshop else []
    rows += [("Date", local_time(record.started_at)),
             *([("Station", shown_station)] if shown_station else []),
             ("Operator", identity.operator or "-")]
    if record.simulated_rig:  # a demonstration or a test run: never to be taken for a valve's test on a rig
        rows.append(("Rig", "SIMULATED: no real valve was tested"))
    return rows


def pump_rows(record: Record) -> list[tuple[str, str]]:
    """Page 1's what: the pump and the valve tested."""
    return [("Pump type", pump_text(record)),
            ("Part number", record.part_number or "-"),
            ("Pump serial", record.identity.pump_serial or "-"),
            ("Valve", record.valve_id or "-")] + ([("Job / vehicle", record.identity.job_ref)]
                                                  if record.identity.job_ref else [])


def pair_decision(record: Record) -> str:
    """What a retested MARGINAL and its retest decide, seen from either test's record ("" for a single test)."""
    if record.retest is not None and record.retest.decision:
        return record.retest.decision
    if record.retested_by is not None and record.retested_by.decision:
        return record.retested_by.decision
    return ""


def shown_verdict(record: Record) -> str:
    """The verdict the customer is given: a retest pair's decision (on both tests' reports), else the test's."""
    return pair_decision(record) or str(record.verdict)


#: page 1's line for a valve not judged twice, both times for a cause the valve itself can cause (the technician's
#: is :data:`~edc_bench.records.advice.SEIZED`)
SEIZED_FOR_CUSTOMER = ("Tested twice, and both times the valve did not move as a sound valve does: it may be seized. "
                       "Replace the valve, or have it examined by an engineer.")


def advice_sentence(record: Record) -> str:
    """The technician's line (:mod:`~edc_bench.records.advice`) as a sentence: ``Worn: replace the valve.``; a
    retest pair's (on either test's report): what the two decided; a valve not judged twice for its own cause: that
    it may be seized, in a customer's words."""
    if record.escalation is not None and record.verdict == Verdict.INVALID:
        return SEIZED_FOR_CUSTOMER
    pair = record.retest if record.retest is not None and record.retest.words else record.retested_by
    words = (pair.words if pair is not None and pair.words else record.advice.words).strip()
    return (words[:1].upper() + words[1:] + ("" if words.endswith(".") else ".")) if words else ""


def findings(record: Record) -> list[str]:
    """Page 1's plain findings under the verdict: the change against a new valve, the coil, a caution."""
    lines = []
    if record.retest is not None and record.retest.decision:
        lines.append(f"Tested twice: {record.retest.of_verdict or 'MARGINAL'} (near the limit), then {record.verdict} "
                     f"on the retest; together they decide {record.retest.decision}.")
    elif record.retested_by is not None and record.retested_by.decision:
        later = record.retested_by
        lines.append(f"Tested twice: {record.verdict} (near the limit) in this test, then {later.verdict} on the "
                     f"retest (record {later.record}); together they decide {later.decision}.")
    cls = record.classification
    if cls is not None:
        af, a1 = cls.features_rel.numbers()
        if cls.features_rel.identified:
            lines.append(f"Friction (af) {_percent(af - 1)} and damping (a1) {_percent(a1 - 1)} compared with "
                         "a new valve of this pump type.")
    coil = coil_sentence(record)
    if coil:
        lines.append(coil)
    baseline = record.baseline
    if baseline is not None and baseline.calibrated is False:
        lines.append("Compared with the pump type's data-sheet figures, not with measured new valves: this verdict "
                     "may be wrong until the pump type is calibrated (edc-bench calibrate --append).")
    part = customer_words(record.part)
    if part:
        lines.append(part)
    if record.verdict == Verdict.INVALID:
        # the customer's words only: the reasons, with their figures, are the engineer's page's
        lines.append("The test could not judge the valve: this report says nothing about its condition.")
        lines.append(CUSTOMER_WORDS[record.invalid_cause])
        if record.escalation is not None:
            lines.append(f"The same valve's test before this one could not judge it either (record "
                         f"{record.escalation.of_record}).")
    return lines


#: page 1's words for a pump the model does not fit (#11): a longer test will not help; what to check instead
MODEL_DOES_NOT_FIT = ("The model does not fit this pump: a longer test will not help. Check that the variant is this "
                      "pump's (its coil and spring), that the rack moves freely and that the solenoid's armature and "
                      "wiring are sound; a pump that behaves like this needs its own variant (docs/faults.md).")


def coil_sentence(record: Record) -> str:
    """The coil's resistance at 20 degC against its spec, or nothing when it was not measured."""
    coil = record.coil
    if coil is None or coil.resistance_20c_ohm is None:
        return ""
    measured = f"Coil resistance {coil.resistance_20c_ohm:.3f} \u03a9 at 20 \u00b0C"
    low, high = coil.spec_ohm
    if coil.in_spec is None or (low is None and high is None):
        return f"{measured} (no spec for this pump type)."
    spec = (f"at most {high:g} \u03a9" if low is None else f"at least {low:g} \u03a9" if high is None
            else f"{low:g} to {high:g} \u03a9")
    return f"{measured}: {'in spec' if coil.in_spec else 'OUT OF SPEC'} ({spec})."


def _percent(fraction: float) -> str:
    return f"{fraction:+.1%}".replace("%", " %")


def _number(value: float | None, spec: str = ".4g", missing: str = "-") -> str:
    return missing if value is None or not math.isfinite(value) else format(value, spec)


def parameter_rows(record: Record) -> list[list[str]]:
    """The parameter table: name, unit, value, its standard error, the reference, its source, the change."""
    refs = {name: (entry.value, entry.source) for name, entry in record.reference_values.items()
            if entry.value is not None}
    rows = []
    for name in PARAMETER_ORDER:
        p = record.parameters.get(name)
        if p is None:
            continue
        ref, source = refs.get(name, (None, ""))
        change = _percent(p.value / ref - 1) if p.value is not None and ref else ""
        rows.append([name, UNITS.get(name, ""), _number(p.value, ".5g"),
                     _number(p.std, ".2g") if p.estimated else "fixed", _number(ref, ".5g"),
                     source or "not recorded", change])
    return rows


def classifier_rows(record: Record) -> list[tuple[str, str]]:
    """The model that judged and what it said, to the last digit the record holds."""
    cls = record.classification
    if cls is None:
        return [("Not asked", "the test was not judged (its reasons are below)")]
    band = cls.marginal_band
    rows = [("Model", f"{cls.model_name or cls.model or 'not recorded'} ({cls.model or '?'} classifier)"),
            ("Model file", cls.model_file or "not recorded"),
            ("SHA-256", cls.model_sha256 or "not recorded"),
            ("P(faulty)", f"{cls.probability_faulty:.4f}"
                          + (f" (threshold {cls.threshold:g})" if cls.threshold is not None else "")),
            ("Distance", (f"{cls.distance:+.4f} to the boundary" if cls.distance is not None
                          else "beyond the classifier's scan (more than 3) from the boundary")
                         + (f" (marginal band \u00b1{band:g}; positive: worn side)" if band is not None else "")),
            ("Features", f"af {_number(cls.features_rel.af, '.4f')}, "
                         f"a1 {_number(cls.features_rel.a1, '.4f')} \u00d7 the baseline")]
    if cls.training_data_sha256:
        rows.append(("Training data", cls.training_data_sha256))
    return rows


def baseline_rows(record: Record) -> list[tuple[str, str]]:
    """The new-valve baseline the features were divided by, and where it came from."""
    baseline = record.baseline
    if baseline is None:
        return [("Baseline", baseline_line(None))]
    rows = [("Baseline", baseline_line(baseline))]
    if baseline.af_v is not None and baseline.a1_v_s_per_mm is not None:
        rows.append(("Values", f"af {baseline.af_v:.5g} V, a1 {baseline.a1_v_s_per_mm:.5g} V s/mm"))
    if baseline.path:
        rows.append(("File", Path(baseline.path).name))
    return rows


def coil_rows(record: Record) -> list[tuple[str, str]]:
    """The coil as measured: resistance, its referral to 20 degC, inductance."""
    coil = record.coil
    if coil is None or coil.resistance_ohm is None:
        return [("Coil", "not measured")]
    rows = [("Coil", (coil_sentence(record) or "").removeprefix("Coil resistance ") or "-"),
            ("Measured", f"{coil.resistance_ohm:.4f} \u03a9 at the end, {_number(coil.resistance_start_ohm, '.4f')} "
                         f"\u03a9 at the start")]
    temp = f"{_number(coil.temp_start_c, '.1f')} \u00b0C at the start ({coil.temp_source or 'source not recorded'})"
    if coil.warming_k is not None:
        temp += f", warmed {coil.warming_k:.1f} K"
    rows.append(("Temperature", temp))
    if coil.inductance_mh is not None:
        rows.append(("Inductance", f"{coil.inductance_mh:g} mH, {coil.inductance_source or 'source not recorded'}"))
    return rows


def test_details_rows(record: Record) -> list[tuple[str, str]]:
    """How the test ran: when, how long, how much of the excitation the fit used, on what."""
    rows = [("Started", f"{utc_time(record.started_at)}, local {local_time(record.started_at)}"),
            ("Rig / clock", f"{'simulated rig' if record.simulated_rig else 'bench rig'}, "
                            f"{_CLOCKS.get(record.clock, record.clock or 'clock not recorded')}")]
    stop = record.stop
    if stop is not None and stop.time_s is not None:
        rows.append(("Ended", f"after {stop.time_s:.1f} s of at most {stop.max_s or 0:g} s: "
                              f"{stop.reason or 'reason not recorded'}"))
    ident = record.identification
    if ident is not None and ident.periods:
        fit = f"{ident.periods} period{'s' if ident.periods != 1 else ''} of {ident.period_s or 0:g} s"
        if ident.samples_used is not None:
            fit += f", {ident.samples_used} samples"
        if ident.condition_number is not None:
            fit += f", condition number {ident.condition_number:.3g}"
        rows.append(("Period fit", fit))
    if ident is not None and ident.estimator:
        rows.append(("Estimator", ident.estimator))
    if record.escalation is not None:
        escalated = record.escalation
        rows.append(("Escalated", f"the valve may be seized: {escalated.of_verdict or 'INVALID'} before too, both "
                                  f"times for its own cause ({escalated.of_cause or '?'}); the earlier test: "
                                  f"{escalated.of_record}"))
    rows.append(("Versions", f"edc-bench {record.software_version or '?'}, ICD {record.icd_version or '?'}, "
                             f"rig firmware {record.firmware_version or 'not recorded'}"))
    return rows


def part_rows(record: Record) -> list[tuple[str, str]]:
    """What the part diagnosis found beyond its limits, and the signatures within them (page 2; the part at fault
    itself is in the page's header)."""
    part = record.part_diagnosis
    if part.part is Part.NOT_JUDGED:
        return [("Part at fault", part_line(record.part)),
                ("Note", "recorded before the part diagnosis: the valve alone was judged")]
    # the part itself heads the page (its header's rows): here what was measured
    rows = [finding_row(f) for f in part.findings if f.beyond] or [("Part at fault", part_line(record.part))]
    within = [str(f.signature) for f in part.findings if not f.beyond]
    if within:
        rows.append(("Within limits", ", ".join(within)))
    return rows


def model_fit_rows(record: Record) -> list[tuple[str, str]]:
    """How well the pump model fits the measurement, and the problems when it does not."""
    fit = record.identification.model_fit if record.identification is not None else None
    if fit is None:
        return [("Model fit", "not assessed (no whole excitation period was fitted)")]
    rows = [("Fits", "yes" if fit.fits else ("NO" if fit.fits is False else "not assessed"))]
    if fit.residual_ratio is not None:
        rows.append(("Residual", f"{fit.residual_ratio:.2f} \u00d7 the sensor noise "
                                 f"({_number(_milli(fit.residual_rms_v), '.3f')} mV rms)"))
    if fit.systematic_ratio is not None:
        rows.append(("Systematic", f"{fit.systematic_ratio:.2f} \u00d7 the sensor noise (the same every period)"))
    spread = {name: value for name, value in (fit.spread_rel or {}).items()
              if value is not None and math.isfinite(value)}
    if spread:
        rows.append(("Spread", ", ".join(f"{name} {value * 100:.2f} %" for name, value in spread.items())
                     + " period to period"))
    elif fit.spread_rel is not None:
        rows.append(("Spread", "not measured (fewer than two whole periods)"))
    if fit.gain_variation_rel is not None:
        rows.append(("Gain variation", f"\u00b1{_number(_hundred(fit.gain_variation_rel), '.2f')} % (solenoid)"))
    rows += [("Problem", problem) for problem in fit.problems]
    return rows


def _milli(value: float | None) -> float | None:
    return None if value is None else value * 1e3


def _hundred(value: float | None) -> float | None:
    return None if value is None else value * 100


def timing_rows(record: Record) -> list[tuple[str, str]]:
    """The loop's timing and the bus, as the test measured them."""
    loop, timing = record.loop, record.timing
    planned = f" of {loop.ticks_planned} planned" if loop.ticks_planned else ""
    rows = [("Ticks", f"{loop.ticks_run}{planned}; {loop.ticks_late} late, {loop.missed_replies} replies missing")]
    lateness = timing.lateness_us
    if lateness is not None:
        rows.append(("Lateness", "p50 {:.0f} \u00b5s, p99 {:.0f} \u00b5s, max {:.0f} \u00b5s".format(*lateness)))
    # an older record without the figure in its timing: the loop's
    steal = timing.cpu_steal_s if "cpu_steal_s" in timing.model_fields_set else loop.cpu_steal_s
    rows.append(("CPU steal", f"{steal:.2f} s"))
    if loop.abort_reason:
        rows.append(("Aborted", loop.abort_reason))
    return rows


def reason_lines(record: Record) -> list[str]:
    """The verdict's reasons and the test's problems, as recorded; for a pump the model does not fit, what to check."""
    lines = list(record.reasons)
    if record.problems:
        lines.append("problems: " + ", ".join(record.problems))
    fit = record.identification.model_fit if record.identification is not None else None
    if record.verdict == Verdict.INVALID and fit is not None and fit.fits is False:
        lines.append(MODEL_DOES_NOT_FIT)
    return lines
