"""A variant's new-valve baseline (af0, a1_0): the tests behind it, its uncertainty, where it lives.

Features are the ratios af/af0 and a1/a1_0 (the paper's Table 1 style), so
one model serves several variants. ``edc-bench calibrate`` writes a
baseline: the mean af and a1 of converged new-valve tests, their spread
between valves, the uncertainty of the mean, where the tests ran (rig,
simulated rig or simulated population), when, on which station, with which
software, and each test with its record.

Two places hold baselines. A station's own (``baselines/`` in its variant
folder, written by ``calibrate --write`` or ``--append``) comes first: it
was measured on this station's rig. Then the library's (``configs/baselines``
for the shipped variants). A variant with neither has only the nominal
figures from its physics: :attr:`Baseline.calibrated` is False and a test
is not judged against it unless the engineer says so.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.config.loader import station_variant_dir, variant_dirs
from edc_bench.config.models import Variant
from edc_bench.errors import ConfigError
from edc_bench.physics.feedforward import nominal_parameters
from edc_bench.verdict.baseline_source import BaselineSource, sources_of_text, sources_text
from edc_bench.verdict.sections import BaselineSummary, MotionFigure

BASELINE_DIR = "baselines"
#: Earlier baselines of a folder are kept here when a new one replaces them.
EARLIER_DIR = "earlier"
#: Fewer tests than this and calibrate says the baseline is thin (the spread between new valves is about 8 %).
RECOMMENDED_TESTS = 5
NOMINAL_SOURCE = str(BaselineSource.NOMINAL)
#: Where a test's pump is the pump type's own figures (a simulated rig or population, the nominal physics).
_SIMULATED = frozenset({BaselineSource.SIMULATED_RIG, BaselineSource.SIMULATED_POPULATION, BaselineSource.NOMINAL})
#: From this many pumps on, calibrate does not ask for more (the mean of their springs is within the type's
#: tolerance over the square root of the pumps: 0.6 of it with three).
RECOMMENDED_PUMPS = 3
#: A [[test]] table's optional figures for the baseline's own uncertainty (:meth:`Baseline.noise_rel`,
#: :meth:`Baseline.core_shift_rel`, :meth:`Baseline.systematic_rms_v`).
UNCERTAINTY_KEYS = ("af_se_rel", "a1_se_rel", "af_core_shift_rel", "a1_core_shift_rel", "systematic_rms_v")
#: A [[test]] table's optional motion parameters (referred to the reference coil): what a rack-travel sensor's gain
#: error scales together (:meth:`Baseline.motion`, :mod:`edc_bench.verdict.part`).
MOTION_KEYS = ("a2_v_s2_per_mm", "a0_v_per_mm", "b_v")
#: The parameter each of :data:`MOTION_KEYS` holds.
MOTION_PARAMETERS = dict(zip(MOTION_KEYS, ("a2", "a0", "b")))


@dataclass(frozen=True)
class BaselineTest:
    """One converged new-valve test behind a baseline.

    Attributes
    ----------
    af_v, a1_v_s_per_mm : float
        Its identified af and a1 (referred to the reference coil).
    valve_id : str
        The valve tested.
    source : BaselineSource or None
        Where it ran (None: not said, as in older files); a word is read as its :class:`BaselineSource`.
    started_at : str
        When the test started (ISO 8601), empty if not known.
    record : str
        Its record folder, empty when none was written (simulated population).
    af_se_rel, a1_se_rel : float or None
        The standard error of its af and a1, relative (None: not known, as in files written before they were kept).
    af_core_shift_rel, a1_core_shift_rel : float or None
        The fit over every used row's af and a1 less the estimate's, relative (what the model missed at reversals,
        :attr:`~edc_bench.identification.period_fit.PeriodFit.core_shift`; None: not known).
    systematic_rms_v : float or None
        The part of its residual that repeats from period to period, V rms (None: not known, as in files written
        before 2026-11-27).
    a2_v_s2_per_mm, a0_v_per_mm, b_v : float or None
        Its identified a2, a0 and b, referred to the reference coil (None: not known, as in files written before
        2026-12-01): the part diagnosis compares a test's with their mean.
    pump_serial : str
        The pump the valve was tested in (empty: not said). Pumps of one type differ by their return spring's
        tolerance; a baseline over several pumps holds the type's spring, one over a single pump that pump's
        (:attr:`Baseline.pumps`).
    """

    af_v: float
    a1_v_s_per_mm: float
    valve_id: str = ""
    source: BaselineSource | None = None
    started_at: str = ""
    record: str = ""
    af_se_rel: float | None = None
    a1_se_rel: float | None = None
    af_core_shift_rel: float | None = None
    a1_core_shift_rel: float | None = None
    systematic_rms_v: float | None = None
    a2_v_s2_per_mm: float | None = None
    a0_v_per_mm: float | None = None
    b_v: float | None = None
    pump_serial: str = ""

    def __post_init__(self) -> None:
        if self.source is not None and not isinstance(self.source, BaselineSource):  # a file's or caller's word
            object.__setattr__(self, "source", BaselineSource.parse(str(self.source)) if self.source else None)

    @property
    def uncertainty_known(self) -> bool:
        """True when the test's standard errors and core shifts are kept (a verdict's interval uses them)."""
        return None not in (self.af_se_rel, self.a1_se_rel, self.af_core_shift_rel, self.a1_core_shift_rel)


@dataclass(frozen=True)
class Baseline:
    """New-valve reference values of a variant.

    Attributes
    ----------
    af_v, a1_v_s_per_mm : float
        Mean identified af and a1 of new valves.
    af_sd_v, a1_sd_v_s_per_mm : float
        Their spread between new valves (standard deviation).
    tests : int
        Number of tests behind the figures (0: nominal physics, uncalibrated).
    source : str
        Where the figures come from, in words (a file's or record's ``source``; :attr:`sources` decides).
    written_at, station, software, command : str
        When, where, by which edc-bench and with which command the baseline was written.
    path : str
        The file it was read from (empty if computed).
    held_motion : tuple of (str, float, float, int)
        The motion parameters' (mean, spread, tests) as a record's summary holds them, for a baseline read back
        from a record (its test list is not kept there): :meth:`motion` answers from them.
    held_pumps : int or None
        :attr:`pumps` as a record's summary holds it, for a baseline read back from a record.
    test_list : tuple of BaselineTest
        The tests behind it, each with its record (empty in files that do not list them).
    sources : frozenset of BaselineSource
        Where its tests ran: from its tests when it lists them, else as its file or record says.
    """

    af_v: float
    a1_v_s_per_mm: float
    af_sd_v: float = 0.0
    a1_sd_v_s_per_mm: float = 0.0
    tests: int = 0
    source: str = NOMINAL_SOURCE
    written_at: str = ""
    station: str = ""
    software: str = ""
    command: str = ""
    path: str = ""
    test_list: tuple[BaselineTest, ...] = field(default=(), repr=False)
    sources: frozenset[BaselineSource] = frozenset({BaselineSource.NOMINAL})
    held_motion: tuple[tuple[str, float, float, int], ...] = ()
    held_pumps: int | None = None

    @property
    def pumps(self) -> int | None:
        """How many pumps of the type its tests ran in: what its a0 and b hold of the type's return spring.

        0 for tests on simulated pumps alone (the type's own spring: ``[rack]``'s figures); for a rig's tests, the
        pumps their serials name (a simulated one among them counts as one more); None where a rig's test does not
        name its pump (then it may be any one pump's, as if from one: :func:`~edc_bench.verdict.part.pump_allowance`).
        """
        if not self.test_list:
            if self.held_pumps is not None or self.sources - _SIMULATED:
                return self.held_pumps
            return 0
        rig = [t for t in self.test_list if t.source not in _SIMULATED]
        if not rig:
            return 0
        serials = {t.pump_serial for t in rig}
        if "" in serials:
            return None
        return len(serials) + (len(rig) < len(self.test_list))

    @property
    def calibrated(self) -> bool:
        """True if the values were measured (calibration), not computed from the nominal physics."""
        return self.tests > 0

    @property
    def af_uncertainty_v(self) -> float:
        """Standard uncertainty of the mean af (spread / sqrt(tests)); nan with fewer than two tests."""
        return self.af_sd_v / math.sqrt(self.tests) if self.tests >= 2 else math.nan

    @property
    def a1_uncertainty_v_s_per_mm(self) -> float:
        """Standard uncertainty of the mean a1; nan with fewer than two tests."""
        return self.a1_sd_v_s_per_mm / math.sqrt(self.tests) if self.tests >= 2 else math.nan

    def noise_rel(self, z: float) -> np.ndarray:
        """How far the noise of the baseline's tests may move its af and a1, relative: (2,), z standard errors of
        the mean of the tests. Over the tests whose figures are kept; zeros when none are (older files, the
        nominal baseline). Every ratio judged against the baseline carries it (docs/method.md, "The interval")."""
        known = [t for t in self.test_list if t.uncertainty_known]
        if not known:
            return np.zeros(2)
        se = np.array([[t.af_se_rel, t.a1_se_rel] for t in known], dtype=float)
        return z * np.sqrt((se ** 2).sum(axis=0)) / len(known)

    def core_shift_rel(self) -> np.ndarray:
        """The mean core shift of the baseline's tests, af and a1, relative and signed: (2,) (zeros when no test
        kept its figures). A valve's ratio to the baseline errs by the difference between its misfit and this
        (docs/method.md, "The interval")."""
        known = [t for t in self.test_list if t.uncertainty_known]
        if not known:
            return np.zeros(2)
        return np.array([[t.af_core_shift_rel, t.a1_core_shift_rel] for t in known], dtype=float).mean(axis=0)

    def systematic_rms_v(self) -> float:
        """The mean repeating residual of the baseline's tests that kept it, V rms (0 when none did: older files,
        the nominal baseline). A valve's misfit beyond this widens its interval (docs/method.md, "The interval")."""
        known = [t.systematic_rms_v for t in self.test_list if t.systematic_rms_v is not None]
        return float(np.mean(known)) if known else 0.0

    @property
    def measured_on_rig(self) -> bool:
        """True if any test behind it ran on a real rig (not the simulated rig or a simulated population)."""
        return BaselineSource.RIG in self.sources

    @classmethod
    def from_summary(cls, summary: dict[str, Any]) -> Baseline:
        """A baseline from its figures and provenance (a record's :meth:`summary`, or a baseline file's keys).

        Its :attr:`sources` are the summary's ``sources`` (a record since schema 10); a file, or an older record,
        names them only in its ``source`` sentence, read once here (:func:`sources_of_text`)."""
        tests = int(summary.get("tests", 0))
        listed = summary.get("sources")
        if isinstance(listed, (list, tuple)) and listed:
            sources = frozenset(BaselineSource.parse(str(word)) for word in listed)
        elif tests == 0:
            sources = frozenset({BaselineSource.NOMINAL})
        else:
            sources = sources_of_text(_text(summary, "source"))
        held = summary.get("motion") or {}
        figures = {key: MotionFigure.model_validate(held[key]) for key in MOTION_KEYS
                   if isinstance(held, dict) and isinstance(held.get(key), dict)}
        motion = tuple((key, f.mean, f.sd, f.tests) for key, f in figures.items())
        return cls(float(summary["af_v"]), float(summary["a1_v_s_per_mm"]), float(summary.get("af_sd_v", 0.0)),
                   float(summary.get("a1_sd_v_s_per_mm", 0.0)), tests,
                   *(_text(summary, key) for key in ("source", "written_at", "station", "software", "command",
                                                      "path")), sources=sources, held_motion=motion,
                   held_pumps=_count(summary.get("pumps")))

    def motion(self, key: str) -> tuple[float, float, int] | None:
        """One of :data:`MOTION_KEYS` over the tests that hold it: (mean, standard deviation between tests, tests);
        None with fewer than two."""
        values = [v for v in (getattr(t, key) for t in self.test_list) if v is not None and math.isfinite(v)]
        if len(values) < 2:
            return next(((mean, sd, n) for name, mean, sd, n in self.held_motion if name == key), None)
        return float(np.mean(values)), float(np.std(values, ddof=1)), len(values)

    def relative(self, af: float, a1: float) -> tuple[float, float]:
        """``(af / af0, a1 / a1_0)``."""
        return af / self.af_v, a1 / self.a1_v_s_per_mm

    def summary(self) -> BaselineSummary:
        """The baseline as a record keeps it: figures, uncertainty and provenance, not the test list."""
        return BaselineSummary(
            af_v=self.af_v, a1_v_s_per_mm=self.a1_v_s_per_mm, af_sd_v=self.af_sd_v,
            a1_sd_v_s_per_mm=self.a1_sd_v_s_per_mm, af_uncertainty_v=self.af_uncertainty_v,
            a1_uncertainty_v_s_per_mm=self.a1_uncertainty_v_s_per_mm, tests=self.tests, source=self.source,
            sources=sorted(self.sources), calibrated=self.calibrated, written_at=self.written_at,
            station=self.station, software=self.software, path=self.path,
            motion={key: MotionFigure(mean=held[0], sd=held[1], tests=held[2])
                    for key in MOTION_KEYS if (held := self.motion(key)) is not None} or None,
            pumps=self.pumps)

    def to_toml(self, variant: str, note: str = "") -> str:
        """The baseline file's text (TOML), the tests behind it listed as ``[[test]]`` tables."""
        import tomlkit

        document = tomlkit.document()
        document.add(tomlkit.comment(f"New-valve baseline of {variant}: {note}" if note
                                     else f"New-valve baseline of {variant}, written by edc-bench calibrate"))
        document.add(tomlkit.comment("af and a1 are the mean of the [[test]] entries below, referred to the "
                                     "variant's reference coil; *_uncertainty_* is the standard uncertainty "
                                     "of the mean (spread / sqrt(tests))"))
        values: dict[str, Any] = {
            "variant": variant, "af_v": self.af_v, "a1_v_s_per_mm": self.a1_v_s_per_mm, "af_sd_v": self.af_sd_v,
            "a1_sd_v_s_per_mm": self.a1_sd_v_s_per_mm, "af_uncertainty_v": self.af_uncertainty_v,
            "a1_uncertainty_v_s_per_mm": self.a1_uncertainty_v_s_per_mm, "tests": self.tests, "source": self.source,
            "written_at": self.written_at, "station": self.station, "software": self.software,
            "command": self.command,
        }
        for key, value in values.items():
            if isinstance(value, float) and not math.isfinite(value):
                continue  # an unknown uncertainty is left out (TOML's nan would read as a number)
            document.add(key, value)
        if self.test_list:
            tests = tomlkit.aot()
            for test in self.test_list:
                table = (tomlkit.table().add("af_v", test.af_v).add("a1_v_s_per_mm", test.a1_v_s_per_mm)
                         .add("valve_id", test.valve_id).add("source", str(test.source or ""))
                         .add("started_at", test.started_at).add("record", test.record))
                for key in UNCERTAINTY_KEYS + MOTION_KEYS:
                    value = getattr(test, key)
                    if value is not None and math.isfinite(value):
                        table.add(key, value)
                if test.pump_serial:
                    table.add("pump_serial", test.pump_serial)
                tests.append(table)
            document.add("test", tests)
        return tomlkit.dumps(document)


