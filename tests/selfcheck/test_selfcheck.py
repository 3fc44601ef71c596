"""The rig self-check: GO on the simulated rig, NO-GO naming the drift (and nothing else) when its sensors have
drifted; the judgement and the due rule as pure functions."""

from __future__ import annotations

import dataclasses
import datetime as dt

import pytest

from edc_bench.config import load_variant
from edc_bench.errors import ConfigError
from edc_bench.selfcheck import Registration, Rig, run_selfcheck, tolerances_of
from edc_bench.selfcheck.compare import Cause, ReferenceValues, Tolerances, compare
from edc_bench.selfcheck.due import LastCheck, SelfCheckPolicy, selfcheck_due
from edc_bench.selfcheck.measure import measure_simulated
from edc_bench.selfcheck.rest import rest_reading
from edc_bench.sim.drift import SensorDrift, parse_rig_drift

# -- on the simulated rig -------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def registration() -> Registration:
    """The reference valve (a new one) registered on the simulated rig with seed 0."""
    values, _ = measure_simulated(load_variant(), "new", 0)
    assert not values.test_problems
    return Registration(1, "bench1", "REF-1", "p-edc-default", values, simulated=True, valve_spec="new", seed=0,
                        registered_at="2026-11-27T08:00:00+00:00")


def _check(registration: Registration, drift: str | None = None, seed: int = 3):
    rig = Rig(drift=None if drift is None else parse_rig_drift(drift))
    return run_selfcheck(rig, registration, load_variant(registration.variant), seed=seed).result


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_the_simulated_rig_is_go_with_other_noise_than_the_registrations(registration: Registration) -> None:
    result = _check(registration)
    assert result.go and result.line() == "rig self-check: GO", result.line()
    assert not result.drifted and all(q.compared for q in result.quantities)


def test_an_lvdt_zero_moved_by_0_05_mm_is_named_and_nothing_else(registration: Registration) -> None:
    result = _check(registration, "lvdt_offset_mm=0.05")
    assert result.verdict == "NO-GO" and result.causes == (Cause.LVDT_ZERO,) and result.drifted == ("lvdt_zero_mm",)
    assert result.line().startswith("rig self-check: NO-GO: LVDT zero moved +0.050 mm (limit 0.02 mm): check the "
                                    "LVDT's mounting and zero it"), result.line()


def test_a_current_sensor_reading_3_percent_high_is_named_and_nothing_else(registration: Registration) -> None:
    result = _check(registration, "current_gain=1.03")
    assert result.causes == (Cause.CURRENT_GAIN,) and result.drifted == ("coil_r20_ohm",), result.line()
    assert result.quantity("coil_r20_ohm").drift == pytest.approx(1 / 1.03 - 1, abs=0.002)
    assert "coil resistance measured -2.9 % (limit 1.5 %): the current sensor's gain" in result.line()


@pytest.mark.slow
@pytest.mark.parametrize(("drift", "cause", "drifted"), [
    ("lvdt_gain=1.03", Cause.LVDT_GAIN, ("a0_v_per_mm", "a1_v_s_per_mm")),
    ("lvdt_offset_mm=-0.05", Cause.LVDT_ZERO, ("lvdt_zero_mm",)),  # below the frame's 0 mm: read as 0.000
    ("current_offset_a=0.02", Cause.CURRENT_ZERO, ("current_zero_a",)),
])
def test_the_other_drifts_are_named_alone(registration: Registration, drift: str, cause: Cause,
                                          drifted: tuple[str, ...]) -> None:
    result = _check(registration, drift)
    assert result.causes == (cause,) and result.drifted == drifted, result.line()


# -- the judgement, pure --------------------------------------------------------------------------------------------

REGISTERED = ReferenceValues(lvdt_zero_mm=0.005, current_zero_a=0.002, coil_r20_ohm=0.70, a0_v_per_mm=0.216,
                             af_v=0.0716, a1_v_s_per_mm=0.0039)


def _moved(**ratios: float) -> ReferenceValues:
    """The registration with figures scaled (the zeros shifted) as given."""
    changes = {name: (getattr(REGISTERED, name) + value if name in ("lvdt_zero_mm", "current_zero_a")
                      else getattr(REGISTERED, name) * value) for name, value in ratios.items()}
    return dataclasses.replace(REGISTERED, **changes)


