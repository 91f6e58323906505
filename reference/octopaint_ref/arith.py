"""IEEE arithmetic in f16, f32 and f64 under XLA on CPU, rounded after every
operation: the precision parameter of the ray caster (spec 7, precision study).

XLA on CPU is not a faithful IEEE machine for this purpose, and both ways it
departs were measured (tests/test_arith.py keeps them measured):

- it contracts `a*b + c` into a fused multiply-add in f32 and f64, and in
  f16 on some processors (not on an AMD EPYC with AVX-512 BF16, 2026-11-27),
  which skips the rounding of the product;
- `lax.reduce_precision` and f16 arithmetic flush subnormal results to zero.

So f16 and f32 values are carried in f64 and every operation is rounded to
the target format explicitly (`round_to`): normal results by
`lax.reduce_precision`, subnormal ones by scaling to an integer count of the
smallest subnormal and rounding half to even. Computing +, -, *, / or sqrt of
two p-bit operands in f64 and rounding once to p bits is exactly the
correctly rounded p-bit result because 53 >= 2p + 2 (p = 11 for f16, 24 for
f32): double rounding cannot occur (Figueroa, "When is double rounding
innocuous?", 1995). A product fed into the rounding is consumed by integer bit
operations, never by an add, so it cannot be contracted.

f64 values are native (XLA flushes f64 subnormals too; the ray caster's f64
values never come near 2^-1022), and a product is passed through an integer XOR with a
zero that XLA cannot see (`guard`, a traced argument) before it is added: that
is the only construction found that stops the contraction (a select, a bitcast
round trip, `optimization_barrier` and `reduce_precision(11, 52)` all failed).

The Rust and WGSL ports round naturally in their own types; the tests hold
these operations to numpy, whose float16/float32/float64 scalars round once
per operation.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import jax.numpy as jnp
from jax import lax

# f16 and f32 are carried in f64: the package runs with JAX's 64-bit mode on
# (jax_setup.py; whoever runs it turns it on).


@dataclass(frozen=True)
class Format:
    """An IEEE binary format: `name` (f16, f32, f64), exponent and mantissa
    bits, and the exponent of its smallest subnormal."""

    name: str
    exponent_bits: int
    mantissa_bits: int
    min_subnormal_exp: int  # smallest subnormal is 2**min_subnormal_exp
    min_normal_exp: int
    # Native: each operation computed in the format's own type by XLA on
    # the device (whatever it fuses or flushes), not emulated; see NATIVE.
    native: bool = False

    @property
    def eps(self) -> float:
        """Machine epsilon as the paper uses it (spacing at 1): 2^-mantissa."""
        return 2.0**-self.mantissa_bits

    @property
    def numpy_dtype(self):
        import numpy as np

        return {"f16": np.float16, "f32": np.float32, "f64": np.float64}[self.name]


F16 = Format("f16", 5, 10, -24, -14)
F32 = Format("f32", 8, 23, -149, -126)
F64 = Format("f64", 11, 52, -1074, -1022)
FORMATS = {"f16": F16, "f32": F32, "f64": F64}

# The same formats computed natively: operands converted to float16 or
# float32, the operation done in that type by XLA on whatever device runs
# it, the result widened back to the f64 carrier (exactly). This is what a
# GPU's own f16/f32 arithmetic does to the walk: XLA may contract a product
# and a sum into one fused multiply-add and the device may flush subnormals,
# the two departures the emulation exists to avoid. The precision study runs
# both and compares (docs/precision.md, "JAX on CUDA").
NATIVE = {"f16": dataclasses.replace(F16, native=True), "f32": dataclasses.replace(F32, native=True)}


def format_of(precision: str) -> Format:
    """The format a ray caster's `precision` names: f16, f32, f64
    (emulated per operation, f64 native), or f16-native, f32-native."""
    if precision.endswith("-native") and precision[: -len("-native")] in NATIVE:
        return NATIVE[precision[: -len("-native")]]
    if precision not in FORMATS:
        raise ValueError(f"unknown precision {precision!r}: f16, f32, f64, f16-native or f32-native")
    return FORMATS[precision]


def round_to(x, fmt: Format):
    """x (f64) rounded to the nearest value of `fmt`, ties to even, with
    subnormals and overflow to infinity as IEEE has them; f64 unchanged."""
    if fmt.name == "f64":
        return x
    normal = lax.reduce_precision(x, exponent_bits=fmt.exponent_bits, mantissa_bits=fmt.mantissa_bits)
    # Scaling by a power of two is exact; the integer rounding is the one
    # rounding step (jnp.round rounds half to even).
    up = 2.0 ** (-fmt.min_subnormal_exp)
    sub = jnp.round(x * up) * (2.0**fmt.min_subnormal_exp)
    return jnp.where(jnp.abs(x) < 2.0**fmt.min_normal_exp, sub, normal)


class Arith:
    """The five operations of one format on f64-carried values.

    `guard` is a traced uint64 zero (pass `np.uint64(0)` into the jitted
    function): XOR-ing the bits of an f64 product with it keeps XLA from
    fusing the product into a following add. Unused for f16 and f32."""

    def __init__(self, fmt: Format, guard=None):
        self.fmt = fmt
        self.guard = guard

    def rnd(self, x):
        if self.fmt.native:
            return jnp.asarray(x).astype(self._dtype).astype(jnp.float64)
        return round_to(x, self.fmt)

    @property
    def _dtype(self):
        return jnp.float16 if self.fmt.name == "f16" else jnp.float32

    def _native(self, op, *xs):
        """op on the operands in the format's own type, widened back."""
        return op(*(jnp.asarray(x).astype(self._dtype) for x in xs)).astype(jnp.float64)

    def _opaque(self, x):
        if self.fmt.native or self.fmt.name != "f64":
            return self.rnd(x)
        bits = lax.bitcast_convert_type(x, jnp.uint64) ^ self.guard
        return lax.bitcast_convert_type(bits, jnp.float64)

    def add(self, a, b):
        if self.fmt.native:
            return self._native(lambda a, b: a + b, a, b)
        return self.rnd(a + b)

    def sub(self, a, b):
        if self.fmt.native:
            return self._native(lambda a, b: a - b, a, b)
        return self.rnd(a - b)

    def mul(self, a, b):
        if self.fmt.native:
            return self._native(lambda a, b: a * b, a, b)
        return self._opaque(a * b)

    def div(self, a, b):
        if self.fmt.native:
            return self._native(lambda a, b: a / b, a, b)
        return self.rnd(a / b)

    def sqrt(self, a):
        if self.fmt.native:
            return self._native(jnp.sqrt, a)
        return self.rnd(jnp.sqrt(a))