def baseline_from_tests(tests: list[BaselineTest], *, written_at: str = "", station: str = "", software: str = "",
                        command: str = "") -> Baseline:
    """The baseline of a list of converged new-valve tests (at least one).

    Raises
    ------
    ConfigError
        Without a test.
    """
    if not tests:
        raise ConfigError("a baseline needs at least one converged new-valve test")
    n = len(tests)
    af = [t.af_v for t in tests]
    a1 = [t.a1_v_s_per_mm for t in tests]

    def mean_sd(values: list[float]) -> tuple[float, float]:
        mean = math.fsum(values) / n
        sd = math.sqrt(math.fsum((v - mean) ** 2 for v in values) / (n - 1)) if n > 1 else 0.0
        return mean, sd

    (af_mean, af_sd), (a1_mean, a1_sd) = mean_sd(af), mean_sd(a1)
    sources = frozenset(t.source for t in tests if t.source) or frozenset({BaselineSource.UNKNOWN})
    return Baseline(af_mean, a1_mean, af_sd, a1_sd, n, sources_text(sources), written_at, station,
                    software, command, "", tuple(tests), sources)


def station_baseline_path(variant_name: str) -> Path:
    """Where the station's own baseline of a variant lives (it may not exist yet)."""
    return station_variant_dir() / BASELINE_DIR / f"{variant_name}.toml"


