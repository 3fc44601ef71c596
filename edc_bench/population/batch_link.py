"""The CAN adapter between bench and rig, vectorised across the batch path's valves.

The loop sends tick k's command at t_k = k T. Through an adapter
(:class:`~edc_bench.sim.adapter.AdapterModel`) it reaches the rig later, at
a_k; the rig then samples the rack and applies the new drive, mid-period; the
reply reaches the bench at b_k and is first used at tick ceil(b_k / T) if it
is then no older than the loop's maximum reply age; as in
:class:`~edc_bench.control.fel.FelController`, the PID's error is the mean
over the samples that came since the last tick, each against the reference
at its own command's tick. :class:`BatchLink` keeps
this bookkeeping for N valves at once, each with its own jitter stream and its
own USB frame phase (a bench PC's is arbitrary, so a population meets every
phase); the plant is advanced between deliveries in quanta of T/10, the
batch path's finest step, so a drive takes effect within 0.05 ms of when the
in-process rig applies it.

Pure numpy, no bus and no clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from edc_bench.population.valve_axis import take_last_axis
from edc_bench.sim.adapter import AdapterModel

#: Commands (and replies) that may be in flight at once, per valve.
RING = 64
JITTER_BLOCK = 1000  # jitter draws per valve made at a time


class BatchLink:
    """Deliveries of commands and replies through one adapter model, per valve.

    Parameters
    ----------
    adapter : AdapterModel
        The adapter's timing (the same for every valve).
    seeds : sequence of int
        One per valve: seeds its jitter and its USB frame phase.
    period_s : float
        The loop's tick period.
    quanta_per_period : int
        The plant's finest steps per period; deliveries are rounded to them.
    max_age_ticks : int
        The oldest sample the loop may use (:func:`~edc_bench.engine.replies.max_reply_age_ticks`).
    reference_mm : callable
        ``reference_mm(ticks, valves)``: the reference at each tick's start (r(0) for tick -1), per valve.
    """

    def __init__(self, adapter: AdapterModel, seeds: Sequence[int], period_s: float, quanta_per_period: int,
                 max_age_ticks: int, reference_mm: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> None:
        if adapter.worst_round_trip_s >= (RING - 2) * period_s:
            raise ValueError(f"adapter {adapter.name}: a round trip of {adapter.worst_round_trip_s * 1e3:g} ms is "
                             f"beyond the batch path's {RING - 2} ticks in flight")
        n = len(seeds)
        self.adapter, self.period_s, self.quanta = adapter, period_s, quanta_per_period
        self.quantum_s = period_s / quanta_per_period
        self.max_age_ticks = max_age_ticks
        self._rngs = [np.random.default_rng([s, 0xADA]) for s in seeds]
        self._phase_s = np.array([r.random() * adapter.usb_frame_s for r in self._rngs])
        self._frame_s = adapter.usb_frame_s * (1.0 + 1e-6 * adapter.usb_drift_ppm)
        # each valve's jitter draws, a block at a time, and the next to use per valve (none drawn yet)
        self._jitter = np.zeros((JITTER_BLOCK, n))
        self._jitter_row = np.full(n, JITTER_BLOCK, dtype=np.int64)
        self._cols = np.arange(n)
        self._last_down = np.full(n, -math.inf)
        self._last_up = np.full(n, -math.inf)
        # per command j (ring slot j % RING): delivery time at the rig, its quantum, drive, noise, sample, use tick
        self._down_s = np.zeros((RING, n))
        self._down_q = np.zeros((RING, n), dtype=np.int64)
        self._drive = np.zeros((RING, n))
        self._noise = np.zeros((RING, n))
        self._sample = np.zeros((RING, n))
        self._use_tick = np.zeros((RING, n), dtype=np.int64)
        self._next_delivery = np.zeros(n, dtype=np.int64)  # oldest command not yet at the rig
        self._next_reply = np.zeros(n, dtype=np.int64)  # oldest reply not yet at the bench
        self._reference_mm = reference_mm
        self.newest_tick = np.full(n, -1, dtype=np.int64)  # the sync sample answers tick -1
        # errors of the samples come since the last tick: the sync sample's is 0 (the reference starts there)
        self._error_sum = np.zeros(n)
        self._errors = np.ones(n)
        self.applied_v = np.zeros(n)  # the drive the rig holds now
        self.ages: dict[int, int] = {}

    def take(self, keep: np.ndarray) -> None:
        """Keep the valves ``keep`` (indices) only: the others' tests have stopped."""
        self._rngs = [self._rngs[j] for j in keep]
        take_last_axis(self, keep, ("_phase_s", "_jitter", "_jitter_row", "_last_down", "_last_up", "_down_s", "_down_q", "_drive",
                                    "_noise", "_sample", "_use_tick", "_next_delivery", "_next_reply", "newest_tick",
                                    "_error_sum", "_errors", "applied_v"))
        self._cols = np.arange(len(keep))

    def _jitter_s(self, idx: np.ndarray) -> np.ndarray | float:
        """The next uniform jitter draw of each of the valves ``idx``, from each valve's own stream: a valve's
        draws do not depend on which other valves share its batch (or have left it)."""
        if self.adapter.jitter_s <= 0.0:
            return 0.0
        used_up = idx[self._jitter_row[idx] >= JITTER_BLOCK]
        for j in used_up.tolist():
            self._jitter[:, j] = self._rngs[j].random(JITTER_BLOCK) * self.adapter.jitter_s
        self._jitter_row[used_up] = 0
        draws = self._jitter[self._jitter_row[idx], idx]
        self._jitter_row[idx] += 1
        return draws

    def _deliver(self, idx: np.ndarray, sent_s: np.ndarray, previous_s: np.ndarray) -> np.ndarray:
        """Frames of valves ``idx`` sent at ``sent_s``: when they come out, by :meth:`AdapterModel.release_s`."""
        return self.adapter.release_s(sent_s, self._jitter_s(idx), previous_s, self._phase_s[idx])

    def fresh_error(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Before tick ``k``, per valve: the mean error of the samples that came since the last tick, whether
        any came, and whether the newest sample is young enough for its error to be used again."""
        max_age = self.max_age_ticks
        while True:
            j = self._next_reply
            slot = j % RING
            arrived = (j < self._next_delivery) & (self._use_tick[slot, self._cols] <= k)
            if not arrived.any():
                break
            idx = np.nonzero(arrived)[0]
            jj, ss = j[idx], slot[idx]
            ages = self._use_tick[ss, idx] - jj
            for age in ages.tolist():
                self.ages[age] = self.ages.get(age, 0) + 1
            young = (k - jj) <= max_age  # a reply older than that is never used
            use, ju, su = idx[young], jj[young], ss[young]
            self.newest_tick[use] = np.maximum(self.newest_tick[use], ju)
            self._error_sum[use] += self._reference_mm(ju, use) - self._sample[su, use]
            self._errors[use] += 1
            self._next_reply[idx] += 1
        fresh = self._errors > 0
        error = self._error_sum / np.maximum(self._errors, 1)
        self._error_sum[:] = 0.0
        self._errors[:] = 0
        return error, fresh, (k - self.newest_tick) <= max_age

    def delivered_sample(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """The rack sampled when command ``j`` reached each valve's rig, and whether it has (``j`` must be one of
        the last ``RING - 2`` commands sent)."""
        return self._sample[j % RING].copy(), j < self._next_delivery

    def send(self, k: int, drive_v: np.ndarray, noise_mm: np.ndarray) -> None:
        """Tick ``k``'s command leaves the bench; ``noise_mm`` is the LVDT noise of the sample it will bring back."""
        slot = k % RING
        down = self._deliver(self._cols, np.full(len(self._cols), k * self.period_s), self._last_down)
        self._last_down = down
        self._down_s[slot] = down
        self._down_q[slot] = np.rint(down / self.quantum_s).astype(np.int64)
        self._drive[slot] = drive_v
        self._noise[slot] = noise_mm

    def advance_period(self, k: int, advance: Callable[[np.ndarray, np.ndarray], None],
                       position_mm: Callable[[], np.ndarray],
                       read: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]) -> None:
        """Let period k pass: each command due in it reaches the rig, which samples and applies its drive.

        Parameters
        ----------
        k : int
            The period [t_k, t_k+1).
        advance : callable
            ``advance(quanta, drive_v)`` moves each valve's plant on by its number of quanta under its drive.
        position_mm : callable
            The plants' true rack positions now.
        read : callable
            ``read(true_mm, noise_mm, valves)``: the LVDT reading of those valves.
        """
        first, end = k * self.quanta, (k + 1) * self.quanta
        done = np.full(len(self._cols), first, dtype=np.int64)
        while True:
            j = self._next_delivery
            slot = j % RING
            q = self._down_q[slot, self._cols]
            due = (j <= k) & (q < end)
            target = np.where(due, np.maximum(q, done), end)
            steps = target - done
            if steps.any():
                advance(steps, self.applied_v)
            done = target
            if not due.any():
                return
            idx = np.nonzero(due)[0]
            ss = slot[idx]
            # the rig samples the rack, then applies the new drive; its reply starts back at once
            self._sample[ss, idx] = read(position_mm()[idx], self._noise[ss, idx], idx)
            self.applied_v[idx] = self._drive[ss, idx]
            up = self._deliver(idx, self._down_s[ss, idx], self._last_up[idx])
            self._last_up[idx] = up
            self._use_tick[ss, idx] = np.ceil(up / self.period_s - 1e-9).astype(np.int64)
            self._next_delivery[idx] += 1
