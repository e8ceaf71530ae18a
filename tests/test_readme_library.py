"""README's "As a library" script runs as printed: the controller and the object map drive the simulated base
past a box to its goal without the studio, with no contact."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_readme_library_script_runs_to_the_end_without_contact():
    section = (ROOT / "README.md").read_text().split("## As a library", 1)[1].split("\n## ", 1)[0]
    (script,) = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(script.strip().splitlines()) <= 25, "a short script is the point"
    done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert re.search(r"sequence finished \(1 subtask\) after [\d.]+ s, 0 contacts", done.stdout), done.stdout
