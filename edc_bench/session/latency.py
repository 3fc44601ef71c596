"""The session's latency: from a test's safe stop to its decision on the screen, and to its report drawn.

The app runs headless (Textual's test driver) on the simulated rig, a valve at a time scanned as a technician
scans it; the app stamps each valve's safe stop (the loop's end, when its judgement begins) and measures from it to
its decision put on the screen's widgets (Textual paints them at its next refresh, within 1/60 s).
"""

from __future__ import annotations

import asyncio
import tempfile
from pathlib import Path

import numpy as np

from edc_bench.perf.figures import SessionLatency

#: valves of the benchmark's shift: worn (FAIL), new (PASS), a MARGINAL pair
VALVES = ("worn", "new", "clearance=0.185")


def session_latency(valves: int) -> SessionLatency:
    """Run ``valves`` valves through the session's app; the latencies' median and worst, in seconds.

    Returns
    -------
    SessionLatency
        ``decision_s`` and ``report_s``: (median, max) over the valves; ``valves``, ``tests``.
    """
    from edc_bench.session.build import make_app
    from edc_bench.session.runner import RigChoice

    with tempfile.TemporaryDirectory(prefix="edc-bench-perf-") as scratch:
        folder = Path(scratch)
        app = make_app(None, RigChoice(), folder / "records", f"sqlite:///{folder / 'history.sqlite'}", "perf",
                       "perf")

        async def shift() -> None:
            async with app.run_test(size=(120, 40)) as pilot:
                await pilot.pause()
                for n in range(valves):
                    for line in (VALVES[n % len(VALVES)], f"PS-{n}", ""):
                        for _ in range(2):  # a valve judged earlier in the shift is asked about: scanned again
                            app.query_one("#entry").value = line
                            await pilot.press("enter")
                            if not app.scan.pending:
                                break
                    await app.workers.wait_for_complete()
                    while app.drawing.is_set():  # the reports, drawn after the decision
                        await asyncio.sleep(0.05)
                    await app.workers.wait_for_complete()
                    await pilot.pause()
                app.exit()

        asyncio.run(shift())
        decision, report = np.array(app.decision_latencies_s), np.array(app.report_latencies_s)
        return SessionLatency((float(np.median(decision)), float(decision.max())),
                              (float(np.median(report)), float(report.max())), len(decision), app.shift.tests)
