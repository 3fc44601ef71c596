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

    Raises
    ------
    OSError
        If it cannot be written (``path`` unchanged, no temporary file left); an error that names no file (a full
        disk's ENOSPC from a write) is raised again naming ``path``.
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
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.filename is None and exc.errno is not None:
            # a write into a full disk names no file: name the one that was not written, for the one-line error
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
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


def package_folders() -> tuple[Path, ...]:
    """The folders of the installed package itself (``edc_bench``, ``firmware_proto``): read-only to the program.

    Returns
    -------
    tuple of pathlib.Path
        Resolved folders; in an editable install, the source tree's.
    """
    import importlib.util

    import edc_bench

    folders = [Path(edc_bench.__file__).resolve().parent]
    spec = importlib.util.find_spec("firmware_proto")
    if spec is not None and spec.submodule_search_locations:
        folders += [Path(p).resolve() for p in spec.submodule_search_locations]
    return tuple(folders)


def inside_package(path: Path) -> bool:
    """Whether ``path`` (existing or not) is one of :func:`package_folders` or lies inside one."""
    resolved = Path(path).resolve()
    return any(resolved == folder or folder in resolved.parents for folder in package_folders())


def source_checkout() -> Path | None:
    """The source tree this edc-bench runs from (a checkout, installed editable or on the path), else None.

    Only a source tree may have its shipped files rebuilt (``edc-bench train --rebuild-shipped``); an installed
    package (site-packages) never.
    """
    import edc_bench

    root = Path(edc_bench.__file__).resolve().parent.parent
    installed = any(part in ("site-packages", "dist-packages") for part in root.parts)
    return root if not installed and (root / "pyproject.toml").is_file() and (root / "configs").is_dir() \
        else None
