"""verify/policy.py on synthetic findings: which refusal stands, when a refused fit is retried, what
``accept_poor_fit`` keeps and says, and the order the warnings come out in."""
from __future__ import annotations

import itertools

import pytest

from handeye_cli.errors import DataError, FitRejectedError
from handeye_cli.verify.policy import (
    REFUSALS,
    RETRY_MAX_RATIO,
    RETRY_MAX_RUN,
    RETRY_MIN_INLIERS,
    WARNING_ORDER,
    Finding,
    policy,
    retry_kept,
)


def _refusal(kind: str) -> Finding:
    error = (FitRejectedError if kind in ("fit", "moved") else DataError)(f"{kind} refused", "test")
    return Finding.refusal(kind, error, f"{kind} evidence")


@pytest.mark.parametrize("kinds", [p for n in (1, 2, 3, 4) for p in itertools.permutations(REFUSALS, n)])
def test_the_first_refusal_in_policy_order_stands_whatever_order_they_were_found(kinds) -> None:
    findings = [Finding.warning("read", "a reader's warning"), *map(_refusal, kinds)]
    outcome = policy(findings, accept_poor_fit=False, robust=False)
    first = min(kinds, key=REFUSALS.index)
    assert outcome.error is not None and outcome.error.what == f"{first} refused"
    assert outcome.retry == (first == "fit")
    assert outcome.accepted == () and outcome.warnings == ()


def test_a_refused_fit_is_not_retried_when_outliers_were_rejected_already() -> None:
    outcome = policy([_refusal("fit")], accept_poor_fit=False, robust=True)
    assert outcome.error is not None and not outcome.retry


def test_accept_poor_fit_keeps_every_refusal_and_says_so_first() -> None:
    findings = [Finding.warning("observability", "obs"), _refusal("moved"), Finding.warning("suspect", "suspect"),
                _refusal("fit"), _refusal("inversion"), _refusal("order"), Finding.warning("read", "read")]
    outcome = policy(findings, accept_poor_fit=True, robust=False)
    assert outcome.error is None and not outcome.retry
    assert outcome.accepted == ("inversion", "order", "fit", "moved")
    # an accepted inversion has no note of its own: its message is the suspect warning that follows
    assert outcome.warnings == ("poor fit accepted with ⟦accept_poor_fit=True⟧: order evidence",
                                "poor fit accepted with ⟦accept_poor_fit=True⟧: fit evidence",
                                "poor fit accepted with ⟦accept_poor_fit=True⟧: moved evidence",
                                "suspect", "read", "obs")


def test_warnings_come_out_in_the_stated_order_stably_within_a_kind() -> None:
    findings = [Finding.warning(kind, f"{kind} {k}") for k in (1, 2) for kind in reversed(WARNING_ORDER)]
    outcome = policy(findings, accept_poor_fit=False, robust=False)
    assert outcome.error is None and outcome.accepted == ()
    assert outcome.warnings == tuple(f"{kind} {k}" for kind in WARNING_ORDER for k in (1, 2))


def test_a_kind_outside_the_policy_is_an_error_not_a_silent_placement() -> None:
    with pytest.raises(ValueError):
        policy([Finding.warning("unheard-of", "x")], accept_poor_fit=False, robust=False)


@pytest.mark.parametrize(("consensus", "run", "ratio", "kept"), [
    (RETRY_MIN_INLIERS, RETRY_MAX_RUN, RETRY_MAX_RATIO, True),        # every bound is inclusive
    (RETRY_MIN_INLIERS - 1e-9, 0.0, 1.0, False),                      # too few samples agree
    (1.0, RETRY_MAX_RUN + 1e-9, 1.0, False),                          # one run disagrees: a sensor moved
    (1.0, 0.0, RETRY_MAX_RATIO * 1.001, False),                       # the inliers still misfit
    (1.0, 0.0, float("nan"), False),                                  # no fit to judge
    (1.0, 0.0, None, False),
])
def test_the_outlier_retry_is_kept_only_within_every_bound(consensus, run, ratio, kept) -> None:
    assert retry_kept(consensus, run, ratio) is kept
