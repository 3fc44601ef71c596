"""Variant files: both shipped variants load; bad ones are refused with clear messages."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import pytest

from edc_bench.config import available_variants, load_variant, parse_variant
from edc_bench.errors import ConfigError


def _raw(name: str = "p-edc-default") -> dict:
    return tomllib.loads(available_variants()[name].read_text())


def test_library_has_two_distinct_variants() -> None:
    default, other = load_variant("p-edc-default"), load_variant("p-edc-long")
    assert default.rack.stroke_mm != other.rack.stroke_mm
    assert default.coil.resistance_ohm != other.coil.resistance_ohm
    assert default.rack.spring_n_per_mm != other.rack.spring_n_per_mm


def test_default_variant_and_lookup_by_part_number_and_path() -> None:
    assert load_variant().name == "p-edc-default"
    assert load_variant("PE-EDC-0002").name == "p-edc-long"
    assert load_variant(str(available_variants()["p-edc-long"])).name == "p-edc-long"


def _write(tmp_path: Path, data: dict) -> Path:
    lines = []

    def is_table_list(v: object) -> bool:
        return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)

    def emit(prefix: str, table: dict, array: bool = False) -> None:
        scalars = {k: v for k, v in table.items() if not isinstance(v, dict) and not is_table_list(v)}
        if prefix:
            lines.append(f"[[{prefix}]]" if array else f"[{prefix}]")
        for k, v in scalars.items():
            lines.append(f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {v!r}")
        for k, v in table.items():
            if isinstance(v, dict):
                emit(f"{prefix}.{k}" if prefix else k, v)
            elif is_table_list(v):
                for item in v:
                    emit(f"{prefix}.{k}" if prefix else k, item, array=True)

    emit("", data)
    path = tmp_path / "bad.toml"
    path.write_text("\n".join(lines).replace("True", "true").replace("False", "false"))
    return path


def test_written_copy_round_trips(tmp_path: Path) -> None:
    assert load_variant(_write(tmp_path, _raw())).name == "p-edc-default"


@pytest.mark.parametrize(
    ("mutate", "expected"),
    [
        (lambda d: d["rack"].update(stroke_mm=-3.0), r"\[rack\]\.stroke_mm = -3.0: Input should be greater than 0"),
        (lambda d: d["rack"].update(strok_mm=20.0), r"\[rack\]\.strok_mm: unknown key; expected one of: .*stroke_mm"),
        (lambda d: d["coil"].pop("resistance_ohm"), r"\[coil\]\.resistance_ohm: required key is missing"),
        (lambda d: d["coil"].update(inductance_mh="1 mH"), r"\[coil\]\.inductance_mh = '1 mH': Input should be a valid number"),
        (lambda d: d.update(extra={"a": 1}), r"\[extra\]: unknown key; expected one of: acceptance, coil, controller, diagnosis, estimator, excitation, pump, rack, retest, rig"),
        # retired (#11): the spread between periods is noise; the file says what replaced it
        (lambda d: d.setdefault("acceptance", {}).update(max_period_spread_rel=0.02),
         r"\[acceptance\]\.max_period_spread_rel: no longer a setting: .*max_residual_ratio.*Delete the line"),
        (lambda d: d["rig"].update(travel_max_mm=25.0), r"travel limits must satisfy.*25.0 <= 20.0"),
        (lambda d: d["rack"].update(mid_stroke_mm=30.0), r"mid_stroke_mm \(30.0\) must lie inside the stroke"),
        (lambda d: d["coil"].update(magnetic_stiffness_n_per_mm=3.0), r"no stable rest position"),
        (lambda d: d["rig"].update(drive_limit_v=30.0), r"drive_limit_v \(30.0\) must not exceed coil.amplifier_limit_v"),
        (lambda d: d["rig"].update(over_current_a=2.0), r"needs .* A, at or above rig.over_current_a"),
        (lambda d: d["valve"]["presets"].pop("faulty"), r"presets must define new, worn and faulty; missing: faulty"),
        (lambda d: d["valve"].update(stiction_ratio=0.5), r"\[valve\]\.stiction_ratio = 0.5: Input should be greater than or equal to 1"),
        (lambda d: d["pump"].update(name="Bad Name"), r"\[pump\]\.name = 'Bad Name': String should match pattern"),
        (lambda d: d["sensors"]["lvdt"].update(resolution=0.0), r"\[sensors\]\.lvdt\.resolution = 0.0"),
        # the swing above mid-stroke beyond travel_max_mm (once accepted: `not a < b and c < d`)
        (lambda d: d["rig"].update(travel_max_mm=13.0), r"swings 4.5 mm about mid-stroke \(10.0 mm\), beyond the travel"),
        (lambda d: d["rig"].update(travel_min_mm=-0.5) or d["excitation"]["tones"][0].update(amplitude_mm=10.0),
         r"swings 10.5 mm about mid-stroke"),
        (lambda d: d["excitation"].update(duration_s=7.0), r"excitation.duration_s \(7 s\) is too short"),
        (lambda d: d["controller"].update(period_s=0.01) or d["excitation"]["tones"][1].update(frequency_hz=8.0),
         r"tone at 8.0 Hz is too fast for a 10 ms period"),
        (lambda d: d["coil"].update(resistance_ohm=0.85, resistance_min_ohm=0.6, resistance_max_ohm=0.8),
         r"resistance_ohm \(0.85\) must lie within the coil spec"),
        (lambda d: d["rig"].update(supply_min_v=30.0), r"supply_min_v \(30.0\) must not exceed"),
        (lambda d: d["rig"].update(drive_limit_v=2.0, over_current_a=15.0) or d["coil"].update(amplifier_limit_v=24.0),
         r"needs .* V, at or above rig.drive_limit_v \(2.0 V\)"),
        (lambda d: d["valve"].update(clearance_spec_mm=0.05), r"clearance_spec_mm \(0.05\) must not be below"),
        (lambda d: d["diagnosis"]["population"].update(clearance_max_mm=0.05), r"clearance_max_mm must exceed"),
        (lambda d: d["excitation"].update(move_s=5.0, fade_s=5.0, duration_s=9.0), r"must exceed move_s \+ fade_s"),
        # the estimator's law is a value (EstimatorKind), named with the ones there are
        (lambda d: d.setdefault("estimator", {}).update(kind="RLS please"),
         r"\[estimator\]\.kind = 'RLS please': Input should be 'rls' or 'gradient'"),
    ],
    ids=["negative", "unknown-key", "missing", "wrong-type", "unknown-section", "retired-key", "travel", "mid-stroke",
         "unstable", "drive-limit", "over-current", "preset", "stiction", "name", "nested",
         "swing-above", "swing-below", "too-short", "tone-too-fast", "coil-spec", "supply", "hold-voltage",
         "clearance-spec", "population", "move-fade", "estimator-kind"],
)
def test_bad_variant_is_refused_naming_file_field_and_value(tmp_path: Path, mutate, expected: str) -> None:
    data = _raw()
    mutate(data)
    path = _write(tmp_path, data)
    with pytest.raises(ConfigError, match=expected) as info:
        load_variant(path)
    assert str(path) in str(info.value)


def test_not_toml(tmp_path: Path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text("[rack\nstroke_mm = 1")
    with pytest.raises(ConfigError, match=r"broken.toml: not valid TOML"):
        load_variant(path)


def test_missing_file_and_unknown_name() -> None:
    with pytest.raises(ConfigError, match=r"variant file 'nope/x.toml' does not exist"):
        load_variant("nope/x.toml")
    with pytest.raises(ConfigError, match=r"unknown variant 'p-edc-nope': give a name \(p-edc-default, p-edc-hard, p-edc-long"):
        load_variant("p-edc-nope")


def test_several_errors_are_all_reported() -> None:
    data = _raw()
    data["rack"]["stroke_mm"] = 0
    data["coil"]["resistance_ohm"] = -1
    with pytest.raises(ConfigError) as info:
        parse_variant(data, "mem.toml")
    assert len(str(info.value).splitlines()) == 2


def test_a_station_adds_a_variant_by_dropping_a_file(tmp_path, monkeypatch) -> None:
    import subprocess
    import sys

    from edc_bench.config.loader import available_variants

    shipped = available_variants()["p-edc-default"].read_text(encoding="utf-8")
    station = tmp_path / "variants"
    station.mkdir()
    (station / "shop-pump.toml").write_text(
        shipped.replace('name = "p-edc-default"', 'name = "shop-pump"').replace("PE-EDC-0001", "SHOP-42"),
        encoding="utf-8")
    (station / "broken.toml").write_text("[pump]\nname = 3\n", encoding="utf-8")
    env = {**os.environ, "EDC_BENCH_VARIANTS_DIR": str(station)}
    listing = subprocess.run([sys.executable, "-m", "edc_bench", "variants"], capture_output=True, text=True,
                             env=env, timeout=120)
    assert listing.returncode == 0, listing.stderr
    assert "shop-pump" in listing.stdout and "SHOP-42" in listing.stdout
    assert "broken" in listing.stdout and "cannot be used" in listing.stdout
    assert str(station) in listing.stdout
    monkeypatch.setenv("EDC_BENCH_VARIANTS_DIR", str(station))
    assert load_variant("SHOP-42").name == "shop-pump"  # by part number


@pytest.mark.parametrize(("section", "key", "value", "expected"), [
    ("rack", "mass_kg", 1e308, r"\[rack\]\.mass_kg = 1e\+308: implausible: .* weighs 0\.01 to 10 kg; check the value"),
    ("rack", "stroke_mm", 1e9, r"\[rack\]\.stroke_mm = 1000000000\.0: implausible: .* 1 to 60 mm"),
    ("coil", "inductance_mh", 1e6, r"\[coil\]\.inductance_mh = 1000000\.0: implausible"),
    ("controller", "period_s", 1.0, r"\[controller\]\.period_s = 1\.0: implausible: the bench loop runs at 100 Hz"),
    ("excitation", "duration_s", 3600.0, r"\[excitation\]\.duration_s = 3600\.0: implausible: a bench test lasts 1 to"),
])
def test_an_absurd_value_is_refused_with_the_reason(tmp_path: Path, section: str, key: str, value: float,
                                                    expected: str) -> None:
    data = _raw()
    data[section][key] = value
    with pytest.raises(ConfigError, match=expected):
        load_variant(_write(tmp_path, data))


def test_every_shipped_variant_lies_in_the_plausible_ranges() -> None:
    for path in available_variants().values():
        load_variant(path)  # a range that refuses a shipped pump is too narrow


def test_the_plausible_ranges_in_the_docs_are_the_schemas() -> None:
    import re

    from edc_bench.config import models

    docs = (Path(__file__).resolve().parents[2] / "docs" / "variants.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| `\[[^|]+\]` \| `(\w+)` \| (-?[0-9.e+-]+) to ([0-9.e+-]+)( [^|]+)? \|", docs, re.MULTILINE)
    documented = {(key, float(low), float(high), (unit or "").strip()) for key, low, high, unit in rows}

    def sections(cls: type) -> list[type]:
        return [cls, *(s for sub in cls.__subclasses__() for s in sections(sub))]

    declared = {(key, p.low, p.high, p.unit) for cls in sections(models._Section) for key, p in cls.plausible.items()}
    assert documented == declared


@pytest.mark.parametrize(("content", "expected"), [
    (bytes(range(256)), "binary data"),
    ("description = 'Prüfstand'\n".encode("latin-1"), r"not UTF-8 text \(byte 0xfc on line 1"),
    ("[pump]\n".encode("utf-16"), "UTF-16 text; save it as UTF-8"),
    (b"  \n", "the variant file is empty"),
])
def test_a_file_that_is_not_utf8_toml_is_refused_in_one_line(tmp_path: Path, content: bytes, expected: str) -> None:
    path = tmp_path / "x.toml"
    path.write_bytes(content)
    with pytest.raises(ConfigError, match=expected) as info:
        load_variant(path)
    assert len(str(info.value).splitlines()) == 1


def test_a_byte_order_mark_is_fine(tmp_path: Path) -> None:
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + available_variants()["p-edc-default"].read_bytes())
    assert load_variant(path).name == "p-edc-default"
