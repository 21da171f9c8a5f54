"""A chunk's inserted nodes placed among its segment ends by scatter: the order a sort of every
node by (row, parameter along the move, the end last) gives."""
import numpy as np
import pytest

from mtcomp.planner._interleave import placed, positions


@pytest.mark.parametrize("seed, n_rows, n_inner", [(0, 50, 120), (1, 50, 120), (2, 50, 120),
                                                    (3, 3000, 7), (4, 3000, 1), (5, 3000, 0)])
def test_positions_are_the_sorted_order_of_every_node(seed, n_rows, n_inner):
    """Many inserted nodes (placed by one scatter) and few (the ends copied in runs between them)."""
    rng = np.random.default_rng(seed)
    rows = rng.integers(0, n_rows, n_inner)
    t = rng.permutation(rows.size) / (rows.size + 1.0) + 0.5 / (rows.size + 1.0)  # distinct, in (0, 1)
    counts = np.ones(n_rows, np.int64)
    np.add.at(counts, rows, 1)
    pos_end, pos_inner = positions(counts, rows, t)
    # the oracle: every node's (row, t), ends at t = 1, sorted
    all_rows = np.concatenate([rows, np.arange(n_rows)])
    all_t = np.concatenate([t, np.ones(n_rows)])
    order = np.lexsort((all_t, all_rows))
    where = np.empty(order.size, np.int64)
    where[order] = np.arange(order.size)
    np.testing.assert_array_equal(pos_inner, where[:rows.size])
    np.testing.assert_array_equal(pos_end, where[rows.size:])
    ends = rng.normal(size=(n_rows, 3, 2))
    inner = rng.normal(size=(rows.size, 3, 2))
    np.testing.assert_array_equal(placed(ends, inner, pos_end, pos_inner),
                                  np.concatenate([inner, ends])[order])


def test_positions_by_hand():
    # row 0: no inserted node; row 1: two (t 0.75 then 0.25: placed 0.25 first); row 2: one
    counts = np.array([1, 3, 2])
    pos_end, pos_inner = positions(counts, np.array([1, 2, 1]), np.array([0.75, 0.5, 0.25]))
    assert pos_end.tolist() == [0, 3, 5]
    assert pos_inner.tolist() == [2, 4, 1]