@pytest.mark.parametrize(("measured", "causes", "drifted"), [
    (_moved(), (), ()),
    (_moved(lvdt_zero_mm=0.019, af_v=1.019, a1_v_s_per_mm=0.986), (), ()),  # within every limit
    (_moved(lvdt_zero_mm=0.05), (Cause.LVDT_ZERO,), ("lvdt_zero_mm",)),
    (_moved(current_zero_a=-0.02), (Cause.CURRENT_ZERO,), ("current_zero_a",)),
    (_moved(coil_r20_ohm=0.97), (Cause.CURRENT_GAIN,), ("coil_r20_ohm",)),
    (_moved(a0_v_per_mm=0.97, a1_v_s_per_mm=0.97), (Cause.LVDT_GAIN,), ("a0_v_per_mm", "a1_v_s_per_mm")),
    (_moved(a0_v_per_mm=1.05, af_v=1.05, a1_v_s_per_mm=1.05), (Cause.DRIVE,), ("a0_v_per_mm", "af_v", "a1_v_s_per_mm")),
    (_moved(af_v=1.3, a1_v_s_per_mm=1.4), (Cause.VALVE,), ("af_v", "a1_v_s_per_mm")),
    (_moved(a0_v_per_mm=0.97, a1_v_s_per_mm=1.2), (Cause.LVDT_GAIN, Cause.VALVE), ("a0_v_per_mm", "a1_v_s_per_mm")),
    (_moved(lvdt_zero_mm=0.05, coil_r20_ohm=1.03), (Cause.LVDT_ZERO, Cause.CURRENT_GAIN),
     ("lvdt_zero_mm", "coil_r20_ohm")),
])
def test_each_drift_is_named_by_what_moved(measured: ReferenceValues, causes: tuple[Cause, ...],
                                           drifted: tuple[str, ...]) -> None:
    result = compare(measured, REGISTERED, Tolerances())
    assert result.causes == causes and result.drifted == drifted, result.line()
    assert result.go == (not causes)
    for finding in result.findings:  # each says what to do, and to check again
        assert "then run the self-check again" in finding.words


def test_a_moved_figure_explained_by_its_cause_is_said_once() -> None:
    result = compare(_moved(a0_v_per_mm=0.97, a1_v_s_per_mm=0.97), REGISTERED, Tolerances())
    assert result.quantity("a1_v_s_per_mm").explained_by is Cause.LVDT_GAIN
    assert result.line().count("LVDT") == 2 and "damping a1 with it" in result.line()  # 'LVDT gain', 'LVDT's scale'


def test_a_zero_below_the_frames_floor_and_an_untrustworthy_test_are_no_go() -> None:
    floor = dataclasses.replace(REGISTERED, lvdt_zero_mm=0.0, lvdt_at_floor=True)
    result = compare(floor, REGISTERED, Tolerances())
    assert result.causes == (Cause.LVDT_ZERO,) and "down to 0.000 mm or below" in result.line()
    invalid = dataclasses.replace(REGISTERED, af_v=float("nan"), test_problems=("the rack did not follow",))
    result = compare(invalid, REGISTERED, Tolerances())
    assert result.causes == (Cause.TEST,) and "the rack did not follow" in result.line()
    assert not result.quantity("af_v").compared and result.quantity("lvdt_zero_mm").compared


def test_the_rest_reading_takes_the_median_and_sees_the_floor() -> None:
    import numpy as np

    reading = rest_reading(np.array([0.004, 0.005, 0.006, 0.0, 0.005]), np.array([0.001, 0.003]))
    assert reading.lvdt_zero_mm == 0.005 and reading.current_zero_a == pytest.approx(0.002)
    assert not reading.lvdt_at_floor
    assert rest_reading(np.array([0.0, 0.0, 0.001]), np.array([0.0])).lvdt_at_floor


def test_the_tolerances_are_the_variants() -> None:
    variant = load_variant()
    assert tolerances_of(variant) == Tolerances(lvdt_zero_mm=0.02, current_zero_a=0.01, coil_r20_rel=0.015,
                                                a0_rel=0.015, af_rel=0.02, a1_rel=0.02)
    # each below half the drift the done-when names: an LVDT zero moved 0.05 mm, a current gain of 3 %
    assert variant.selfcheck.lvdt_zero_mm <= 0.025 and variant.selfcheck.coil_r20_rel <= 0.015


# -- the due rule, pure ---------------------------------------------------------------------------------------------

NOW = dt.datetime(2026, 11, 27, 12, 0, tzinfo=dt.UTC)


