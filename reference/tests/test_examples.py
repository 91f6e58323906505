"""The two differentiable examples run, and their loss falls (a few
iterations on small images; the full runs are in docs/examples)."""

import os
import sys

EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")
sys.path.insert(0, EXAMPLES)

import fit_leaves  # noqa: E402
import inverse_paint  # noqa: E402


def test_fit_leaves_loss_falls(tmp_path):
    losses = fit_leaves.run(iterations=8, out=str(tmp_path), size=(16, 16), log=lambda *a: None)
    assert losses[-1] < 0.5 * losses[0]
    assert sorted(os.listdir(tmp_path)) == ["fit_leaves_after.png", "fit_leaves_before.png", "fit_leaves_target.png"]


def test_inverse_paint_loss_falls(tmp_path):
    losses, fitted = inverse_paint.run(iterations=8, out=str(tmp_path), size=(16, 16), log=lambda *a: None)
    assert losses[-1] < 0.7 * losses[0]
    assert fitted["radius"] > inverse_paint.START["radius"]  # moving towards the target's 0.11
    assert len(os.listdir(tmp_path)) == 3
