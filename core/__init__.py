"""Core of Perceptive HTMPC Studio: robot model, controller, mapping and simulation.

`core` knows no application, task files or benchmarks (docs/design.md, "Layers").
"""
