"""When a rig self-check is due: every N tests or hours, and after a NO-GO (pure: the caller gives the time).

A variant's ``[selfcheck]`` section may ask for a self-check every ``every_tests`` tests or every
``every_hours`` hours at a station; a session that tests several variants holds to the strictest of theirs
(:meth:`SelfCheckPolicy.strictest`). Registering the reference valve counts as a check that passed.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

from edc_bench.timefmt import local_text


@dataclass(frozen=True)
class SelfCheckPolicy:
    """How often a station must run the rig self-check.

    Attributes
    ----------
    every_tests : int or None
        At most this many tests between two self-checks (None: no limit).
    every_hours : float or None
        At most this many hours between two self-checks (None: no limit).
    """

    every_tests: int | None = None
    every_hours: float | None = None

    @classmethod
    def of_variant(cls, variant: Any) -> SelfCheckPolicy:
        """The policy a variant's ``[selfcheck]`` section states."""
        section = variant.selfcheck
        return cls(section.every_tests, section.every_hours)

    @classmethod
    def strictest(cls, *policies: SelfCheckPolicy) -> SelfCheckPolicy:
        """The policy that keeps every one of ``policies`` (the fewest tests, the fewest hours)."""
        tests = [p.every_tests for p in policies if p.every_tests is not None]
        hours = [p.every_hours for p in policies if p.every_hours is not None]
        return cls(min(tests) if tests else None, min(hours) if hours else None)


@dataclass(frozen=True)
class LastCheck:
    """The station's latest self-check (or the reference valve's registration, which counts as one that passed).

    Attributes
    ----------
    at : datetime.datetime
        When it ran (time-zone aware, as the history stores it).
    go : bool
        It was GO.
    """

    at: dt.datetime
    go: bool


def selfcheck_due(last_check: LastCheck | None, tests_since: int, now: dt.datetime,
                  policy: SelfCheckPolicy) -> str | None:
    """Whether the rig must run its self-check before the next test, and why.

    Parameters
    ----------
    last_check : LastCheck or None
        The station's latest self-check or registration (None: none on record).
    tests_since : int
        Tests the station ran since it.
    now : datetime.datetime
        The time now (aware, like ``last_check.at``).
    policy : SelfCheckPolicy
        How often checks are required.

    Returns
    -------
    str or None
        None when no check is due; else why, in words for the technician.
    """
    if last_check is not None and not last_check.go:
        return (f"the last rig self-check ({_when(last_check.at)}) was NO-GO: the rig must pass one before it tests "
                "valves")
    if policy.every_tests is None and policy.every_hours is None:
        return None
    if last_check is None:
        return "no rig self-check on record at this station"
    if policy.every_tests is not None and tests_since >= policy.every_tests:
        return (f"{tests_since} tests since the last rig self-check ({_when(last_check.at)}); one is required every "
                f"{policy.every_tests} tests")
    if policy.every_hours is not None:
        hours = (now - last_check.at).total_seconds() / 3600.0
        if hours >= policy.every_hours:
            return (f"{hours:.1f} hours since the last rig self-check ({_when(last_check.at)}); one is required every "
                    f"{policy.every_hours:g} hours")
    return None


def _when(at: dt.datetime) -> str:
    return local_text(at)


__all__ = ["LastCheck", "SelfCheckPolicy", "selfcheck_due"]