def baseline_path(variant_name: str, *, station: bool = True) -> Path | None:
    """The baseline file a variant is judged against: the station's own first, then the library's.

    Parameters
    ----------
    variant_name : str
        The variant.
    station : bool, optional
        Look at the station's own baselines (default). Training on the simulated population passes
        False: simulated features are compared with the simulated baseline shipped with the variant.
    """
    own = station_baseline_path(variant_name)
    if station and own.is_file():
        return own
    for folder in variant_dirs():
        path = folder / BASELINE_DIR / f"{variant_name}.toml"
        if path.is_file() and path != own:
            return path
    return None


def _number(data: dict[str, Any], key: str) -> float | None:
    """An optional number of a [[test]] table (None when absent)."""
    value = data.get(key)
    return None if value is None else float(value)


def _count(value: object) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else None


def _text(data: dict[str, Any], key: str) -> str:
    value = data.get(key, "")
    return value if isinstance(value, str) else str(value)


def read_baseline(path: Path, variant_name: str | None = None) -> Baseline:
    """Read a baseline file.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not TOML, or lacks a field.
    """
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the baseline: {exc}") from None
    if variant_name is not None and data.get("variant") != variant_name:
        raise ConfigError(f"{path}: baseline is for variant {data.get('variant')!r}, not {variant_name!r}")
    try:
        tests = tuple(BaselineTest(float(t["af_v"]), float(t["a1_v_s_per_mm"]), _text(t, "valve_id"),
                                   _text(t, "source"), _text(t, "started_at"), _text(t, "record"),
                                   *(_number(t, key) for key in UNCERTAINTY_KEYS),
                                   **{key: _number(t, key) for key in MOTION_KEYS},
                                   pump_serial=_text(t, "pump_serial"))
                      for t in data.get("test", []))
        baseline = Baseline.from_summary(data)
        # a file that lists its tests: where they ran decides, not the file's sentence
        sources = (frozenset(t.source for t in tests if t.source) or frozenset({BaselineSource.UNKNOWN})) if tests \
            else baseline.sources
        baseline = dataclasses.replace(baseline, path=str(path), test_list=tests, sources=sources)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ConfigError(f"{path}: baseline needs af_v and a1_v_s_per_mm as numbers, and numbers in each "
                          f"[[test]] ({exc})") from None
    values = [baseline.af_v, baseline.a1_v_s_per_mm] + [v for t in tests for v in (t.af_v, t.a1_v_s_per_mm)]
    if not all(math.isfinite(v) and v > 0 for v in values):
        raise ConfigError(f"{path}: baseline af_v and a1_v_s_per_mm, and those of every [[test]], must be positive "
                          "numbers; restore the file from baselines/earlier/ or calibrate anew with --write")
    for n, test in enumerate(tests, start=1):
        for key in UNCERTAINTY_KEYS:
            value = getattr(test, key)
            if value is not None and not (math.isfinite(value) and (value >= 0 or "shift" in key)):
                kind = "a number" if "shift" in key else "a number of at least 0"
                raise ConfigError(f"{path}: [[test]] {n}: {key} must be {kind}, not {value}; delete the line (that "
                                  "test then counts for the baseline's figures only, not for its uncertainty) or "
                                  "calibrate anew with --write")
    return baseline


