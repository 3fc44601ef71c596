"""Every module of the default suite that reads a clock or waits on a process or a socket, and why what it asserts
does not depend on how busy the machine is.

The README's test command must pass on a busy PC (a virus scan beside it, two workers on two cores), so no test in
the default suite may judge the machine's speed. A module that reads the wall clock, sleeps, opens a socket or
waits with a timeout is listed here with its kinds (:class:`Kind`); ``tests/structure/test_machine_time.py`` finds
every such module and fails on one missing here (or listed here and no longer reading a clock), and
``docs/testing.md`` prints the list. Tests that do need the machine to themselves are marked ``realtime`` (or
``slow``) and run in ``.ci/run``'s own passes, not in the README's command.
"""

from __future__ import annotations

import enum
import re


class Kind(enum.StrEnum):
    """How a test that reads a clock stays independent of the machine's speed."""

    #: time is simulated (the loop steps a simulated clock), or a real clock is built but no elapsed time is judged
    SIMULATED = "simulated time"
    #: a real process, thread or socket is driven step by step; the outcome is the same at any speed
    LOCKSTEP = "lockstep"
    #: waits for something with a deadline at least 10 times what it needs here: only a hang passes it
    HANG_GUARD = "hang guard"
    #: measures how disturbed its run was (its own side and the other's) and skips, saying why, when it was
    SKIPS_WHEN_DISTURBED = "skips when disturbed"


#: What makes a module read the clock or wait (the structure test's search, on each module's source).
READS_A_CLOCK = re.compile(r"time\.monotonic|perf_counter|time\.time\(\)|time\.sleep|RealTimeClock|"
                           r"import socket|socket\.|\btimeout(?:_s)?=|getloadavg|WebDriverWait|\.join\(\d|"
                           r"\.wait\(\d|asyncio\.sleep|\.wait_for\(")

S, L, H, D = Kind.SIMULATED, Kind.LOCKSTEP, Kind.HANG_GUARD, Kind.SKIPS_WHEN_DISTURBED

