"""The session's app put together as ``edc-bench session`` runs it: the runner, the rig self-check, the pump
types' part numbers, the history's lines of a valve and the station's scan patterns (also for tests and the
benchmark)."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def make_app(variant_name: str | None, rig: Any, out_dir: Path, history_url: str | None, station: str,
             operator: str, ask_workshop: bool = False, station_given: str | None = None) -> Any:
    """The session's app on ``rig`` (a :class:`~edc_bench.session.runner.RigChoice`), as the command runs it
    (``ask_workshop``: the station's settings do not name the workshop yet: the session asks for it once)."""
    from edc_bench.config import load_variant
    from edc_bench.session.app import SessionApp
    from edc_bench.session.operator import remember_operator
    from edc_bench.session.rig_selfcheck import SessionSelfCheck
    from edc_bench.session.runner import SessionRunner
    from edc_bench.session.scan_rules import station_scan_rules
    from edc_bench.station_settings import remember_workshop, station_identity

    scan_rules = station_scan_rules()  # a settings file that cannot be read is said before the screen opens
    runner = SessionRunner(rig, out_dir, history_url, station, operator, station_given=station_given)
    selfcheck = SessionSelfCheck(rig, history_url, station, by=lambda: runner.operator or "session")
    return SessionApp(runner, load_variant, variant_name, library_part_numbers(), operator, remember_operator,
                      history_lines(history_url), out_dir, selfcheck=selfcheck, scan_rules=scan_rules,
                      remember_workshop=remember_workshop if ask_workshop else None,
                      ask_station_name=ask_workshop and not station_identity().for_customers(station_given))


def library_part_numbers() -> dict[str, str]:
    """Part number -> variant name, of every variant this station has (unreadable files left out)."""
    from edc_bench.config import load_variant
    from edc_bench.config.loader import available_variants
    from edc_bench.errors import ConfigError
    from edc_bench.session.scan import part_number_index

    names: dict[str, str] = {}
    for name in available_variants():
        try:
            names[name] = load_variant(name).pump.part_number
        except ConfigError:
            continue
    return part_number_index(names)


def history_lines(url: str | None) -> Any:
    """Valve id -> its last tests at this shop, newest first, as lines for the screen."""

    def lines(valve_id: str) -> list[str]:
        from edc_bench.history.store import Filters, HistoryStore

        try:
            with HistoryStore(url) as store:
                rows = store.list(Filters(valve_id=valve_id), limit=5)[::-1]  # newest first
        except Exception as exc:  # noqa: BLE001 - the history is a help here, never a stop
            return [f"(the history could not be read: {type(exc).__name__})"]
        return [f"{_local(row.started_at)}  {row.verdict}" + (f" -> {row.decision}" if row.decision else "")
                + f"  pump {row.pump_serial or '-'}, {row.variant}" for row in rows]

    return lines


def _local(iso: str) -> str:
    """A history time (UTC) in this station's local time, to the minute, with its offset."""
    from edc_bench.timefmt import local_text

    return local_text(iso)
