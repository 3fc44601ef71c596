"""Build hook: the modules every tick runs through, compiled by mypyc into the wheel.

A bench test's tick is about two hundred Python calls on the bench's side and
the simulated rig's (frames, reply matching, the controller, the trace, the
firmware and the plant). mypyc compiles these same source files, type hints
and all, to C extension modules: one definition, run as C. The arithmetic stays
IEEE double, operation for operation (``-ffp-contract=off``: no fused
multiply-add, whatever the compiler's target), so a compiled run gives the same
records (trace, frames, record.json), to the bit, as the source
(``tests/structure/test_compiled.py``).

- A wheel (``pip install .``) carries the compiled modules beside their
  sources; Python imports the compiled one.
- An editable install (``pip install -e .``) compiles nothing: a developer's
  edit takes effect at once.
- ``EDC_BENCH_PURE_PYTHON=1`` builds a wheel without them (a machine without a
  C compiler). Everything works the same, only slower: the simulated test
  takes about twice as long (docs/performance.md). Tracebacks from a compiled
  module show its source lines without the ``^^^`` markers.

What is compiled is :data:`COMPILED`. A module there must type-check under
mypy (mypyc checks its types at run time) and must not be changed from outside
while it runs: a compiled class's methods and a compiled module's functions
cannot be monkeypatched. That is why the controller's law
(``edc_bench/control/law.py``) stays interpreted: its callers look it up at
every call, so one change there reaches the loop, replay, the batch path and
the floor.
"""

from __future__ import annotations

import importlib.machinery
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from hatchling.builders.hooks.plugin.interface import BuildHookInterface

#: The modules compiled, relative to the project root (the tick's hot path, bench side and simulated rig side).
COMPILED = (
    "edc_bench/control/fel.py",
    "edc_bench/control/pid.py",
    "edc_bench/control/estimators.py",
    "edc_bench/control/scalar_ops.py",
    "edc_bench/protocol/crc.py",
    "edc_bench/protocol/icd.py",
    "edc_bench/engine/tick.py",
    "edc_bench/engine/replies.py",
    "edc_bench/engine/trace.py",
    "edc_bench/engine/tracking.py",
    "edc_bench/runtime/loop.py",
    "edc_bench/runtime/clock.py",
    "edc_bench/sim/plant.py",
    "edc_bench/sim/rig.py",
    "edc_bench/sim/inprocess.py",
    "edc_bench/sim/sensors.py",
    "edc_bench/sim/adapter.py",
    "firmware_proto/firmware.py",
)

#: Set to 1 to build a wheel of sources only.
PURE_PYTHON_ENV = "EDC_BENCH_PURE_PYTHON"
_YES, _NO = ("1", "true", "yes"), ("", "0", "false", "no")

_SETUP = """\
import sys
from setuptools import setup
from mypyc.build import mypycify

# the package's modules they import are read for their types, not compiled, and their own type errors are not
# this build's; installed packages (numpy, python-can, ...) are not looked at, so their values are typed Any and
# run with Python's own semantics, and a build does not depend on what the build environment happens to hold
options = ["--ignore-missing-imports", "--follow-imports=silent", "--no-site-packages", "--python-version=3.11"]
extensions = mypycify([*options, *{paths!r}], opt_level="3", group_name="edc_bench_compiled")
for extension in extensions:
    # IEEE double, operation for operation: never a fused multiply-add, even on a target that has one
    extension.extra_compile_args = [*extension.extra_compile_args, "-ffp-contract=off"]
setup(name="edc-bench-compiled", packages=[], py_modules=[], ext_modules=extensions)
"""


class CompiledEngineHook(BuildHookInterface):
    """Compiles :data:`COMPILED` with mypyc and puts the extension modules in the wheel."""

    PLUGIN_NAME = "custom"

    def initialize(self, version: str, build_data: dict[str, Any]) -> None:
        """Compile :data:`COMPILED` into a temporary folder and add the extension modules to the wheel's files."""
        if self.target_name != "wheel" or version == "editable":
            return
        pure = os.environ.get(PURE_PYTHON_ENV, "").strip().lower()
        if pure not in _YES + _NO:
            raise ValueError(f"{PURE_PYTHON_ENV}={pure!r}: give 1 (no compiled modules) or 0 (compile them)")
        if pure in _YES:
            self.app.display_warning(f"{PURE_PYTHON_ENV} is set: the wheel carries no compiled modules")
            return
        self._work = Path(tempfile.mkdtemp(prefix="edc-bench-mypyc-"))
        lib = self._work / "lib"
        setup_file = self._work / "setup.py"
        setup_file.write_text(_SETUP.format(paths=[str(Path(self.root) / p) for p in COMPILED]), encoding="utf-8")
        # run where no pyproject.toml is, so setuptools reads only the setup() above
        done = subprocess.run([sys.executable, str(setup_file), "build_ext", "--build-lib", str(lib),
                               "--build-temp", str(self._work / "temp")], cwd=self._work,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if done.returncode != 0:
            shutil.rmtree(self._work, ignore_errors=True)
            raise RuntimeError(
                f"compiling the tick's modules with mypyc failed; it needs a C compiler and Python's headers. The "
                f"end of its output:\n{done.stdout[-4000:]}\nTo install without compiling them (slower simulated "
                f"tests), set {PURE_PYTHON_ENV}=1.")
        for built in sorted(lib.rglob("*")):
            if built.name.endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES)):
                build_data["force_include"][str(built)] = built.relative_to(lib).as_posix()
        build_data["pure_python"] = False
        build_data["infer_tag"] = True

    def finalize(self, version: str, build_data: dict[str, Any], artifact_path: str) -> None:
        """Remove the temporary folder once the wheel holds its files."""
        work = getattr(self, "_work", None)
        if work is not None:
            shutil.rmtree(work, ignore_errors=True)
