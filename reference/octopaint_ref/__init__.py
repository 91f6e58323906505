"""octopaint_ref: the Python/JAX reference implementation of Octopaint.

The oracle the Rust painter is checked against: the dynamic deep octree, the
brushes, tree dumps and a differentiable ray caster. Rules:
docs/spec.md.
"""

__version__ = "0.1.0"