def load_baseline(variant: Variant, *, station: bool = True) -> Baseline:
    """The variant's baseline (see :func:`baseline_path`), or the nominal one from its physics (uncalibrated)."""
    path = baseline_path(variant.name, station=station)
    if path is not None:
        return read_baseline(path, variant.name)
    nominal = nominal_parameters(variant)
    return Baseline(nominal.af, nominal.a1)


def write_baseline(path: Path, text: str) -> Path | None:
    """Write a baseline file; a baseline already there is moved to ``earlier/`` first, never overwritten.

    Returns
    -------
    pathlib.Path or None
        Where the earlier baseline went, if there was one.

    Raises
    ------
    ConfigError
        If the folder cannot be written.
    RecordNotWrittenError
        If the disk is full (or the quota used up).
    """
    from edc_bench.paths import atomic_write

    path = Path(path)
    kept = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.exists():
            stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
            earlier = path.parent / EARLIER_DIR
            earlier.mkdir(exist_ok=True)
            kept = earlier / f"{path.stem}-{stamp}.toml"
            n = 1
            while kept.exists():
                n += 1
                kept = earlier / f"{path.stem}-{stamp}-{n}.toml"
            kept.write_bytes(path.read_bytes())
        atomic_write(path, lambda handle: handle.write(text), mode="w")
    except OSError as exc:
        from edc_bench.errors import RecordNotWrittenError, disk_full

        if disk_full(exc):  # exit 74 as every full disk, not 2: nothing was wrong with what was asked
            raise RecordNotWrittenError(f"{path}: cannot write the baseline ({exc.strerror or exc}); the measured "
                                        "tests are listed above: free space, then calibrate again, or write it "
                                        "elsewhere with --baseline-file FILE") from None
        raise ConfigError(f"{path}: cannot write the baseline ({exc.strerror or exc}); the measured tests are "
                          "listed above: write it elsewhere with --baseline-file FILE") from None
    return kept
