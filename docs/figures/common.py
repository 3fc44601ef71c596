"""The registry of measurements, their stored results, and formatting shared by the pages' figures."""

from __future__ import annotations

import contextlib
import datetime as dt
import importlib
import io
import json
import os
import pkgutil
import platform
import subprocess
import tempfile
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Sequence

#: Where measurements are stored; ``EDC_BENCH_DOCS_DATA`` points elsewhere (the slow check measures into a
#: temporary folder and checks the pages against it).
DEFAULT_DATA_DIR = Path(__file__).resolve().parent / "data"


@dataclass(frozen=True)
class Measurement:
    """A figure too slow to compute while a page is written: measured by its command, stored, then printed.

    Attributes
    ----------
    name : str
        File stem in the data folder, and the name ``python docs/regenerate.py --measure`` takes.
    function : callable
        Returns the JSON-serialisable result (round it to what the page prints, or a little finer).
    minutes : float
        About how long it takes on two cores (for ``--list`` and for planning CI's slow pass).
    timing : bool
        True when the result depends on the machine (speeds, latencies): it is stored with the machine and
        the date, printed with them, and not measured again in CI (a busy machine must not fail CI).
    """

    name: str
    function: Callable[[], Any]
    minutes: float
    timing: bool = False


REGISTRY: dict[str, Measurement] = {}


def measurement(name: str, *, minutes: float, timing: bool = False) -> Callable[[Callable[[], Any]], Callable[[], Any]]:
    """Register a function as the measurement ``name`` (a decorator)."""

    def register(function: Callable[[], Any]) -> Callable[[], Any]:
        if name in REGISTRY:
            raise ValueError(f"two measurements are named {name!r}")
        REGISTRY[name] = Measurement(name, function, minutes, timing)
        return function

    return register


def load_all() -> dict[str, Measurement]:
    """Import every page's module, so that every measurement is registered; return the registry."""
    package = importlib.import_module("figures")
    for module in pkgutil.iter_modules(package.__path__):
        importlib.import_module(f"figures.{module.name}")
    return REGISTRY


def data_dir() -> Path:
    """The folder measurements are read from and written to."""
    return Path(os.environ.get("EDC_BENCH_DOCS_DATA", DEFAULT_DATA_DIR))


def machine() -> str:
    """This machine in a few words: CPU model, cores, OS, Python."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, Python {platform.python_version()}"


def measured_commit() -> str | None:
    """The commit of the code a timing measured (short hash; '+ changes' when the package's files differ from it),
    or None outside a git checkout: a page's figure says which code it is of."""
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                              check=True).stdout.strip()
        changed = subprocess.run(["git", "status", "--porcelain", "--", "edc_bench", "firmware_proto", "configs"],
                                 cwd=root, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return f"{head} + changes" if changed else head


@contextlib.contextmanager
def isolated_station() -> Iterator[Path]:
    """A temporary, empty station: data, cache and variant folders and the working folder, restored afterwards.

    Every measurement and every page's writing runs in one, so that what this machine's station holds (an
    adopted model, its own baselines or variants, cached margins) never changes a figure.

    Yields
    ------
    Path
        The temporary folder (the working folder meanwhile).
    """
    names = ("EDC_BENCH_DATA_DIR", "EDC_BENCH_CACHE_DIR", "EDC_BENCH_VARIANTS_DIR")
    saved = {name: os.environ.get(name) for name in names}
    cwd = Path.cwd()
    with tempfile.TemporaryDirectory(prefix="edc-docs-") as folder:
        root = Path(folder)
        for name, sub in zip(names, ("data", "cache", "variants"), strict=True):
            os.environ[name] = str(root / sub)
        os.chdir(root)
        try:
            yield root
        finally:
            os.chdir(cwd)
            for name, value in saved.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value


def run_cli(argv: Sequence[str]) -> tuple[int, str, str]:
    """``edc-bench ARGV`` in this process: exit code, stdout, stderr."""
    from edc_bench.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def shipped_classifier(kind: str = "mlp") -> Any:
    """The packaged network (``mlp``) or linear model (``linear``), whatever a station adopted."""
    from edc_bench.verdict.classifier import (
        DEFAULT_MODEL,
        LINEAR_MODEL,
        ValveClassifier,
        packaged_model_path,
    )

    return ValveClassifier(packaged_model_path(DEFAULT_MODEL if kind == "mlp" else LINEAR_MODEL))


def measure(name: str) -> Path:
    """Run the measurement ``name`` in an isolated station and store its result (with the machine and date
    for a timing)."""
    entry = load_all()[name]
    with isolated_station():
        result = entry.function()
    record: dict[str, Any] = {"name": name, "command": f"python docs/regenerate.py --measure {name}",
                              "result": result}
    if entry.timing:
        record["measured"] = {"date": dt.date.today().isoformat(), "machine": machine(), "commit": measured_commit()}
    folder = data_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.json"
    path.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    return path


def stored_record(name: str) -> dict[str, Any]:
    """The stored record of measurement ``name`` (its result and, for a timing, when and where)."""
    path = data_dir() / f"{name}.json"
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing: measure it with `python docs/regenerate.py --measure {name}`")
    return json.loads(path.read_text())


def stored(name: str) -> Any:
    """The stored result of measurement ``name``."""
    return stored_record(name)["result"]


def measured_on(name: str) -> str:
    """'Measured on <date> on <machine> (`command`).' for a timing measurement."""
    record = stored_record(name)
    when = record["measured"]
    code = f", code at commit {when['commit']}" if when.get("commit") else ""
    return f"Measured on {when['date']} on {when['machine']}{code} (`{record['command']}`)."


def when_and_where(name: str) -> str:
    """'<date>, <machine>' of a timing measurement, to print beside its figure."""
    when = stored_record(name)["measured"]
    return f"{when['date']}, {when['machine']}"


def wrap(text: str, width: int = 110) -> str:
    """A paragraph of generated prose, wrapped like the pages' hand-written ones."""
    return textwrap.fill(text, width=width, break_long_words=False, break_on_hyphens=False)


def table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def percent(value: float, digits: int = 1, *, sign: bool = False) -> str:
    """``value`` (a fraction) as a percentage: 0.0123 -> '1.2 %' ('+1.2 %' with ``sign``)."""
    return f"{value * 100:{'+' if sign else ''}.{digits}f} %"


def span(low: float, high: float, fmt: str = "{:.1f}", unit: str = "") -> str:
    """'low-high unit', or one figure when they print the same."""
    a, b = fmt.format(low), fmt.format(high)
    text = a if a == b else f"{a}-{b}"
    return f"{text} {unit}".strip()
