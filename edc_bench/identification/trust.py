"""The one rule for trusting a test, vectorised: it serves one test (the judgement), the early stop's check
after each period, and 10,000 simulated tests of the batch path alike.

A test is trusted when nothing in :class:`Problem` holds for it. The rule
takes arrays (one entry per test; scalars broadcast) and gives each test's
problems as bits, so code branches on the bits and the judgement turns
them into sentences (:func:`edc_bench.verdict.judgement.trust_reasons`).

The excitation's conditioning is part of the rule, defined once
(:func:`judged_condition_number`): the larger of the reference's own
regressors' (a property of the excitation: identifiability is decided by
what the reference makes the plant do) and the period fit's.
"""

from __future__ import annotations

import numpy as np

from edc_bench.config.models import AcceptanceSection
from edc_bench.engine.problems import Problem


#: The trust rule's problems: a test with none of them is trusted.
TRUST_PROBLEMS = (Problem.ABORTED | Problem.NOT_IDENTIFIED | Problem.MODEL_DOES_NOT_FIT | Problem.TOO_FEW_PERIODS
                  | Problem.DRIFTING | Problem.POORLY_CONDITIONED | Problem.TIMING | Problem.REPLIES_MISSING)


def judged_condition_number(excitation_condition: float, fit_condition: np.ndarray | float) -> np.ndarray:
    """The condition number the trust rule judges: the excitation's, or the period fit's where that is worse."""
    return np.maximum(excitation_condition, np.asarray(fit_condition, dtype=float))


def trust_problems(acceptance: AcceptanceSection, *, periods: np.ndarray | int, settled: np.ndarray | bool,
                   misfit: np.ndarray | bool, condition_number: np.ndarray | float,
                   aborted: np.ndarray | bool = False, ticks: np.ndarray | int = 1,
                   ticks_late_or_lost: np.ndarray | int = 0, missed_replies: np.ndarray | int = 0,
                   stalls_cost_rows: bool = True) -> np.ndarray:
    """Each test's problems under the trust rule, as :class:`Problem` bits (an int array; 0: trusted).

    Parameters
    ----------
    acceptance : AcceptanceSection
        The variant's limits.
    periods : int or numpy.ndarray
        Whole excitation periods the fit used.
    settled : bool or numpy.ndarray
        af and a1 settled (the halves of the periods agree).
    misfit : bool or numpy.ndarray
        A model-fit measure is beyond its limit (judged only with enough periods).
    condition_number : float or numpy.ndarray
        :func:`judged_condition_number`.
    aborted : bool or numpy.ndarray, optional
        The loop was cut short.
    ticks, ticks_late_or_lost, missed_replies : int or numpy.ndarray, optional
        Ticks that ran; those late or lost to host stalls; commands whose replies never came in time. Ticks lost
        beyond ``max_overrun_fraction`` make a test INVALID for its timing only where what the fit kept (it leaves
        out every row a stall touched) is not trusted, or the test was cut short: the PC is then named.
    stalls_cost_rows : bool, optional
        False: the rule before record schema 9, where ticks lost beyond the limit made any test INVALID (a record
        of that time is checked by the rule it was decided by).

    Notes
    -----
    An aborted test is judged only on its abort, timing and replies (what it identified before the abort is not
    evidence); a model that does not fit is named instead of 'not converged' (a longer test will not help).
    """
    periods = np.asarray(periods)
    aborted = np.asarray(aborted, dtype=bool)
    enough = periods >= acceptance.min_periods
    misfit = enough & np.asarray(misfit, dtype=bool) & ~aborted
    unsettled = ~aborted & ~misfit & ~(enough & np.asarray(settled, dtype=bool))
    ticks = np.maximum(np.asarray(ticks), 1)
    poorly = ~aborted & ~(np.asarray(condition_number, dtype=float) <= acceptance.max_condition_number)
    # a host stall costs the rows it touched, not the test: the fit leaves them out (period_fit.rows), so what
    # remains decides, and a PC that lost ticks still gets a verdict; past the limit the PC is named for a test
    # whose remaining rows did not give a trusted fit (or that was cut short)
    disturbed = np.asarray(ticks_late_or_lost) / ticks > acceptance.max_overrun_fraction
    found = (
        (aborted, Problem.ABORTED),
        (misfit, Problem.MODEL_DOES_NOT_FIT),
        (unsettled & ~enough, Problem.TOO_FEW_PERIODS),
        (unsettled & enough, Problem.DRIFTING),
        (poorly, Problem.POORLY_CONDITIONED),
        (disturbed & (aborted | misfit | unsettled | poorly) if stalls_cost_rows else disturbed, Problem.TIMING),
        (np.asarray(missed_replies) / ticks > acceptance.max_missed_reply_fraction, Problem.REPLIES_MISSING),
    )
    flags = np.zeros(np.broadcast_shapes(*(np.shape(bits) for bits, _ in found)), dtype=np.int64)
    for bits, problem in found:
        flags |= np.where(bits, int(problem), 0)
    return flags


__all__ = ["TRUST_PROBLEMS", "Problem", "judged_condition_number", "trust_problems"]
