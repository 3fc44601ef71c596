"""edc-bench: bench diagnosis of worn solenoid valves in P-EDC in-line pumps."""

import os

#: The package's version; the one place it is written (pyproject.toml reads it from here: reading it back from the
#: installed metadata cost every command's start-up the import of importlib.metadata).
__version__ = "0.1.0"

# Every matrix here is tiny (5 x 5 at most): BLAS threads only spin. In the process pool of `train` they made
# the batch path several times slower, and in the real-time loop they would take the CPU from the tick. Set
# before numpy is first imported; a value the user set is kept.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
