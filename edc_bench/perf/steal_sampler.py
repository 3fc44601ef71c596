"""Print ``perf_counter_ns steal_s`` every N seconds until terminated (run as a child process).

Kept to the standard library, so it starts in a few tens of milliseconds
and takes no CPU worth mentioning from the loop it watches.
"""

from __future__ import annotations

import os
import sys
import time


def main(every_s: float) -> None:
    """Sample until killed."""
    ticks_per_s = os.sysconf("SC_CLK_TCK")
    print("started", flush=True)
    while True:
        with open("/proc/stat", encoding="ascii") as stat:
            fields = stat.readline().split()
        steal = int(fields[8]) / ticks_per_s if len(fields) > 8 else 0.0
        print(time.perf_counter_ns(), steal, flush=True)
        time.sleep(every_s)


if __name__ == "__main__":
    try:
        main(float(sys.argv[1]) if len(sys.argv) > 1 else 0.02)
    except (KeyboardInterrupt, BrokenPipeError):
        pass
