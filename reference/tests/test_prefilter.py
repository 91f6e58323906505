"""Interior values (spec 4.4): the rule on hand-worked units, its agreement
with refinement and coarsening, and the check that catches a stale value."""

import numpy as np
from octopaint_ref.check import check_arrays
from octopaint_ref.dump import tree_arrays
from octopaint_ref.prefilter import prefiltered, stale_cells, unit_value
from octopaint_ref.tree import Tree


def one(rgb, sigma):
    r, s = unit_value(np.array([rgb], np.uint8), np.array([sigma], np.float32))
    return r[0].tolist(), s[0]


def test_eight_equal_children_give_their_own_value():
    for rgb, sigma in [((0, 0, 0), 0.0), ((255, 7, 128), 1e-45), ((1, 2, 3), 3.4028235e38), ((200, 100, 50), 0.37)]:
        r, s = one([rgb] * 8, [sigma] * 8)
        assert r == list(rgb) and s.view(np.uint32) == np.float32(sigma).view(np.uint32)


def test_density_is_the_mean_and_colour_the_density_weighted_mean():
    rgb = [[0, 0, 0]] * 8
    sigma = [0.0] * 8
    rgb[1], sigma[1] = [255, 0, 10], 3.0
    rgb[6], sigma[6] = [0, 255, 20], 1.0
    rgb[0] = [9, 9, 9]  # empty: no weight
    # (3*255)/4 = 191.25; 255/4 = 63.75; (30 + 20)/4 = 12.5 -> 13.
    assert one(rgb, sigma) == ([191, 64, 13], np.float32(0.5))


def test_all_empty_children_give_octant_zeros_colour():
    rgb = [[k * 30, 1, 2] for k in range(8)]
    rgb[0] = [77, 66, 55]
    assert one(rgb, [0.0] * 8) == ([77, 66, 55], np.float32(0.0))


def painted_tree():
    """Roots 2x1x1, two levels refined under root 0, uneven values."""
    t = Tree((2, 1, 1), max_depth=4, capacity=1 << 12)
    (u,), _ = t.refine_round([0])
    t.refine_round([u + 3])
    n = t.n_used
    live = np.nonzero((t.depth[:n] != 255) & (t.first_child[:n] == 0xFFFFFFFF))[0]
    t.sigma[live] = (np.arange(len(live)) % 5).astype(np.float32) * np.float32(0.3)
    t.rgb[live] = np.stack([live * 7 % 256, live * 13 % 256, live * 29 % 256], 1).astype(np.uint8)
    return t


def test_a_parent_holds_the_prefilter_of_its_children_computed_first():
    t = painted_tree()
    a = tree_arrays(t)
    assert not check_arrays(a)
    # Root 0's value comes from its children, one of which (u + 3) has
    # children of its own whose prefilter it holds.
    fc0 = int(a["first_child"][0])
    kids = np.arange(fc0, fc0 + 8)
    r, s = unit_value(a["rgb"][kids][None], a["sigma"][kids][None])
    assert a["rgb"][0].tolist() == r[0].tolist() and a["sigma"][0] == s[0]
    fc3 = int(a["first_child"][fc0 + 3])
    r3, s3 = unit_value(a["rgb"][fc3 : fc3 + 8][None], a["sigma"][fc3 : fc3 + 8][None])
    assert a["rgb"][fc0 + 3].tolist() == r3[0].tolist() and a["sigma"][fc0 + 3] == s3[0]
    # Leaves keep their own values.
    leaf = (a["first_child"] == 0xFFFFFFFF) & (a["depth"] != 255)
    assert np.array_equal(a["rgb"][leaf], t.rgb[: t.n_used][leaf]) and np.array_equal(a["sigma"][leaf], t.sigma[: t.n_used][leaf])


def test_the_check_names_an_interior_cell_whose_value_is_stale():
    a = tree_arrays(painted_tree())
    a["sigma"] = a["sigma"].copy()
    a["sigma"][0] = np.nextafter(a["sigma"][0], np.float32(np.inf))
    problems = check_arrays(a)
    assert len(problems) == 1 and "prefilter" in problems[0] and ": 0" in problems[0]
    assert stale_cells(a["first_child"], a["depth"], a["rgb"], a["sigma"]).tolist() == [c == 0 for c in range(len(a["sigma"]))]


def test_refinement_and_collapse_keep_the_values():
    t = painted_tree()
    before = tree_arrays(t)
    # Refining a leaf: its children copy it, and its value stays its own.
    leaf = int(np.nonzero((t.depth[: t.n_used] == 2) & (t.sigma[: t.n_used] > 0))[0][0])
    t.refine_round([leaf])
    after = tree_arrays(t)
    n = len(before["sigma"])
    assert np.array_equal(after["rgb"][:n], before["rgb"][:n]) and np.array_equal(after["sigma"][:n], before["sigma"][:n])
    rgb, sigma = prefiltered(t.first_child[: t.n_used], t.depth[: t.n_used], t.rgb[: t.n_used], t.sigma[: t.n_used])
    assert rgb[leaf].tolist() == t.rgb[leaf].tolist() and sigma[leaf] == t.sigma[leaf]
