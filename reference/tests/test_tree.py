"""Pools, allocator, balance, g3 and the neighbour mask."""

import numpy as np
import pytest
from octopaint_ref.check import check_arrays
from octopaint_ref.clean import clean
from octopaint_ref.dump import tree_arrays
from octopaint_ref.g3 import NONE, g3_brute_force, g3_from_links
from octopaint_ref.noise import hash32
from octopaint_ref.tree import Tree


def valid(tree):
    problems = check_arrays(tree_arrays(tree)) + tree.check_allocator()
    assert not problems, problems


def test_allocator_index_sequence_known_case():
    # Roots 3x1x1: 3 roots padded to 8, so the first unit is 8.
    t = Tree((3, 1, 1), max_depth=4, capacity=1 << 12)
    u, _ = t.refine_round([0])
    assert list(u) == [8]
    # Cell 9 (octant 1, high x) touches root 1 across +x: root 1 is refined
    # first (unit 16), then 9 (24); cell 12 (octant 4) touches nothing coarser.
    u, _ = t.refine_round([12, 9])
    assert list(u) == [16, 24, 32]
    assert (t.first_child[1], t.first_child[9], t.first_child[12]) == (16, 24, 32)
    # Collapse cell 12's children (unit 32, the last): the used length shrinks.
    t.coarsen(np.array([12]))
    assert t.n_used == 32 and len(t.free_units) == 0
    # Collapse 9's children (unit 24): now the lowest free unit, reused
    # before the pool grows.
    t.coarsen(np.array([9]))
    assert t.n_used == 24 and len(t.free_units) == 0  # 24 was last: trimmed too
    u, _ = t.refine_round([10, 11])  # 10: no coarser neighbour; 11 touches root 1's children (same depth)
    assert list(u) == [24, 32]
    t.coarsen(np.array([10]))
    assert list(t.free_units) == [24] and t.n_used == 40
    # Cell 17 (root 1's octant 1) touches root 2 across +x: root 2 takes the
    # free unit 24, then 17 grows the pool.
    u, _ = t.refine_round([17])
    assert list(u) == [24, 40] and t.first_child[2] == 24 and t.first_child[17] == 40
    valid(t)


def test_balance_refines_coarser_neighbours_first_in_face_order():
    t = Tree((2, 1, 1), max_depth=5, capacity=1 << 12)
    t.refine_round([0])  # unit 8: children of root 0
    # Child of root 0 at octant 1 (high x) touches root 1 across +x: refining
    # it to depth 2 must first refine root 1 (depth 0 < 1).
    c = 8 + 1
    units, _ = t.refine_round([c])
    assert list(units) == [16, 24]  # root 1 first (gets 16), then the cell
    assert t.first_child[1] == 16 and t.first_child[c] == 24
    valid(t)


def test_capacity_refuses_and_keeps_the_tree_valid():
    t = Tree((1, 1, 1), max_depth=8, capacity=32)  # roots unit + 3 units
    t.refine_round([0])
    units, refused = t.refine_round(list(range(8, 16)))
    assert refused and len(units) == 2  # only 2 units left
    assert list(units) == [16, 24]
    assert t.available_units() == 0
    units, refused = t.refine_round([16])
    assert refused and len(units) == 0
    valid(t)


def _random_tree(seed: int, steps: int = 60) -> Tree:
    t = Tree((2, 2, 1), max_depth=7, capacity=1 << 16)
    for i in range(steps):
        leaves = t.leaves()
        pick = leaves[hash32(seed * 1000 + i) % len(leaves)]
        if t.depth[pick] < t.max_depth:
            t.refine_round([pick])
        if i % 7 == 6:  # coarsen something where allowed
            inner = np.nonzero((t.depth[: t.n_used] != 255) & (t.first_child[: t.n_used] != NONE))[0]
            ok = inner[t.mergeable(inner) & t.balance_allows_coarsen(inner)] if len(inner) else inner
            # mergeable() needs equal values: every cell is still empty here
            if len(ok):
                t.coarsen(ok[:1])
    return t


