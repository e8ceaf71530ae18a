"""Reproductions of the paper's four experiments in simulation (issue 8), each runnable alone:

    python -m bench.experiments.e1_object_vs_voxel [--quick] [--workers N] [--ray ADDRESS]
    python -m bench.experiments.e2_cbf_vs_edf
    python -m bench.experiments.e3_reactive
    python -m bench.experiments.e4_long_term

Each writes `reports/<experiment>/` (JSON, PNG figures, a markdown report with the paper's figures
beside ours). The trial machinery (process pool or Ray, progress bar) is in `trials.py`.
"""
