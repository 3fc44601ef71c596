"""A variant's new-valve baseline (af0, a1_0), from calibration.

Features are the ratios af/af0 and a1/a1_0 (the paper's Table 1 style), so
one model serves several variants. A baseline lives in
``configs/baselines/<variant>.toml``, written by ``edc-bench calibrate``.
Without one, the nominal new-valve values from the variant's physics are used
and the record says the baseline is uncalibrated.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from edc_bench.config.loader import variant_dirs
from edc_bench.config.models import Variant
from edc_bench.errors import ConfigError
from edc_bench.physics.feedforward import nominal_parameters

BASELINE_DIR = "baselines"


@dataclass(frozen=True)
class Baseline:
    """New-valve reference values of a variant.

    Attributes
    ----------
    af_v, a1_v_s_per_mm : float
        Mean identified af and a1 of new valves.
    af_sd_v, a1_sd_v_s_per_mm : float
        Their spread between new valves.
    tests : int
        Number of tests behind the figures (0: nominal physics, uncalibrated).
    source : str
        Where the figures come from.
    """

    af_v: float
    a1_v_s_per_mm: float
    af_sd_v: float = 0.0
    a1_sd_v_s_per_mm: float = 0.0
    tests: int = 0
    source: str = "nominal physics (uncalibrated)"

    @property
    def calibrated(self) -> bool:
        """True if the values were measured (calibration), not computed."""
        return self.tests > 0

    def relative(self, af: float, a1: float) -> tuple[float, float]:
        """``(af / af0, a1 / a1_0)``."""
        return af / self.af_v, a1 / self.a1_v_s_per_mm

    def to_toml(self, variant: str, note: str = "") -> str:
        """The baseline file's text."""
        lines = [f"# {note}" if note else "# written by edc-bench calibrate",
                 f'variant = "{variant}"', f"af_v = {self.af_v!r}", f"a1_v_s_per_mm = {self.a1_v_s_per_mm!r}",
                 f"af_sd_v = {self.af_sd_v!r}", f"a1_sd_v_s_per_mm = {self.a1_sd_v_s_per_mm!r}",
                 f"tests = {self.tests}", f'source = "{self.source}"']
        return "\n".join(lines) + "\n"


def baseline_path(variant_name: str) -> Path | None:
    """The baseline file of a variant, if one exists in the library."""
    for folder in variant_dirs():
        path = folder / BASELINE_DIR / f"{variant_name}.toml"
        if path.is_file():
            return path
    return None


def read_baseline(path: Path, variant_name: str | None = None) -> Baseline:
    """Read a baseline file.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not TOML, or lacks a field.
    """
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the baseline: {exc}") from None
    if variant_name is not None and data.get("variant") != variant_name:
        raise ConfigError(f"{path}: baseline is for variant {data.get('variant')!r}, not {variant_name!r}")
    try:
        baseline = Baseline(float(data["af_v"]), float(data["a1_v_s_per_mm"]), float(data.get("af_sd_v", 0.0)),
                            float(data.get("a1_sd_v_s_per_mm", 0.0)), int(data.get("tests", 0)),
                            str(data.get("source", "")))
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"{path}: baseline needs af_v and a1_v_s_per_mm as numbers ({exc})") from None
    if baseline.af_v <= 0 or baseline.a1_v_s_per_mm <= 0:
        raise ConfigError(f"{path}: baseline af_v and a1_v_s_per_mm must be positive")
    return baseline


def load_baseline(variant: Variant) -> Baseline:
    """The variant's calibrated baseline, or the nominal one from its physics."""
    path = baseline_path(variant.name)
    if path is not None:
        return read_baseline(path, variant.name)
    nominal = nominal_parameters(variant)
    return Baseline(nominal.af, nominal.a1)
