"""The benchmarks of the checkout (not part of the installed package): ``benchmarks.bench`` is the resolver
benchmark's harness, driven by ``benchmarks/compare_resolvers.py``."""
