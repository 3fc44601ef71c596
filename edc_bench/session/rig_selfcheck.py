"""The session's rig self-check: at the start of a shift, and again whenever the pump type's policy says one is
due (every N tests or hours, or after a NO-GO), with the station's registered reference valve
(:mod:`edc_bench.selfcheck`). Where none is registered the session says so once and goes on."""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from edc_bench.session.runner import RigChoice


@dataclass(frozen=True)
class SelfCheckWords:
    """A rig self-check as the session shows it: GO (True), NO-GO (False) or not run (None), and its words: a whole
    line that names the check ("rig self-check: ..."), shown and kept as it is."""

    go: bool | None
    words: str


class SessionSelfCheck:
    """Runs the station's rig self-check and says when the next is due.

    Parameters
    ----------
    rig : RigChoice
        The session's rig.
    history_url : str or None
        The history (the registration and the ledger live there).
    station, by : str
        This station, and who runs the check (the operator).
    """

    def __init__(self, rig: RigChoice, history_url: str | None, station: str, by: Callable[[], str]) -> None:
        self.rig, self.history_url, self.station, self.by = rig, history_url, station, by
        self.checks = 0

    def _registration(self, store: Any) -> Any:
        from edc_bench.selfcheck import Registration

        return Registration.of(store.reference(self.station))

    def reference_valve(self) -> str | None:
        """The registered reference valve's id (None: none registered for this station)."""
        from edc_bench.history.store import HistoryStore

        with HistoryStore(self.history_url) as store:
            registration = self._registration(store)
        return None if registration is None else registration.valve_id

    def no_reference_words(self) -> SelfCheckWords:
        """What the session says, once, where no reference valve is registered."""
        from edc_bench.selfcheck import no_reference_line

        return SelfCheckWords(None, no_reference_line(self.station))

    def run(self) -> SelfCheckWords:
        """Run the check now (the reference valve mounted); its words, stored in the ledger."""
        from edc_bench.config import load_variant
        from edc_bench.history.store import HistoryStore
        from edc_bench.runtime.signals import stop_requested
        from edc_bench.selfcheck import MEASURED, Rig, no_reference_line, rig_check_row, run_selfcheck

        with HistoryStore(self.history_url) as store:
            registration = self._registration(store)
            if registration is None:
                return SelfCheckWords(None, no_reference_line(self.station))
            if registration.simulated != self.rig.simulated:
                where = "the simulated rig" if registration.simulated else "a rig's bus"
                return SelfCheckWords(None, f"rig self-check: the reference valve {registration.valve_id} was "
                                            f"registered on {where}: not checked on this rig")
            variant = load_variant(registration.variant)
            measured = [r for r in store.rig_checks(self.station, registration.id) if r.verdict in MEASURED]
            seed = (registration.seed or 0) + 1 + len(measured)  # a skip measured nothing: no new noise
            rig = Rig(bus=self.rig.bus_config, drift=self.rig.rig_drift)
            check = run_selfcheck(rig, registration, variant, seed=seed)
            if stop_requested():  # Ctrl-C or SIGTERM cut the reference valve's test: its figures judge nothing
                return SelfCheckWords(None, "rig self-check: interrupted (Ctrl-C or SIGTERM): not stored; run it "
                                            "again")
            store.add_rig_check(rig_check_row(check, self.station, self.by()))
        self.checks += 1
        return SelfCheckWords(check.result.go, check.result.line())

    def skip(self, why_due: str) -> str:
        """The technician skipped a due check (Esc): kept in the rig's ledger; the words for the screen."""
        from edc_bench.history.store import HistoryStore
        from edc_bench.selfcheck import skip_row

        try:
            with HistoryStore(self.history_url) as store:
                registration = self._registration(store)
                if registration is None:
                    return "rig self-check skipped"
                store.add_rig_check(skip_row(registration, self.station, self.by(), why_due))
        except Exception as exc:  # noqa: BLE001 - the shift goes on; the skip is in the shift's summary still
            return f"rig self-check skipped; the rig's ledger could not keep the skip ({type(exc).__name__}: {exc})"
        return "rig self-check skipped: kept in the rig's ledger (edc-bench history --rig)"

    def due(self) -> str | None:
        """Why a check must run before the next test (the pump type's policy, or a NO-GO), else None."""
        from edc_bench.config import load_variant
        from edc_bench.history.store import HistoryStore
        from edc_bench.selfcheck import SelfCheckPolicy, check_due

        with HistoryStore(self.history_url) as store:
            registration = self._registration(store)
            if registration is None:  # said once at the start; the shift goes on
                return None
            policy = SelfCheckPolicy.of_variant(load_variant(registration.variant))
            return check_due(store, registration, policy, dt.datetime.now(dt.UTC))
