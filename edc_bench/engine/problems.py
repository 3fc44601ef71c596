"""What stands between a test and a verdict, as bits: the trust rule's problems and the verdict's own.

A leaf (no imports from edc_bench): the trust rule (:mod:`edc_bench.identification.trust`) sets them, the
judgement turns them into sentences, the record keeps their names, and the technician's advice
(:mod:`edc_bench.records.advice`) is chosen by them.
"""

from __future__ import annotations

import enum


class Problem(enum.IntFlag):
    """What stands between a test and a verdict on the valve's wear. The first eight are the trust rule's."""

    NONE = 0
    #: the loop was cut short (the abort says why)
    ABORTED = enum.auto()
    #: nothing was identified (the test ended before its first tick)
    NOT_IDENTIFIED = enum.auto()
    #: the feedforward model does not fit the pump (a longer test will not help)
    MODEL_DOES_NOT_FIT = enum.auto()
    #: fewer whole excitation periods than the variant needs
    TOO_FEW_PERIODS = enum.auto()
    #: af and a1 still drifting between the first and second half of the periods
    DRIFTING = enum.auto()
    #: the excitation does not make af and a1 identifiable
    POORLY_CONDITIONED = enum.auto()
    #: many ticks late or lost to host stalls, and what the fit kept of the test not trusted (or the test cut short)
    TIMING = enum.auto()
    #: too many replies missing
    REPLIES_MISSING = enum.auto()
    #: the variant has no measured new-valve baseline to judge against (not a trust problem: the verdict's)
    NOT_CALIBRATED = enum.auto()
    #: the coil's resistance is out of its spec (not a trust problem: the valve FAILs whatever its wear)
    COIL_OUT_OF_SPEC = enum.auto()
    #: the PC stalled right before an abort a stall of the bench causes (the rig's watchdog, replies missing): the
    #: PC, not the rig or the bus, is what to check (not a trust problem: the abort is)
    PC_STALLED = enum.auto()
    #: the pump's control rack binds or its rack-travel sensor misreads (the part diagnosis,
    #: :mod:`edc_bench.verdict.part`): the valve's figures are biased and it is not judged (not a trust problem: the
    #: test itself ran as it should)
    PUMP_FAULT = enum.auto()

    @property
    def names(self) -> list[str]:
        """The problems set, by name, lowercase with spaces (the record's ``problems``)."""
        return [p.name.lower().replace("_", " ") for p in Problem if p and p in self]

    @classmethod
    def from_names(cls, names: list[str]) -> Problem:
        """The problems a record lists (:attr:`names`)."""
        out = cls.NONE
        for name in names:
            out |= cls[name.upper().replace(" ", "_")]
        return out
