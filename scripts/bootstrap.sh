#!/usr/bin/env bash
# Install everything whisker-pipeline needs on a fresh Debian 12 machine:
# the system libraries Open3D links against, a .venv, and the package itself.
# Idempotent: each step is skipped when its result is already present.
set -euo pipefail
cd "$(dirname "$0")/.."

SYSTEM_PACKAGES="libusb-1.0-0 libgl1 libegl1 libx11-6 libudev1 libidn2-0 libgomp1"
EXTRA_PACKAGES="${EXTRA_PACKAGES:-}"   # e.g. chromium for the web-viewer test

PYTHON="${PYTHON:-python3}"
"$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null \
    || { echo "bootstrap: error: $PYTHON is missing or older than 3.11 (set PYTHON=...)" >&2; exit 2; }
# Debian's own python3 ships without ensurepip, which `python -m venv` needs.
VENV_PACKAGE=""
"$PYTHON" -c "import ensurepip" >/dev/null 2>&1 || VENV_PACKAGE="python3-venv"

missing=""
for pkg in $SYSTEM_PACKAGES $EXTRA_PACKAGES $VENV_PACKAGE; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing="$missing $pkg"
done
if [ -n "$missing" ]; then
    echo "bootstrap: installing Debian packages:$missing"
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
    echo "bootstrap: creating .venv with $($PYTHON --version)"
    "$PYTHON" -m venv .venv
    .venv/bin/python -m pip install -q --upgrade pip
fi
echo "bootstrap: installing whisker-pipeline into .venv"
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[dev]" 2>&1 | grep -v "is ignored: it is neither" || true
check=$(.venv/bin/python -c "import pipeline, open3d, pybullet, mujoco" 2>&1) \
    || { echo "$check" >&2; echo "bootstrap: error: the installed package does not import (above)" >&2; exit 1; }
echo "bootstrap: ready"
