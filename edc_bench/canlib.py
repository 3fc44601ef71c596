"""python-can for the whole package, imported without its MF4 support until something needs it.

``import can`` imports python-can's MF4 reader and writer, and with them
asammdf and pandas: the largest part of a test's start, paid before its
first tick although no bench test reads or writes MF4 through python-can. Every module of edc-bench takes python-can from here
(``from edc_bench.canlib import can``); the first import keeps asammdf out
of python-can's reach, so python-can's MF4 classes are disabled, and
:func:`mf4_module` brings them back (the module reloaded with asammdf) for
the two things that need them: reading a CAN log in MF4 and the trace's
bus-logging channels. A process where python-can was imported first by
someone else simply has MF4 support from the start.
"""

from __future__ import annotations

import importlib
import sys
from types import ModuleType


def _import_can_without_mf4() -> ModuleType:
    if "can" in sys.modules:
        return sys.modules["can"]
    blocked = "asammdf" not in sys.modules
    if blocked:
        sys.modules["asammdf"] = None  # type: ignore[assignment]  # `import asammdf` raises ImportError
    try:
        import can
    finally:
        if blocked and sys.modules.get("asammdf", ...) is None:
            del sys.modules["asammdf"]
    return can


can = _import_can_without_mf4()


def mf4_module() -> ModuleType:
    """python-can's ``can.io.mf4`` with asammdf loaded, its reader and writer registered for ``.mf4`` files.

    Raises
    ------
    ImportError
        If asammdf is not installed.
    """
    import can.io.logger
    import can.io.mf4
    import can.io.player

    module = can.io.mf4
    if module.asammdf is None:
        import asammdf  # noqa: F401 - raises ImportError here, where it is clear, if asammdf is missing

        module = importlib.reload(can.io.mf4)
        can.io.player.MESSAGE_READERS[".mf4"] = module.MF4Reader
        can.io.logger.MESSAGE_WRITERS[".mf4"] = module.MF4Writer
        for namespace in (can, can.io):
            namespace.MF4Reader, namespace.MF4Writer = module.MF4Reader, module.MF4Writer
    return module


__all__ = ["can", "mf4_module"]
