#!/usr/bin/env bash
# Command 2 of the README: set up with test needs (Debian chromium, the dev extra) and run every test.
# Two phases: the lockstep tests in parallel (pytest-xdist, TEST_WORKERS processes, default 2; each test goes to the
# next free process, the slowest first as tests/slowest_tests.txt measured them: tests/conftest.py), then the
# tests marked `wallclock` (live loops, a browser, a served bridge) one at a time, so that nothing else competes
# with their clocks. Fails if a test fails or if no test ran. Extra arguments go to
# pytest in both phases.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --dev
.venv/bin/python -m ruff check .
.venv/bin/python -m pyright --pythonpath .venv/bin/python  # [tool.pyright] in pyproject.toml: core/, tasks/, app/

# pytest's exit code 5 is "no test collected": a phase may be empty when arguments pick a few tests.
phase() {
  local name=$1; shift
  set +e
  .venv/bin/python -m pytest -q -ra --junitxml="test-artifacts/junit-$name.xml" "$@"
  local status=$?
  set -e
  if [[ $status != 0 && $status != 5 ]]; then failed=1; fi
  if [[ $status == 5 ]]; then rm -f "test-artifacts/junit-$name.xml"; fi
}

mkdir -p test-artifacts
rm -f test-artifacts/junit-*.xml
failed=0
phase lockstep -m "not wallclock" -n "${TEST_WORKERS:-2}" --dist load "$@"
phase wallclock -m wallclock "$@"

ran=$(.venv/bin/python - <<'PY'
import glob
import xml.etree.ElementTree as E
total = 0
for path in glob.glob("test-artifacts/junit-*.xml"):
    root = E.parse(path).getroot()
    suite = root if root.tag == "testsuite" else root[0]
    total += int(suite.get("tests")) - int(suite.get("skipped"))
print(total)
PY
)
if [[ "$ran" -lt 1 ]]; then echo "[test] no test ran"; exit 1; fi
echo "[test] $ran tests ran"
exit $failed
