#!/usr/bin/env bash
# Command 1 of the README: set up (if needed) and start the studio on the embedded MuJoCo simulation.
# Extra arguments go to `python -m app` (e.g. --port 8081, --scene core/scenes/random_0.yaml).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/python -m app "$@"
