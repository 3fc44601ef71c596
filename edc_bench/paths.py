"""Where edc-bench keeps files of its own: the station's data and its caches.

The user's platform directories (via platformdirs), unless the environment
says otherwise: ``EDC_BENCH_DATA_DIR`` and ``EDC_BENCH_CACHE_DIR`` (tests
and shared stations set them).
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any


def data_dir(create: bool = True) -> Path:
    """The station's data folder (history database, the station's variants); created if missing unless told not to."""
    configured = os.environ.get("EDC_BENCH_DATA_DIR")
    if configured:
        path = Path(configured)
    else:
        from platformdirs import user_data_dir

        path = Path(user_data_dir("edc-bench", appauthor=False))
    if create:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            from edc_bench.errors import ConfigError

            where = "EDC_BENCH_DATA_DIR" if configured else "the station's data folder"
            raise ConfigError(f"{where} {path} cannot be used as a folder ({exc.strerror}): set EDC_BENCH_DATA_DIR "
                              "to a folder this user can write") from None
    return path


def cache_dir() -> Path:
    """The cache folder (results that can always be computed again); not created here."""
    configured = os.environ.get("EDC_BENCH_CACHE_DIR")
    if configured:
        return Path(configured)
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("edc-bench", appauthor=False))


def umask() -> int:
    """The process's file-creation mask, read without changing it where Linux says it (/proc/self/status)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)  # elsewhere: set and put back at once
    os.umask(mask)
    return mask


def atomic_write(path: Path, write: Callable[[Any], None], mode: str = "wb") -> None:
    """Write ``path`` through ``write(fileobj)`` atomically.

    Parameters
    ----------
    path : pathlib.Path
        Final file path.
    write : callable
        Receives the open temporary file and writes the content.
    mode : str
        ``"wb"`` or ``"w"``.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        # mkstemp makes the file 0600; the shop's records, reports and exports get the mode any new file gets
        # (0644 under umask 022), so that the shop's other accounts can read them
        os.fchmod(fd, 0o666 & ~umask())
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)  # the rename itself survives a power cut
    finally:
        os.close(dir_fd)


def write_json_atomic(path: Path, data: Any) -> None:
    """Write ``data`` as JSON to ``path`` atomically, creating its folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda f: json.dump(data, f), mode="w")
