"""Where the experiments live on disk: the repository's root (their commit is read there) and the reports folder."""

from pathlib import Path

ROOT = Path(__file__).parents[2]
REPORTS_DIR = ROOT / "reports"
