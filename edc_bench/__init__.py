"""edc-bench: bench diagnosis of worn solenoid valves in P-EDC in-line pumps."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("edc-bench")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"
