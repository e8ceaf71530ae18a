#!/usr/bin/env bash
# Command 2 of the README: set up with test needs (Debian chromium, the dev extra) and run every test.
# Fails if a test fails or if no test ran. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --dev
.venv/bin/python -m ruff check .
.venv/bin/python -m pyright --pythonpath .venv/bin/python  # [tool.pyright] in pyproject.toml: core/, tasks/, app/
set +e
.venv/bin/python -m pytest -q -ra --junitxml=test-artifacts/junit.xml "$@"
status=$?
set -e
if [[ $status == 5 ]]; then echo "[test] no test ran"; exit 1; fi
if [[ $status == 0 ]]; then
  ran=$(.venv/bin/python -c "import xml.etree.ElementTree as E; r=E.parse('test-artifacts/junit.xml').getroot(); s=r if r.tag=='testsuite' else r[0]; print(int(s.get('tests'))-int(s.get('skipped')))")
  if [[ "$ran" -lt 1 ]]; then echo "[test] no test ran"; exit 1; fi
  echo "[test] $ran tests ran"
fi
exit $status