#: module (path from the repository's root) -> (its kinds, why)
MODULES: dict[str, tuple[tuple[Kind, ...], str]] = {
    "tests/helpers.py": ((S, H), "edc_bench()'s subprocess timeout is 600 s for commands of 0.5-3 s; the safe-state "
                                 "check compares simulated frame times"),
    "tests/tmux_terminal.py": ((H,), "a screen is awaited for 90 s; the app shows it in about 1 s"),
    "tests/bench/test_replay.py": ((S, H), "simulated tests; replays as processes with 120-300 s timeouts for 1 s"),
    "tests/bench/test_station.py": ((S, H), "check-station's verdict is judged on given lateness; the command itself "
                                            "(120 s timeout for 1.6 s) may say GO or NO-GO"),
    "tests/cli/test_bad_input.py": ((L, H), "a port held by another socket; a READY timeout nobody can meet is the "
                                            "expected outcome; 60 s timeouts for refusals of 0.5 s"),
    "tests/cli/test_bus_interfaces.py": ((L, H), "fake socketcand servers on loopback; the command's own timeouts "
                                                 "(0.3-3 s) expire as expected; 30 s bounds for refusals of 0.4 s"),
    "tests/cli/test_interrupted_commands.py": ((L, H, D), "commands' lines awaited for 120 s (they come in under "
                                                          "1 s); a signal that came after the moment (the child's "
                                                          "CPU time, or its output, says so) skips"),
    "tests/cli/test_plain_install.py": ((L,), "a port held by another socket: refused, at any speed"),
    "tests/cli/test_rig_priority.py": ((H,), "the rig's first two lines read, then it is stopped: 60 s for 1 s"),
    "tests/config/test_config.py": ((H,), "120 s timeout for a command of 0.5 s"),
    "tests/experiments/test_coverage.py": ((H,), "60 s timeouts for refusals of 0.5 s"),
    "tests/firmware/test_c_firmware.py": ((S,), "the C firmware in simulated time (its real-time test is slow and "
                                                "realtime)"),
    "tests/firmware/test_c_firmware_build.py": ((H,), "120 s timeout for a refusal of 0.5 s"),
    "tests/history/test_attacks.py": ((L, H), "a second station's insert is awaited on the lock for 30 s (it blocks "
                                              "in 0.05 s); 600 s timeouts for commands of 1 s"),
    "tests/history/test_history.py": ((L, H), "concurrent writers meet at a barrier; 60-120 s joins for 2 s"),
    "tests/history/test_passwords.py": ((H,), "120 s timeouts for commands refused at once"),
    "tests/history/test_shop_chain.py": ((H,), "600 s timeouts for commands of 1 s"),
    "tests/history/test_shop_labels.py": ((H,), "600 s timeouts for commands of 1-2 s"),
    "tests/history/test_silent_network.py": ((H, D), "a silent server's 2 s limit is given 30 s (the command takes "
                                                     "2.7 s; without the limit, minutes), skipped on a loaded "
                                                     "machine; a 0.5 s statement timeout cuts a 60 s sleep"),
    "tests/perf/test_perf.py": ((S,), "steal windows from given samples; the benchmark itself is slow"),
    "tests/records/test_clock_kind.py": ((S,), "a real-time clock is built to read its kind only"),
    "tests/records/test_report.py": ((S, H), "a bus cut at 4 s of simulated time; 300 s timeouts for 3 s"),
    "tests/records/test_standalone_record.py": ((S, H), "120 s timeouts for 3 s; CAN log times are simulated"),
    "tests/records/test_workshop.py": ((L,), "the session driven by Textual's pilot, message by message"),
    "tests/runtime/test_bus_reader.py": ((L, H), "bytes this thread wrote to loopback are read with a 1 s bound; a "
                                                 "send timeout to a peer that never reads expires as expected"),
    "tests/runtime/test_hostile_bus.py": ((L, D), "slcan over loopback in simulated time; the hostile host's test "
                                                  "skips when its own line took 5 s to arrive"),
    "tests/runtime/test_interrupts.py": ((H, D), "the signals must land mid-test: a test that ended first says so "
                                                 "and the test skips (the kill test is slow and realtime)"),
    "tests/runtime/test_priority.py": ((H,), "120 s timeout for a child of 0.3 s"),
    "tests/runtime/test_signals.py": ((L, H), "signals sent to itself; a child's 30-60 s deadline for 0.3 s"),
    "tests/runtime/test_stop_worker.py": ((S, H), "thread hand-offs awaited for 30 s (they take microseconds)"),
    "tests/session/test_session_app.py": ((L, H), "the app driven by Textual's pilot; a test's worker waits for the "
                                                  "keys (an event, 30-60 s for what comes in milliseconds)"),
    "tests/session/test_session_interrupts.py": ((H, D), "90 s for screens of 1 s; a signal that came after the "
                                                         "test it was meant for ended (its record says so) skips"),
    "tests/sim/test_kernels.py": ((S,), "the plant's kernels in simulated time"),
    "tests/sim/test_server.py": ((S, H), "a fake clock over a socket pair; a 10 s alarm per test of 0.05 s"),
    "tests/structure/test_startup.py": ((H,), "120 s timeouts for commands of 2.5 s"),
    "tests/ui/test_live.py": ((S, D), "the panel's process skips the test when it was killed for being late"),
    "tests/verdict/test_variant_model.py": ((S, H), "120 s timeouts for commands of 1 s"),
    "tests/web/test_web_browser.py": ((H,), "30 s for the server to start (0.1 s) and for each element "
                                            "(0.1-0.5 s); 120 s for a PDF drawn on request (2-3 s)"),
    "tests/web/test_web_command.py": ((L, H), "the page is fetched once the URL is printed (the socket listens by "
                                              "then); 60 s for a page of 0.05 s"),
    "tests/web/test_web_postgres.py": ((H,), "10 s for a reload the server makes in 0.1 s; the sign-in throttle's "
                                             "300 s window holds 6 tries of 0.5 s"),
}

#: modules whose clock reads are all in slow or realtime tests (or, for a helper, used only by those): module -> why
ONLY_IN_SLOW_TESTS: dict[str, str] = {
    "tests/history/test_many_stations.py": "eight stations and an engineer at once: one slow test",
    "tests/history/test_shop_network_doc.py": "the shop-network page's steps on a server of its own: one slow test",
    "tests/learning/test_train.py": "the shipped models rebuilt as a command: the slow test",
    "tests/package_files.py": "the wheel's install, for the installed-package tests (slow)",
    "tests/parts/second_plant.py": "the second plant's study prints its own duration when run by hand; its "
                                   "tests are slow",
    "tests/session/test_session_tmux.py": "the session in a real terminal: every test in it is slow",
    "tests/runtime/test_realtime.py": "every real-time test in it is slow and realtime; the one default test reads "
                                      "no clock",
}
