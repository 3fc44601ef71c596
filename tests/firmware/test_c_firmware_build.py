"""The C firmware comes with the install (#52): built on first use into the user's cache, never inside the package,
and without make or a compiler one line saying what is missing.

Measured before: `edc-bench rig --firmware c` after `pip install .` asked to run
`make -C .../site-packages/firmware_proto/c` (to build inside the installed package) or to name a library built
elsewhere.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from package_files import package_digest

from firmware_proto import c_firmware
from firmware_proto.c_firmware import LIBRARY_ENV, CFirmwareMissing, cached_library_path, load_library

needs_tools = pytest.mark.skipif(not (shutil.which("make") and shutil.which("cc")),
                                 reason="no make or cc on this machine: the first-use build cannot run here")


def _clean_env(tmp_path: Path, path: str) -> dict[str, str]:
    """This environment with a fresh cache, no library named, and ``path`` as PATH."""
    env = {k: v for k, v in os.environ.items() if k not in (LIBRARY_ENV, "CC")}
    return {**env, "PATH": path, "EDC_BENCH_CACHE_DIR": str(tmp_path / "cache")}


@pytest.mark.parametrize("tools", [(), ("make",)], ids=["neither", "make-only"])
@pytest.mark.parametrize("command", [["rig", "--listen", "127.0.0.1:0"], ["test", "--no-history", "--no-figure"]])
def test_without_a_compiler_firmware_c_says_what_is_missing_in_one_line(tmp_path: Path, tools: tuple[str, ...],
                                                                        command: list[str]) -> None:
    bin_dir = tmp_path / "bin"  # PATH without cc (and without make, or with it)
    bin_dir.mkdir()
    for tool in tools:
        if shutil.which(tool):
            (bin_dir / tool).symlink_to(shutil.which(tool))
    proc = subprocess.run([sys.executable, "-m", "edc_bench", *command, "--firmware", "c"], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path, env=_clean_env(tmp_path, str(bin_dir)))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "no C compiler (cc)" in lines[0] and LIBRARY_ENV in lines[0] and "apt-get install" in lines[0], lines[0]
    assert ("no make" in lines[0]) == (not tools), lines[0]
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").iterdir())


@needs_tools
def test_the_first_use_builds_into_the_cache_once_never_into_the_package(tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(LIBRARY_ENV, raising=False)
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("EDC_BENCH_CACHE_DIR", str(tmp_path / "cache"))
    before = package_digest()
    expected = cached_library_path()
    assert expected.parent.parent == tmp_path / "cache" and expected.parent.name.startswith("firmware-")
    lib = load_library()
    assert Path(lib._name) == expected and expected.is_file()
    built_at = expected.stat().st_mtime_ns
    load_library()  # the second use loads the first's build
    assert expected.stat().st_mtime_ns == built_at
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == [expected.parent.name]  # no work left over
    assert package_digest() == before


def test_the_cache_follows_xdg_cache_home_and_the_sources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if not sys.platform.startswith("linux"):
        pytest.skip("XDG_CACHE_HOME is Linux's")
    monkeypatch.delenv("EDC_BENCH_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    path = cached_library_path()
    assert path.parent.parent == tmp_path / "xdg" / "edc-bench"
    # another source (a changed Makefile, C file, DBC or generator) is another folder: never a stale build
    digest = c_firmware.sources_digest()
    monkeypatch.setattr(c_firmware, "C_DIR", tmp_path / "c")
    shutil.copytree(Path(c_firmware.__file__).parent / "c", tmp_path / "c")
    assert c_firmware.sources_digest() == digest
    with open(tmp_path / "c" / "src" / "rig_firmware.c", "a", encoding="utf-8") as source:
        source.write("\n/* changed */\n")
    assert c_firmware.sources_digest() != digest


@needs_tools
def test_a_build_that_fails_says_so_in_one_line_and_keeps_make_s_output(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(LIBRARY_ENV, raising=False)
    monkeypatch.setenv("EDC_BENCH_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", "false")  # a compiler that fails
    with pytest.raises(CFirmwareMissing) as raised:
        load_library()
    message = str(raised.value)
    assert "\n" not in message and "building the C firmware failed" in message, message
    log = Path(message.rsplit(" ", 1)[-1])
    assert log.is_file() and "false" in log.read_text(encoding="utf-8")
    assert not cached_library_path().exists()  # nothing half-built where the next run looks
    assert [p.name for p in (tmp_path / "cache").iterdir()] == [log.name]


def test_a_named_library_that_is_missing_says_how_to_build_one_outside_the_package(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LIBRARY_ENV, str(tmp_path / "missing.so"))
    with pytest.raises(CFirmwareMissing, match=rf"unset {LIBRARY_ENV} to build it on first use, or build one with "
                                               r"'make -C .*firmware_proto/c BUILD=DIR'"):
        load_library()
