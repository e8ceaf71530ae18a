"""Benchmarks and experiment reproductions; each runs alone as `python -m bench.<name>` (BENCH.md)."""
