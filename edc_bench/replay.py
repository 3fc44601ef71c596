"""Replay a test from its CAN log: the identification and the verdict again, from the frames alone.

The log holds every command the bench sent and every reply it read, in the
order it read them. The bench loop used, at tick k, the rack position of
the reply to command k-1 (the last one accepted if it was missing). Replay
feeds the same positions, tick by tick, to a controller built from the same
variant, so the estimator walks the same path bit for bit; each drive it
computes is checked against the command that was logged (to the codec's
1 mV). The trace it rebuilds is judged by the same code as the live test
(:func:`edc_bench.verdict.judgement.judge_run`).

What a CAN log cannot hold is taken from the record when there is one: the
tick timing (lateness, ticks late) and why the loop stopped. A raw log alone
is judged without them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from edc_bench.config import parse_variant
from edc_bench.config.loader import without_retired_keys
from edc_bench.config.models import Variant
from edc_bench.control.fel import FelController
from edc_bench.engine.abort_figures import LogEndsFigures
from edc_bench.engine.outcome import Abort, AbortKind, LoopOutcome
from edc_bench.engine.tick import TickEngine
from edc_bench.errors import ConfigError
from edc_bench.identification.trust import Problem
from edc_bench.physics.feedforward import nominal_parameters
from edc_bench.protocol import BENCH_CMD_ID, Icd, Mode, default_icd
from edc_bench.records.reader import LoggedFrame
from edc_bench.records.consistency import PART_SCHEMA, STALL_ROWS_SCHEMA
from edc_bench.records.schema import Record
from edc_bench.engine.tick_timing import TickTiming
from edc_bench.verdict.baseline import Baseline
from edc_bench.verdict.judgement import Judgement, judge_run
from edc_bench.verdict.verdicts import Verdict

#: The command carries the drive in mV; a replayed drive further off than this is a different run.
DRIVE_TOLERANCE_V = 0.0005 + 1e-9


@dataclass
class ReplayedRun:
    """The rebuilt run: its trace, its controller and what the frames say about the loop."""

    trace: dict[str, np.ndarray]
    controller: FelController
    ticks: int
    missed_replies: int
    max_drive_deviation_v: float
    gaps: int = 0
    ticks_lost: int = 0
    notes: list[str] = field(default_factory=list)


def replay_frames(frames: list[LoggedFrame], variant: Variant, *, ticks_start_s: float = 0.0,
                  icd: Icd | None = None, recorded_variant: bool = False) -> ReplayedRun:
    """Rebuild a test's trace and controller from its frames, through the loop's own tick engine.

    The frames are taken in the order the loop logged them: a RUN command is
    a tick (its counter says which, so ticks lost to a host stall show as a
    jump), and each frame logged after it goes to the engine as the loop
    handed it over between that tick and the next, so the controller is fed
    exactly the samples the loop used.

    Parameters
    ----------
    frames : list of (time, CAN id, payload)
        The CAN log, in the order the bench logged it.
    variant : Variant
        The variant as the test ran it.
    ticks_start_s : float, optional
        Clock time of tick 0 (the record's ``loop.ticks_start_s``), so the
        trace's times are computed as the loop computed them.
    recorded_variant : bool, optional
        ``variant`` is the record's own (the test ran with it): drives that differ then point at the log, not at
        the variant.

    Raises
    ------
    ConfigError
        If the log has no test in it, or the drives it computes are not the
        ones logged (another variant, another software version).
    """
    icd = icd or default_icd()
    capacity = int(round(variant.excitation.duration_s / variant.controller.period_s))
    engine = TickEngine(variant, icd, capacity)
    worst = 0.0
    first_off: int | None = None
    k = -1
    # every frame goes to the engine, as the loop handed it over: the rig's frames through receive() (the log's
    # times are not the loop's clock: a reply's latency is not known here), the bench's own commands through
    # logged_command(), which knows the synchronising SAFE and numbers each RUN's tick by its counter
    for _, can_id, data in frames:
        if can_id != BENCH_CMD_ID:
            engine.receive(can_id, data, math.nan)
            continue
        logged = engine.logged_command(data)
        if logged is None:
            continue
        if logged.mode != Mode.RUN:
            if engine.ticking:
                break  # the safe stop: the ticks are over
            continue
        if not engine.ticking:
            if engine.sync_reply is None or engine.safe_counter is None:
                break
            engine.start(engine.sync_reply, engine.safe_counter, ticks_start_s)
        tick = logged.tick
        if tick is None:  # a RUN always has one (logged_command)
            continue
        if tick >= capacity:
            raise ConfigError(f"the CAN log has more than the variant's {capacity} ticks: "
                              "give the variant the test ran with")
        if tick > k + 1:
            engine.skip(k + 1, tick - k - 1)
        k = tick
        made = engine.command(k)
        off = abs(made.drive_v - logged.drive_v)
        if off > DRIVE_TOLERANCE_V and first_off is None:
            first_off = k
        worst = max(worst, off)
        engine.sent(k, math.nan, math.nan)
    if k < 0:
        raise ConfigError("the CAN log holds no bench test (no synchronising SAFE reply followed by RUN commands)")
    if worst > DRIVE_TOLERANCE_V:
        where = f"replayed drives differ from the logged commands from tick {first_off} on, by up to " \
                f"{worst * 1e3:.1f} mV"
        if recorded_variant:  # the test's own variant: what changed is the log (or the controller that reads it)
            raise ConfigError(f"{where}: the CAN log is not the one the test wrote (changed or cut after the test), "
                              "or this edc-bench's controller is not the one that ran it (its software_version)")
        raise ConfigError(f"{where}: the log was not made with this variant (or this edc-bench version's "
                          "controller)")
    outcome = engine.outcome
    return ReplayedRun(engine.trace.view(), engine.controller, k + 1, engine.matcher.counts.missed, worst,
                       gaps=outcome.gaps, ticks_lost=outcome.ticks_lost)


@dataclass
class ReplayReport:
    """A replay's judgement, and how it compares with the record's."""

    judged: Judgement
    run: ReplayedRun
    differences: list[str]
    compared: bool
    notes: list[str] = field(default_factory=list)  # how it was compared, when not to the bit

    @property
    def reproduced(self) -> bool:
        """True if compared with a record and nothing differs."""
        return self.compared and not self.differences


#: How close a record of an older schema must come (its controller summed in another order: the last bits differ).
OLDER_RECORD_REL_TOL = 1e-9
#: The first record schema whose figures replay must give to the bit (the controller's sums in today's order).
EXACT_SCHEMA = 4
#: The first record schema whose af and a1 are the period fit over the core rows (docs/method.md, section 7): an
#: older record's were the fit over every used row, and replay, which identifies as today's edc-bench does, says so.
CORE_ROWS_SCHEMA = 6
#: The first record schema whose uncertainties carry the held gain terms' error and whose interval the residual's
#: repeating part (docs/method.md, section 7): an older record's std are smaller, its early stop judged a narrower box.
RESIDUAL_SCHEMA = 7
#: The first record schema whose part diagnosis takes the solenoid's pull along the stroke out of a sensor's gain and
#: tells a sensor that reads unevenly from a rack that binds (#67): a schema 11 record's part may differ.
PART_METHOD_SCHEMA = 12
#: The first record schema whose part diagnosis allows the pump's return spring within the pump type's tolerance
#: (``[rack] spring_tolerance_rel``, ``preload_tolerance_rel``; #67): an older record's sensor may have been named
#: for a spring.
PUMP_SPRING_SCHEMA = 13


def _same(a: Any, b: Any, rel_tol: float = 0.0) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) and math.isnan(b):
            return True
        if rel_tol:
            return math.isclose(a, b, rel_tol=rel_tol, abs_tol=1e-300)
    return a == b


def compare_with_record(judged: Judgement, record: Record, rel_tol: float = 0.0) -> list[str]:
    """Every recorded figure the replay did not reproduce (exactly, or within ``rel_tol``), as readable lines."""
    diffs = []
    if judged.verdict != record.verdict:
        diffs.append(f"verdict: recorded {record.verdict}, replayed {judged.verdict}")
    for name, entry in judged.parameters.items():
        rec = record.parameters.get(name)
        for key in ("value", "std"):
            got, want = getattr(entry, key), None if rec is None else getattr(rec, key)
            got, want = (math.nan if v is None else v for v in (got, want))
            if not _same(float(got), float(want), rel_tol):
                diffs.append(f"{name} {key}: recorded {want!r}, replayed {got!r}")
    rec_cls, cls = record.classification, judged.classification
    if (rec_cls is None) != (cls is None):
        diffs.append("classification: present in one, absent in the other")
    elif cls is not None and rec_cls is not None:
        for key in ("probability_faulty", "distance"):
            if not _same(getattr(cls, key), getattr(rec_cls, key), rel_tol):
                diffs.append(f"{key}: recorded {getattr(rec_cls, key)!r}, replayed {getattr(cls, key)!r}")
    return diffs + _part_differences(judged, record, rel_tol)


def _part_method_note(judged: Judgement, record: Record, rel_tol: float) -> list[str]:
    """Why a record of schema 11 or 12 whose part replayed otherwise differs (none where it does not)."""
    if not PART_SCHEMA <= record.schema_version < PUMP_SPRING_SCHEMA or not _part_differences(judged, record,
                                                                                            rel_tol):
        return []
    if record.schema_version >= PART_METHOD_SCHEMA:
        return [f"recorded by an edc-bench whose part diagnosis did not allow the pump's return spring to differ "
                f"within the pump type's tolerance (record schema {record.schema_version}); today's does "
                "(docs/diagnosis.md, \"What the baseline must hold\"), so the sensor's linearity and the spring's "
                "figures, and the part, may differ"]
    return [f"recorded by an edc-bench whose part diagnosis read a sensor's gain without the solenoid's pull along "
            f"the stroke and had no test for a sensor that reads unevenly (record schema {record.schema_version}); "
            "today's has both (docs/diagnosis.md, \"Which part is at fault\"), so the part's figures, and the part, "
            "may differ"]


def _part_differences(judged: Judgement, record: Record, rel_tol: float) -> list[str]:
    """Where the replayed part diagnosis differs from the recorded one: the part, and each finding's figure."""
    diffs: list[str] = []
    if record.part is not None and judged.part is not None:
        if judged.part.part != record.part.part:
            diffs.append(f"part at fault: recorded {record.part.part}, replayed {judged.part.part}")
        for finding in judged.part.findings:
            held = record.part.finding(finding.signature)
            got = math.nan if finding.figure is None else float(finding.figure)
            want = math.nan if held is None or held.figure is None else float(held.figure)
            if not _same(got, want, rel_tol):
                diffs.append(f"{finding.signature}: recorded {want!r}, replayed {got!r}")
    return diffs


def record_variant(record: Record, source: str) -> Variant:
    """The variant exactly as the recorded test ran it (with its command-line overrides)."""
    config = record.config
    if config is None:
        raise ConfigError(f"{source}: the record holds no variant configuration")
    # a record of an older edc-bench may hold settings since retired; it replays under today's rules
    return parse_variant(without_retired_keys(config), f"{source} (recorded variant)")


def replay_record(folder: Any, classifier_path: Any = None, can_log: Any = None) -> ReplayReport:
    """Replay a record folder from its CAN log and compare with what it recorded.

    ``can_log`` replays another log of the same test instead of the folder's
    ``can.log`` (the log converted to ASC or BLF, the frames in ``trace.mf4``).
    """
    from pathlib import Path

    from edc_bench.records.reader import changed_since_written, load_record, read_can_log
    from edc_bench.records.writer import CAN_LOG_FILE

    folder = Path(folder)
    record = load_record(folder, check_integrity=False)  # replay compares; an altered record is one difference
    altered = changed_since_written(folder)
    variant = record_variant(record, str(folder))
    loop = record.loop
    frames = read_can_log(Path(can_log) if can_log is not None else folder / CAN_LOG_FILE)
    notes = []
    judged_by = record.classification.model_sha256 if record.classification is not None else None
    if classifier_path is None and judged_by and record.classification is not None:
        from edc_bench.verdict.classifier import find_model

        # judged by the model that judged it, whatever the station adopted since
        classifier_path = find_model(judged_by)
        if classifier_path is None:
            name = record.classification.model_name
            notes.append(f"the model that judged this test ({name}, sha256 {judged_by[:16]}...) is not on this "
                         "station: judged with the model that judges this variant's valves here")
    run = replay_frames(frames, variant, ticks_start_s=loop.ticks_start_s, recorded_variant=True)
    planned = run.ticks if loop.ticks_planned is None else loop.ticks_planned
    outcome = LoopOutcome(ticks_planned=planned, ticks_run=run.ticks, missed_replies=run.missed_replies,
                          abort=loop.abort, gaps=run.gaps, ticks_lost=run.ticks_lost)
    if "missed_replies" in loop.model_fields_set and loop.missed_replies != run.missed_replies:
        run.notes.append(f"missed replies: recorded {loop.missed_replies}, found {run.missed_replies} in the log")
    timing = record.timing
    classify = record.verdict != Verdict.UNCLASSIFIED
    coil = record.coil
    given = coil.temp_start_c if coil is not None and coil.temp_given else None
    # a record judged against the nominal baseline (--nominal-baseline) is replayed the same way
    recorded = record.baseline
    nominal = recorded is not None and recorded.calibrated is False
    # judged against the baseline the record was judged against, whatever the station holds now
    baseline = Baseline.from_summary(recorded.model_dump()) if recorded is not None and recorded.af_v else None
    if baseline is None and record.part is not None and record.part.compared_with is not None:
        # a test not judged held its pump's figures to this baseline all the same
        baseline = Baseline.from_summary(record.part.compared_with.model_dump())
    if Problem.NOT_CALIBRATED in record.problem_flags:
        nominal_figures = nominal_parameters(variant)  # refused then: refused again, even if calibrated since
        baseline = Baseline(nominal_figures.af, nominal_figures.a1)
    # a record from before the part diagnosis judged the valve alone: replayed the same way
    judged = judge_run(variant, run.trace, run.controller, outcome, timing, classify=classify,
                       classifier_path=classifier_path, coil_temp_c=given, nominal_baseline=nominal,
                       baseline=baseline, real_rig=record.real_time, diagnose=record.schema_version >= PART_SCHEMA)
    rel_tol = 0.0
    if record.schema_version < EXACT_SCHEMA:
        rel_tol = OLDER_RECORD_REL_TOL
        notes_after = [f"recorded by an older edc-bench (record schema {record.schema_version}): its figures are "
                       f"compared to {rel_tol:g} relative, not to the last bit (the controller's sums have been "
                       "reordered since)"]
    else:
        notes_after = []
    if record.schema_version < CORE_ROWS_SCHEMA:
        notes_after.append(f"recorded by an edc-bench whose af and a1 were the fit over every used row (record schema "
                           f"{record.schema_version}); today's are the fit over the core rows (docs/method.md, "
                           "section 7), so af, a1, their uncertainties and what follows from them (the early "
                           "stop, the verdict's distance) may differ from the recorded ones")
    elif record.schema_version < RESIDUAL_SCHEMA:
        notes_after.append(f"recorded by an edc-bench whose uncertainties left out the held gain terms' error, and "
                           f"whose interval the residual's repeating part (record schema {record.schema_version}); "
                           "today's have them (docs/method.md, section 7), so the parameters' std, and what follows "
                           "from the interval (the early stop), may differ from the recorded ones")
    ticks_run = max(record.timing.ticks, 1)
    over_limit = (record.timing.ticks_late + loop.ticks_lost) / ticks_run \
        > variant.acceptance.max_overrun_fraction
    if record.schema_version < STALL_ROWS_SCHEMA and over_limit:  # only where the rules can differ
        notes_after.append(f"recorded by an edc-bench that made a test INVALID for ticks lost to host stalls beyond "
                           f"the variant's limit whatever its fit (record schema {record.schema_version}); today's "
                           "leaves the rows a stall touched out of the fit and judges what remains, so the verdict "
                           "may differ from the recorded one")
    differences = compare_with_record(judged, record, rel_tol) + run.notes + notes
    notes_after += _part_method_note(judged, record, rel_tol)
    if altered:
        differences.insert(0, f"changed after the test (its integrity manifest): {', '.join(altered)}")
    return ReplayReport(judged, run, differences, compared=True, notes=notes_after)


#: In real time the early stop decides beside the ticks (runtime.stop_worker), and the loop ends at the first tick
#: after the decision: 14-80 ticks after the period's end measured on a slow, busy PC. A raw log that ends this close
#: after a whole period ended there (a log cut by chance this soon after one is taken for an early stop: a tenth of
#: a period's 2000 ticks).
EARLY_STOP_LAG_TICKS = 200


def _ends_at_a_period(variant: Variant, ticks: int) -> bool:
    """A log of ``ticks`` ticks ends where an early stop ends a test (after whole excitation periods)."""
    from edc_bench.identification.period_fit import FitSetup

    setup = FitSetup.from_variant(variant)
    periods = setup.blocks_in(ticks)
    return periods >= variant.acceptance.min_periods and 0 <= ticks - (setup.end_tick(periods) + 1) <= \
        EARLY_STOP_LAG_TICKS


def replay_can_log(path: Any, variant: Variant, classifier_path: Any = None,
                   nominal_baseline: bool = False) -> ReplayReport:
    """Replay a raw CAN log with a variant (no record: timing is not judged).

    ``nominal_baseline`` judges a variant without a measured baseline against the nominal one.
    """
    from edc_bench.records.reader import read_can_log

    frames = read_can_log(path)
    # a raw log does not say when the loop's clock started; its ticks are taken at k T exactly
    run = replay_frames(frames, variant)
    planned = int(round(variant.excitation.duration_s / variant.controller.period_s))
    abort = None if run.ticks == planned or _ends_at_a_period(variant, run.ticks) else \
        Abort(AbortKind.LOG_ENDS, LogEndsFigures(ticks=run.ticks, planned=planned))
    outcome = LoopOutcome(ticks_planned=planned, ticks_run=run.ticks, missed_replies=run.missed_replies,
                          gaps=run.gaps, ticks_lost=run.ticks_lost, abort=abort)
    timing = TickTiming(ticks=run.ticks)
    run.notes.append("raw CAN log: tick timing is not in it and was not judged")
    judged = judge_run(variant, run.trace, run.controller, outcome, timing, classifier_path=classifier_path,
                       nominal_baseline=nominal_baseline)
    return ReplayReport(judged, run, [], compared=False)
