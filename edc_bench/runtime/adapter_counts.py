"""What a bus adapter's driver skipped while a test ran, as the record keeps it: one small typed interface."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable


@dataclass(frozen=True)
class AdapterCounts:
    """What the driver skipped (all zero for a bus that keeps no such count, as python-can's own).

    Attributes
    ----------
    bad_lines : int
        Lines from the adapter that were not valid frames, acknowledgements or errors.
    bad_line_samples : tuple of bytes
        The first few of them, for the record.
    device_errors : int
        Error answers of the adapter (slcan's BEL).
    """

    bad_lines: int = 0
    bad_line_samples: tuple[bytes, ...] = ()
    device_errors: int = 0


@runtime_checkable
class CountsAdapterErrors(Protocol):
    """A bus that says what its adapter's driver skipped (:class:`~edc_bench.runtime.bus.BufferedSlcanBus`)."""

    def adapter_counts(self) -> AdapterCounts:
        """What was skipped so far."""
        ...


def adapter_counts(bus: object) -> AdapterCounts:
    """What ``bus``'s driver skipped; zeros for a bus that does not count (:class:`CountsAdapterErrors`)."""
    return bus.adapter_counts() if isinstance(bus, CountsAdapterErrors) else AdapterCounts()
