"""The benchmarks of the checkout (not part of the installed package): ``benchmarks.bench`` is the resolver
benchmark's harness, driven by ``benchmarks/compare_resolvers.py``."""

import os

# The benchmarks time compiled steps after untimed warm-up steps: the kernels compile in the first step's thread,
# not in redundik's background thread (whose interpreted steps would be timed; redundik._coldstart).
os.environ.setdefault("REDUNDIK_COLD_START", "wait")
