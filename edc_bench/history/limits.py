"""How long the history may take: a connection and each statement have limits, so a network that went silent (a
VPN down) costs a test seconds, never minutes.

The limits are the station's settings: ``[history]`` in ``station.toml`` in the station's data folder, or the
environment (``EDC_BENCH_HISTORY_CONNECT_TIMEOUT_S``, ``EDC_BENCH_HISTORY_STATEMENT_TIMEOUT_S``), which wins::

    [history]
    connect_timeout_s = 5      # to reach the server and log in
    statement_timeout_s = 15   # each statement, and each wait for the server's answer

They hold on PostgreSQL (libpq's ``connect_timeout``, the server's ``statement_timeout`` and the socket's
``tcp_user_timeout``, so a server that stops answering mid-statement is given up too); a station's SQLite file
is on its own disk.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from edc_bench.errors import ConfigError
from edc_bench.station_settings import settings_section

DEFAULT_CONNECT_S = 5.0
DEFAULT_STATEMENT_S = 15.0
#: libpq counts connect_timeout in whole seconds and takes less than 2 as 2.
MIN_CONNECT_S = 2.0


@dataclass(frozen=True)
class HistoryLimits:
    """A connection's and a statement's limit, in seconds."""

    connect_timeout_s: float = DEFAULT_CONNECT_S
    statement_timeout_s: float = DEFAULT_STATEMENT_S

    def connect_args(self, server_options: str = "") -> dict[str, object]:
        """psycopg's (libpq's) connection parameters that hold these limits (``server_options``: more ``-c`` settings
        for the server, before the statement's limit)."""
        statement_ms = int(self.statement_timeout_s * 1000)
        return {"connect_timeout": max(int(math.ceil(self.connect_timeout_s)), int(MIN_CONNECT_S)),
                "tcp_user_timeout": statement_ms, "keepalives": 1, "keepalives_idle": 5, "keepalives_interval": 2,
                "keepalives_count": 3, "options": f"{server_options} -c statement_timeout={statement_ms}".strip()}


def _number(value: object, name: str, where: str) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        number = math.nan
    if not math.isfinite(number) or number <= 0 or number > 3600:
        raise ConfigError(f"{where}: {name} = {value!r} is not a time limit: give seconds, more than 0 and at most "
                          "3600 (e.g. 5)")
    return number


def history_limits(data_folder: Path | None = None) -> HistoryLimits:
    """The station's limits (defaults where nothing is set).

    Raises
    ------
    ConfigError
        For a settings file that cannot be read, or a limit that is not a number of seconds, naming where.
    """
    values: dict[str, float] = {}
    section, path = settings_section("history", data_folder)
    for name in ("connect_timeout_s", "statement_timeout_s"):
        if name in section:
            values[name] = _number(section[name], name, str(path))
    for name, variable in (("connect_timeout_s", "EDC_BENCH_HISTORY_CONNECT_TIMEOUT_S"),
                           ("statement_timeout_s", "EDC_BENCH_HISTORY_STATEMENT_TIMEOUT_S")):
        if os.environ.get(variable):
            values[name] = _number(os.environ[variable], variable, "the environment")
    return HistoryLimits(**values)


__all__ = ["HistoryLimits", "history_limits"]
