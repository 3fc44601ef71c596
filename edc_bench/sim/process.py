"""Start ``edc-bench rig`` as a child process on a free loopback port."""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager

from edc_bench.errors import RigError


@contextmanager
def rig_process(variant: str | None, valve: str, seed: int, adapter: str = "none",
                status: dict[str, float] | None = None, extra: list[str] | None = None) -> Iterator[str]:
    """Run the simulated rig in its own process for the duration of a ``with``.

    Parameters
    ----------
    variant, valve, seed :
        As ``edc-bench rig`` takes them.
    adapter : str, optional
        ``edc-bench rig --adapter``: the CAN adapter's timing to simulate.
    status : dict, optional
        Filled when the process has stopped: ``worst_gap_ms``, the longest the
        rig went without serving while a host was connected (a disturbed rig).
    extra : list of str, optional
        More ``edc-bench rig`` arguments (``--break RULE``).

    Yields
    ------
    str
        The pyserial URL to give python-can's slcan interface
        (``socket://127.0.0.1:PORT``).
    """
    cmd = [sys.executable, "-m", "edc_bench", "rig", "--listen", "127.0.0.1:0", "--valve", valve,
           "--seed", str(seed), "--adapter", adapter]
    if variant:
        cmd += ["--variant", variant]
    cmd += extra or []
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    above_the_bench(proc.pid)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        match = re.search(r"(socket://127\.0\.0\.1:\d+)", line)
        if not match:
            rest = proc.stdout.read() if proc.poll() is not None else ""
            raise RigError(f"the simulated rig process did not start: {(line + rest).strip()}")
        yield match.group(1)
    finally:
        proc.terminate()
        try:
            out, _ = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
        gap = re.search(r"worst serve gap ([0-9.]+) ms", out or "")
        if status is not None and gap:
            status["worst_gap_ms"] = float(gap.group(1))


def above_the_bench(pid: int) -> int | None:
    """Give the rig process ``pid`` a real-time priority one above this (bench) process's, when the bench runs
    under one (as it raises itself to where the PC permits, :mod:`edc_bench.runtime.priority`, or under ``chrt``).

    The rig inherits the bench's policy and priority; under SCHED_FIFO a process of equal priority is never
    preempted, so the bench's spinning loop and the rig took turns only when one blocked: the rig went unserved
    for milliseconds and the test aborted, "replies missing". The rig is the hardware's side: it sleeps until a
    frame comes and must then answer at once, so it runs above the bench. Returns the rig's priority (None: the
    bench is not real-time, or the OS refused, and the rig keeps what it inherited).
    """
    import os

    try:
        policy = os.sched_getscheduler(0)
        if policy not in (os.SCHED_FIFO, os.SCHED_RR):
            return None
        priority = min(os.sched_getparam(0).sched_priority + 1, os.sched_get_priority_max(policy))
        os.sched_setscheduler(pid, policy, os.sched_param(priority))
    except (AttributeError, OSError):  # not Linux, or not permitted: the rig keeps the bench's priority
        return None
    return priority
