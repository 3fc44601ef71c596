"""What a shift did: each valve's tests and decision, each rig self-check, and the summary kept as a file."""

from __future__ import annotations

import datetime
import json
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path

from edc_bench.paths import atomic_write
from edc_bench.timefmt import folder_stamp, local_text


def now_local() -> str:
    """Local time with its UTC offset, to the second."""
    return datetime.datetime.now().astimezone().isoformat(timespec="seconds")


@dataclass(frozen=True)
class ValveEntry:
    """One valve of the shift."""

    valve_id: str
    pump_serial: str
    variant: str
    verdicts: tuple[str, ...]  # each test's verdict, the retest's last
    final: str  # the verdict the technician acts on (a retested MARGINAL's decision)
    words: str  # what to do
    records: tuple[str, ...]  # the record folders
    at: str  # local time, ISO
    cause: str = ""  # an INVALID's: who it points at (records.advice.Cause), else ""


@dataclass(frozen=True)
class RigCheckEntry:
    """One rig self-check of the shift."""

    go: bool | None  # None: not run (no reference valve registered)
    words: str
    at: str


@dataclass
class ShiftLog:
    """The shift so far."""

    operator: str
    station: str
    rig: str
    started: str = field(default_factory=now_local)
    valves: list[ValveEntry] = field(default_factory=list)
    rig_checks: list[RigCheckEntry] = field(default_factory=list)
    interrupted: bool = False  # ended by Ctrl-C or SIGTERM, not by the operator's Ctrl+Q

    @property
    def tests(self) -> int:
        """Tests run (a retest counts)."""
        return sum(len(v.verdicts) for v in self.valves)

    @property
    def retests(self) -> int:
        """Valves tested a second time (a MARGINAL's retest)."""
        return sum(1 for v in self.valves if len(v.verdicts) > 1)

    def judged(self) -> dict[str, str]:
        """Valve id -> its last judgement in this shift, as said on screen ("FAIL at 10:02"). A valve left INVALID
        is not in it: no judgement, and testing it again is what its words ask for."""
        return {v.valve_id: f"{v.final} at {v.at[11:16]}" for v in self.valves if v.final != "INVALID"}

    def summary_lines(self) -> list[str]:
        """The shift in a few lines, for the screen and the file."""
        finals = Counter(v.final for v in self.valves)
        counted = ", ".join(f"{finals[name]} {name}" for name in ("PASS", "FAIL", "MARGINAL", "INVALID")
                            if finals[name]) or "none"
        checks = Counter("GO" if c.go else "NO-GO" if c.go is False else "not run" for c in self.rig_checks)
        check_words = ", ".join(f"{n} {what}" for what, n in checks.items()) or "none"
        ended = " (ended by Ctrl-C or SIGTERM)" if self.interrupted else ""
        return [f"shift of {self.operator or '?'} at {self.station}, {self.rig}, from {local_text(self.started)} to "
                f"{local_text(now_local())}"
                f"{ended}",
                f"valves: {len(self.valves)} ({counted}); tests: {self.tests}; retests: {self.retests}",
                f"rig self-checks: {check_words}"]

    def write(self, folder: Path) -> Path:
        """Write the summary (text, with every valve) and its data (JSON) into ``folder``; the text file."""
        stamp = folder_stamp(self.started)  # as record folders are named
        text_path = folder / f"shift-{stamp}.txt"
        lines = [*self.summary_lines(), ""]
        lines += [f"{local_text(v.at, seconds=True)}  {v.valve_id}  pump {v.pump_serial}  {v.variant}  {' then '.join(v.verdicts)}  ->  "
                  f"{v.final}: {v.words}  ({', '.join(Path(r).name for r in v.records)})" for v in self.valves]
        lines += [f"{local_text(c.at, seconds=True)}  {c.words}" for c in self.rig_checks]
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(text_path, lambda f: f.write("\n".join(lines) + "\n"), mode="w")
        data = {"operator": self.operator, "station": self.station, "rig": self.rig, "started": self.started,
                "ended": now_local(), "ended_by": "interrupt" if self.interrupted else "operator",
                "valves": [asdict(v) for v in self.valves], "rig_checks": [asdict(c) for c in self.rig_checks]}
        atomic_write(text_path.with_suffix(".json"), lambda f: json.dump(data, f, indent=2), mode="w")
        return text_path
