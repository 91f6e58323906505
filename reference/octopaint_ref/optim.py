"""Adam (Kingma and Ba, 2015) on pytrees of arrays: the optimiser of the
differentiable examples (reference/examples/)."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def adam_init(params):
    zeros = jax.tree_util.tree_map(jnp.zeros_like, params)
    return {"m": zeros, "v": zeros, "t": 0}


def adam_step(params, grads, state, lr, b1=0.9, b2=0.999, eps=1e-8):
    """One update; `lr` is a number or a pytree of numbers like params."""
    t = state["t"] + 1
    m = jax.tree_util.tree_map(lambda m, g: b1 * m + (1 - b1) * g, state["m"], grads)
    v = jax.tree_util.tree_map(lambda v, g: b2 * v + (1 - b2) * g * g, state["v"], grads)
    lrs = lr if isinstance(lr, dict) else jax.tree_util.tree_map(lambda _: lr, params)

    def upd(p, m, v, a):
        return p - a * (m / (1 - b1**t)) / (jnp.sqrt(v / (1 - b2**t)) + eps)

    return jax.tree_util.tree_map(upd, params, m, v, lrs), {"m": m, "v": v, "t": t}
