"""Shared fixtures.

The suite mirrors the package: one folder per layer (tests/protocol, ...,
tests/cli) and tests/bench for the top-level bench.py, replay.py and
station.py. Tests marked ``slow`` are skipped by default (``-m "not slow"``
in pyproject.toml's addopts); run them with ``pytest -m slow -n 0``, everything
with ``pytest -m ""``.
"""

from __future__ import annotations

import itertools
import os
import signal
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from typing import NamedTuple

import can
import pytest
from hypothesis import settings

# Property tests draw the same examples on every run (seeded by the test's name): CI never fails on an example
# no one ran before. `pytest --hypothesis-profile explore` draws new ones, to hunt for what the fixed set misses.
# no deadline: an example held off the CPU on a busy machine is not a failing one (the suite judges no speed)
settings.register_profile("default", derandomize=True, deadline=None)
settings.register_profile("explore", derandomize=False, max_examples=2000)
settings.load_profile("default")

# People read local time (edc_bench.timefmt): the suite runs in UTC whatever the developer's zone, so that what a
# test expects to read does not depend on where it runs; tests of other zones set theirs (the time_zone fixture).
os.environ["TZ"] = "UTC0"
time.tzset()

# A suite started in the background (`pytest &`, nohup) inherits SIGINT ignored, and so would every edc-bench it
# runs: the tests of Ctrl-C would fail for the way the suite was started (a newcomer's trial found 10). Ctrl-C
# means what it means to a technician, in the suite and in the commands it starts.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

from edc_bench.config import Variant, load_variant
from edc_bench.physics.valve import ValveSpec, parse_valve_spec
from edc_bench.protocol import Icd, default_icd
from edc_bench.runtime.clock import SimulatedClock
from edc_bench.sim.inprocess import InProcessRig
from edc_bench.sim.lockstep_bus import lockstep_pair
from edc_bench.sim.rig import RigOptions, SimulatedRig

#: the history tests' PostgreSQL server and databases (tests/pg_server.py), the web view's site (tests/web_site.py)
pytest_plugins = ["pg_server", "web_site"]


def pytest_configure(config: pytest.Config) -> None:
    build_c_firmware()
    keep_compiled_kernels_out_of_the_users_cache(config)


def keep_compiled_kernels_out_of_the_users_cache(config: pytest.Config) -> None:
    """The batch path's compiled kernels (numba) go to pytest's cache folder: test modules import the batch path as
    they are collected, before :func:`_station_dirs` points edc-bench's cache folder elsewhere. Shared by the
    workers and kept between runs, so a run compiles them only when they changed. Without pytest's cache (``-p
    no:cacheprovider``, or a folder that cannot be made) a temporary folder of the run's own."""
    import os
    import tempfile

    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    cache = getattr(config, "cache", None)
    try:
        folder = cache.mkdir("numba") if cache is not None else None
    except OSError:  # pytest itself only warns that it cannot write its cache
        folder = None
    if folder is None:
        folder = tempfile.mkdtemp(prefix="edc-bench-numba-")
        remove_at_exit(folder)
    os.environ["NUMBA_CACHE_DIR"] = str(folder)


def remove_at_exit(folder: str | os.PathLike[str]) -> None:
    """Remove a temporary folder of this test process when it exits (a loaded library may stay mapped: Linux
    keeps an unlinked file's pages until it is unmapped)."""
    import atexit
    import shutil

    atexit.register(shutil.rmtree, folder, ignore_errors=True)