@pytest.mark.parametrize("seed", range(6))
def test_g3_from_links_equals_brute_force_on_random_trees(seed):
    t = _random_tree(seed)
    n = t.n_used
    a = g3_from_links(t.parent[:n], t.first_child[:n], t.depth[:n], t.roots)
    b = g3_brute_force(t.parent[:n], t.first_child[:n], t.depth[:n], t.origin[:n], t.roots, t.max_depth)
    assert np.array_equal(a, b)
    valid(t)


def test_g3_outward_faces_and_boundaries():
    t = Tree((1, 1, 1), max_depth=3, capacity=1 << 10)
    t.refine_round([0])  # children 8..15
    t.refine_round([8])  # children of octant 0 (low corner): 16..23, refines nothing else
    g3 = g3_from_links(t.parent[: t.n_used], t.first_child[: t.n_used], t.depth[: t.n_used], t.roots)
    # Children of the single root: outward faces are the canvas boundary.
    assert np.all(g3[8:16] == NONE)
    # Cell 16+7 (octant 7 of cell 8): outward faces +x,+y,+z point into
    # cells 9, 10, 12 (siblings of 8, same depth as 8: coarser than 23).
    assert list(g3[23]) == [9, 10, 12]
    assert np.all(g3[:8] == NONE)


def test_dirty_cells_cover_every_g3_change():
    t = Tree((2, 2, 2), max_depth=6, capacity=1 << 16)
    for i in range(40):
        n = t.n_used
        before = g3_from_links(t.parent[:n], t.first_child[:n], t.depth[:n], t.roots)
        leaves = t.leaves()
        pick = leaves[hash32(i + 77) % len(leaves)]
        if i % 5 == 4:
            inner = np.nonzero((t.depth[:n] != 255) & (t.first_child[:n] != NONE))[0]
            ok = inner[t.mergeable(inner) & t.balance_allows_coarsen(inner)]
            if len(ok):
                t.coarsen(ok[-1:])
        elif t.depth[pick] < t.max_depth:
            t.refine_round([pick])
        m = t.n_used
        after = g3_from_links(t.parent[:m], t.first_child[:m], t.depth[:m], t.roots)
        k = max(n, m)
        pad = lambda g: np.vstack([g, np.full((k - len(g), 3), NONE, np.uint32)])  # noqa: B023 (called in this iteration only)
        changed = set(np.nonzero(np.any(pad(before) != pad(after), axis=1))[0].tolist())
        dirty = set(t.take_dirty().tolist())
        assert changed <= dirty, sorted(changed - dirty)[:10]
    # The mask has one bit per region of ceil(capacity / 2048) cells.
    bits = t.dirty_regions(np.array([0, 31, 32, 65535]))
    assert bits.shape == (32, 64) and bits.sum() == 3 and bits[0, 0] and bits[0, 1] and bits[31, 63]


def test_leaf_at_and_cell_at():
    t = Tree((2, 1, 1), max_depth=4, root_size=2.0, capacity=1 << 10)
    t.refine_round([1])
    c = t.leaf_at([3.9, 0.1, 1.9])  # root 1 spans x in [2, 4): high x, low y, high z
    assert t.parent[c] == 1 and c - t.first_child[1] == 1 | 4
    assert t.leaf_at([4.0, 0.5, 0.5]) is None and t.leaf_at([-1e-300, 0.5, 0.5]) is None


def test_clean_collapses_to_the_fixpoint():
    t = Tree((1, 1, 1), max_depth=5, capacity=1 << 12)
    t.refine_round([0])
    t.refine_round([8])
    t.refine_round([16])
    t.sigma[24:32] = 0.5  # one identical unit deep down
    t.rgb[24:32] = (10, 20, 30)
    n = clean(t, np.arange(8, t.n_used))
    # Unit 24 is identical and collapses into 16, which then differs from its
    # empty siblings: the cleaning stops there.
    assert n == 1 and t.first_child[16] == NONE and t.first_child[8] == 16
    assert tuple(t.rgb[16]) == (10, 20, 30) and t.sigma[16] == np.float32(0.5)
    valid(t)
    # Erase it: now every level is empty and the tree collapses to the root.
    t.sigma[16] = 0
    n = clean(t, np.array([16]))
    assert n == 2 and t.first_child[0] == NONE and t.n_used == 8
    valid(t)
