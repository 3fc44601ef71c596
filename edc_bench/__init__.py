"""edc-bench: bench diagnosis of worn solenoid valves in P-EDC in-line pumps."""

import os
from importlib.metadata import PackageNotFoundError, version

# Every matrix here is tiny (5 x 5 at most): BLAS threads only spin. In the process pool of `train` they made
# the batch path 7x slower (1,000 valves: 69 s against 10 s), and in the real-time loop they would take the
# CPU from the tick. Set before numpy is first imported; a value the user set is kept.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

try:
    __version__ = version("edc-bench")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"
