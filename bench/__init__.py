"""Benchmarks and experiment reproductions; each runs alone as `python -m bench.<name>`.

Conventions: docs/design.md, "Benchmarks".
"""