def build_c_firmware() -> None:
    """Build the C firmware core once per test process where make and a C compiler are (CI has gcc), so that its
    tests run against it; without them they skip, saying how to build it. A build that fails is kept in
    ``EDC_BENCH_C_FIRMWARE_BUILD_ERROR`` for tests/firmware/test_c_firmware.py to report."""
    import os
    import shutil
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from firmware_proto.c_firmware import C_DIR, LIBRARY_ENV, library_path

    if os.environ.get(LIBRARY_ENV):
        return
    if library_path().is_file():  # this user's first-use build of these very sources (firmware_proto/c_firmware.py)
        os.environ[LIBRARY_ENV] = str(library_path())  # pinned: the tests' own cache folder has none
        return
    if not (shutil.which("make") and shutil.which("cc")):
        return
    build = Path(tempfile.mkdtemp(prefix="edc-bench-c-firmware-"))
    remove_at_exit(build)  # one per test process: left behind, CI's runs filled the disk's temporary folder
    proc = subprocess.run(["make", "-C", str(C_DIR), f"BUILD={build}", f"PYTHON={sys.executable}"],
                          capture_output=True, text=True)
    if proc.returncode == 0:
        os.environ[LIBRARY_ENV] = str(build / "libedcrig.so")
    else:
        os.environ["EDC_BENCH_C_FIRMWARE_BUILD_ERROR"] = (proc.stdout + proc.stderr)[-2000:]


@pytest.fixture(scope="session")
def icd() -> Icd:
    return default_icd()


@pytest.fixture(scope="session")
def variant() -> Variant:
    return load_variant("p-edc-default")


@pytest.fixture(scope="session", params=["p-edc-default", "p-edc-long"])
def any_variant(request: pytest.FixtureRequest) -> Variant:
    return load_variant(request.param)


@pytest.fixture(scope="session", autouse=True)
def _station_dirs(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Keep the tests' history database and caches out of the user's own folders (subprocesses inherit it)."""
    import os

    base = tmp_path_factory.mktemp("station")
    os.environ.setdefault("EDC_BENCH_DATA_DIR", str(base / "data"))
    os.environ.setdefault("EDC_BENCH_CACHE_DIR", str(base / "cache"))


# -- the simulated bench: the rig in process, in simulated time ---------------------------------------------------


class SimBench(NamedTuple):
    """What :func:`edc_bench.bench.run_bench_test` needs to run against the simulated rig."""

    bench: can.BusABC  # the bench's end of the bus
    clock: SimulatedClock  # simulated time; ``clock.rig`` is the InProcessRig serving the rig's end
    rig: SimulatedRig  # the rig itself: its firmware, plant and truth


_channels = itertools.count()


@pytest.fixture()
def simulated_bench() -> Iterator[Callable[..., SimBench]]:
    """A factory for the simulated rig on a bus pair (:func:`simulated_bench_factory`), for one test."""
    with simulated_bench_factory() as make:
        yield make


@contextmanager
def simulated_bench_factory() -> Iterator[Callable[..., SimBench]]:
    """A factory for the simulated rig on a bus pair, as ``run_simulated_test`` builds it.

    ``simulated_bench(variant, valve="new", seed=0, *, options=None, interface="lockstep")``
    returns ``(bench_bus, clock, rig)``: ``interface="lockstep"`` joins the two ends back to back
    (``lockstep_pair``, what ``run_simulated_test`` uses), ``"virtual"`` puts them on a fresh
    python-can ``virtual`` channel (timestamps preserved). Every bus made is shut down at teardown.
    """
    with ExitStack() as stack:

        def make(variant: Variant, valve: str | ValveSpec = "new", seed: int = 0, *,
                 options: RigOptions | None = None, interface: str = "lockstep") -> SimBench:
            spec = valve if isinstance(valve, ValveSpec) else parse_valve_spec(valve, variant)
            rig = SimulatedRig(variant, spec, seed, options)
            channel = f"tests-sim-{next(_channels)}"
            if interface == "lockstep":
                bench, rig_bus = lockstep_pair(channel)
            elif interface == "virtual":
                bench = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
                rig_bus = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
            else:
                raise ValueError(f"interface must be 'lockstep' or 'virtual', not {interface!r}")
            stack.callback(bench.shutdown)
            stack.callback(rig_bus.shutdown)
            return SimBench(bench, SimulatedClock(InProcessRig(rig_bus, rig)), rig)

        yield make


@pytest.fixture()
def time_zone(monkeypatch: pytest.MonkeyPatch):
    """Set this process's local time zone (a POSIX TZ string: no tz database needed), restored afterwards."""

    def set_zone(zone: str) -> None:
        monkeypatch.setenv("TZ", zone)
        time.tzset()

    yield set_zone
    monkeypatch.undo()
    time.tzset()