@pytest.mark.parametrize(("last", "tests", "policy", "due"), [
    (LastCheck(NOW - dt.timedelta(hours=1), True), 5, SelfCheckPolicy(), None),
    (LastCheck(NOW - dt.timedelta(days=30), True), 5000, SelfCheckPolicy(), None),  # nothing asked
    (None, 0, SelfCheckPolicy(), None),
    (None, 0, SelfCheckPolicy(every_tests=100), "no rig self-check on record"),
    (LastCheck(NOW - dt.timedelta(hours=1), True), 99, SelfCheckPolicy(every_tests=100), None),
    (LastCheck(NOW - dt.timedelta(hours=1), True), 100, SelfCheckPolicy(every_tests=100),
     "100 tests since the last rig self-check (2026-11-27 11:00 +00:00); one is required every 100 tests"),
    (LastCheck(NOW - dt.timedelta(hours=7.9), True), 3, SelfCheckPolicy(every_hours=8), None),
    (LastCheck(NOW - dt.timedelta(hours=8), True), 3, SelfCheckPolicy(every_hours=8),
     "8.0 hours since the last rig self-check"),
    (LastCheck(NOW - dt.timedelta(minutes=5), False), 0, SelfCheckPolicy(),
     "the last rig self-check (2026-11-27 11:55 +00:00) was NO-GO"),
])
def test_a_check_is_due_every_n_tests_or_hours_and_after_a_no_go(last: LastCheck | None, tests: int,
                                                                  policy: SelfCheckPolicy, due: str | None) -> None:
    said = selfcheck_due(last, tests, NOW, policy)
    assert (said is None) == (due is None), said
    if due is not None:
        assert said is not None and said.startswith(due), said


def test_a_session_over_several_variants_holds_to_the_strictest_policy() -> None:
    strict = SelfCheckPolicy.strictest(SelfCheckPolicy(every_tests=200), SelfCheckPolicy(every_tests=50,
                                                                                          every_hours=24),
                                       SelfCheckPolicy())
    assert strict == SelfCheckPolicy(every_tests=50, every_hours=24)
    assert SelfCheckPolicy.of_variant(load_variant()) == SelfCheckPolicy()


# -- the simulated rig's drift option -------------------------------------------------------------------------------


def test_a_drift_is_parsed_and_bad_ones_are_refused_in_words() -> None:
    assert parse_rig_drift("lvdt_offset_mm=0.05, current_gain=1.03") == SensorDrift(lvdt_offset_mm=0.05,
                                                                                    current_gain=1.03)
    assert parse_rig_drift("none").none and parse_rig_drift("lvdt_gain=1.02").spec() == "lvdt_gain=1.02"
    for text, words in (("lvdt_offset=0.05", "is not a drift"), ("current_gain=abc", "not a number"),
                        ("current_gain=3", "outside 0.5..1.5"), ("lvdt_gain=1.1,lvdt_gain=1.2", "given twice"),
                        ("current_gain=nan", "outside")):
        with pytest.raises(ConfigError, match=words):
            parse_rig_drift(text)


@pytest.mark.parametrize(("sensor", "said"), [("spikes", "spikes"),
                                               pytest.param("noise_sd_mm=0.02", "noise", marks=pytest.mark.slow)])
def test_an_lvdt_whose_signal_spikes_or_is_noisy_is_named_not_the_reference_valve(sensor: str, said: str) -> None:
    """#67: the self-check judges the LVDT's own signal by the part diagnosis's signatures (a pump's test and the
    self-check say the same): noise and spikes were blamed on the reference valve."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    from edc_bench.selfcheck.compare import Cause, compare
    from edc_bench.selfcheck.measure import reference_values
    from edc_bench.selfcheck.rest import RestReading

    variant = load_variant("p-edc-default")
    rest = RestReading(lvdt_zero_mm=0.005, current_zero_a=0.002, lvdt_sd_mm=0.003, current_sd_a=0.005, samples=500,
                       lvdt_at_floor=False)
    registered = reference_values(variant, rest, run_simulated_test(variant, "new", 1, classify=False))
    assert not registered.signal_faults and not registered.test_problems
    measured = reference_values(variant, rest, run_simulated_test(variant, "new", 2, classify=False,
                                                                  sensor_fault=sensor))
    assert measured.signal_faults and said in measured.signal_faults[0] and not measured.test_problems
    result = compare(measured, registered, tolerances_of(variant))
    assert not result.go and result.causes == (Cause.LVDT_SIGNAL,), result.line()  # not the valve, through it
    assert "check the LVDT, its cable and its connector" in result.line()
