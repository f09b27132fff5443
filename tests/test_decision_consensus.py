"""The consensus's independent count B_m: champions whose windows share no scan."""

import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st


def _brute_disjoint(members, start, end):
    """Largest set of member windows that pairwise share no sample (exhaustive)."""
    import itertools

    idx = [k for k in range(len(start)) if members[k]]
    best = 0
    for r in range(1, len(idx) + 1):
        for sub in itertools.combinations(idx, r):
            if all(start[b] > end[a] for a, b in zip(sub, sub[1:], strict=False)):
                best = max(best, r)
    return best


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.booleans(), min_size=1, max_size=9),
    st.integers(2, 12),
    st.integers(4, 40),
)
def test_independent_count_is_the_largest_scan_disjoint_set(members, step, length):
    """Proposition 1's independence by construction: B_m counts champions whose windows share
    no scan, and is the largest such set (windows = intervals, equally spaced like the
    sliding windows)."""
    from mfcl_jax.decision.consensus import disjoint_count

    k = len(members)
    start = np.arange(k) * step
    end = start + length - 1
    got = int(disjoint_count(jnp.asarray([members]), jnp.asarray(start), jnp.asarray(end))[0])
    assert got == _brute_disjoint(members, start, end)


def test_three_overlapping_windows_are_one_vote():
    """d_s = 6 m, step 2 m, 0.25 m keyframes: window k holds keyframes 8k .. 8k + 24, so
    windows k .. k + 3 share scans (k + 3 starts on k's last scan) and k + 4 does not."""
    from mfcl_jax.decision.consensus import disjoint_count

    start = np.arange(10) * 8
    end = start + 24
    one = np.zeros((1, 10), bool)
    one[0, [2, 3, 4]] = True
    assert int(disjoint_count(jnp.asarray(one), start, end)[0]) == 1
    assert int(disjoint_count(jnp.ones((1, 10), bool), start, end)[0]) == 3  # 0, 4, 8
