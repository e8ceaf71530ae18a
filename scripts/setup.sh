#!/usr/bin/env bash
# Set up Perceptive HTMPC Studio on a fresh Debian machine with Python 3.11; idempotent.
#   scripts/setup.sh          Debian libraries for open3d and off-screen MuJoCo, .venv, the package
#   scripts/setup.sh --dev    the same plus Debian chromium (for UI tests) and the dev extra
# A second run skips what is installed: apt only runs for missing packages, pip only when
# pyproject.toml changed since the last install.
set -euo pipefail
cd "$(dirname "$0")/.."

DEV=0
[[ "${1:-}" == "--dev" ]] && DEV=1

DEBS=(libusb-1.0-0 libgomp1 libegl1 libgl1 libgl1-mesa-dri libosmesa6)
# nodejs: the pyright wheel runs on it (without it, pyright would fetch a node from the internet)
[[ $DEV == 1 ]] && DEBS+=(chromium chromium-driver fonts-dejavu-core nodejs)

missing=()
for pkg in "${DEBS[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
PY=""
for cand in python3.11 python3; do
  if command -v "$cand" >/dev/null && "$cand" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    PY=$(command -v "$cand"); break
  fi
done
if [[ -z "$PY" ]]; then missing+=(python3 python3-venv); fi
if [[ -n "$PY" ]] && ! "$PY" -c 'import ensurepip, venv' 2>/dev/null; then missing+=(python3-venv); fi

if (( ${#missing[@]} )); then
  echo "[setup] installing Debian packages: ${missing[*]}"
  SUDO=""; [[ $(id -u) != 0 ]] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  [[ -z "$PY" ]] && PY=$(command -v python3)
fi

if [[ ! -x .venv/bin/python ]]; then
  echo "[setup] creating .venv with $PY"
  "$PY" -m venv .venv
fi

extra=""; [[ $DEV == 1 ]] && extra="[dev]"
stamp=".venv/.setup-stamp${extra}"
want=$(sha256sum pyproject.toml | cut -d' ' -f1)
current() { [[ -f "$1" && "$(cat "$1")" == "$want" ]]; }
if ! current "$stamp" && ! { [[ $DEV == 0 ]] && current ".venv/.setup-stamp[dev]"; }; then
  echo "[setup] installing the package${extra} into .venv (about a minute the first time)"
  .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
  PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 .venv/bin/python -m pip install -q --disable-pip-version-check -e ".${extra}"
  echo "$want" > "$stamp"
else
  echo "[setup] .venv is up to date"
fi
