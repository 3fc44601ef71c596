"""After `pip install .` (a wheel, not an editable install): the C firmware's sources are in it, `edc-bench rig
--firmware c` builds the library into the user's cache and runs it, and neither that nor `train` writes a byte inside
the installed package (#52). Slow: the wheel is built (sources only) and installed into a folder of its own."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from package_files import install_wheel, package_digest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory, worker_id: str) -> Path:
    """The installed package's folder (``pip install --target``), built once for all test processes."""
    shared = tmp_path_factory.getbasetemp() if worker_id == "master" else tmp_path_factory.getbasetemp().parent
    return install_wheel(shared / "installed-edc-bench")


def _env(site: Path, tmp_path: Path) -> dict[str, str]:
    """A new user's environment: the installed package first on the path, no library named, a cache of its own."""
    env = {k: v for k, v in os.environ.items() if k not in ("EDC_BENCH_C_FIRMWARE", "EDC_BENCH_CACHE_DIR", "CC")}
    return {**env, "PYTHONPATH": str(site), "XDG_CACHE_HOME": str(tmp_path / "xdg"),
            "EDC_BENCH_DATA_DIR": str(tmp_path / "station")}


def _run(site: Path, tmp_path: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "edc_bench", *args], capture_output=True, text=True, cwd=tmp_path,
                          env=_env(site, tmp_path), timeout=timeout)


def _folders(site: Path) -> tuple[Path, ...]:
    return (site / "edc_bench", site / "firmware_proto")


def test_the_wheel_is_what_runs_and_carries_the_c_firmware_s_sources(site: Path, tmp_path: Path) -> None:
    where = subprocess.run([sys.executable, "-c", "import edc_bench, firmware_proto.c_firmware as c; "
                            "print(edc_bench.__file__); print(c.C_DIR)"], capture_output=True, text=True,
                           cwd=tmp_path, env=_env(site, tmp_path), check=True).stdout.split()
    assert where == [str(site / "edc_bench" / "__init__.py"), str(site / "firmware_proto" / "c")]
    for name in ("Makefile", "src/rig_firmware.c", "src/rig_firmware.h", "hal/stm32g4_hal.c", "README.md"):
        assert (site / "firmware_proto" / "c" / name).is_file(), name
    assert not (site / "firmware_proto" / "c" / "build").exists()


def test_rig_firmware_c_works_after_pip_install_and_builds_into_the_user_s_cache(site: Path, tmp_path: Path) -> None:
    import shutil

    if not (shutil.which("make") and shutil.which("cc")):
        pytest.skip("no make or cc on this machine (without them: tests/firmware/test_c_firmware_build.py)")
    before = package_digest(_folders(site))
    rig = subprocess.Popen([sys.executable, "-m", "edc_bench", "rig", "--listen", "127.0.0.1:0", "--firmware", "c"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                           env=_env(site, tmp_path))
    try:
        line = rig.stdout.readline()  # the first line: serving, or nothing (and the reason on stderr)
        assert "c firmware" in line and "serving slcan at socket://127.0.0.1:" in line, line + rig.stderr.read()
    finally:
        rig.send_signal(signal.SIGINT)
        out, err = rig.communicate(timeout=60)
    assert rig.returncode == 0, out + err
    assert "building the C firmware into" in err
    built = sorted((tmp_path / "xdg" / "edc-bench").glob("firmware-*/libedcrig.so"))
    assert len(built) == 1, err
    assert package_digest(_folders(site)) == before
    # a test through the C core, the library found again in the cache
    test = _run(site, tmp_path, "test", "--firmware", "c", "--valve", "new", "--no-history", "--no-figure",
                "--out", "rec")
    assert test.returncode in (0, 10), test.stderr
    assert "building" not in test.stderr
    assert package_digest(_folders(site)) == before


def test_train_writes_nothing_inside_the_installed_package(site: Path, tmp_path: Path) -> None:
    pytest.importorskip("sklearn", reason="training needs the 'train' extra")
    before = package_digest(_folders(site))
    for args, code in ((("train", "--count", "20", "--save-dataset", "d.npz"), 0),
                       (("train", "--dataset", "d.npz", "--own", "--variants", "p-edc-hard"), 0),
                       (("train", "--dataset", "d.npz", "--rebuild-shipped"), 2),
                       (("train", "--dataset", "d.npz", "--models-dir", str(site / "edc_bench" / "verdict" / "models")),
                        2),
                       (("train", "--adopt", "shipped"), 0)):
        proc = _run(site, tmp_path, *args)
        assert proc.returncode == code, (args, proc.stderr)
        assert package_digest(_folders(site)) == before, args
    assert sorted(p.name for p in (tmp_path / "station" / "models" / "candidates").iterdir())
