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

# Debian packages: installed when root or passwordless sudo allows it; otherwise (a cluster
# account, a non-Debian system, a conda environment) named for an admin, and the import check
# at the end tells whether the libraries are really missing (docs/install.md).
missing=""
if command -v dpkg >/dev/null 2>&1; then
    for pkg in $SYSTEM_PACKAGES $EXTRA_PACKAGES $VENV_PACKAGE; do
        dpkg -s "$pkg" >/dev/null 2>&1 || missing="$missing $pkg"
    done
fi
if [ -n "$missing" ]; then
    SUDO="none"
    if [ "$(id -u)" -eq 0 ]; then SUDO=""
    elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo"
    fi
    if [ "$SUDO" = "none" ]; then
        echo "bootstrap: not root and no passwordless sudo: not installing the Debian packages$missing" >&2
        echo "bootstrap: (ask an admin for them, or use the conda route of docs/install.md)" >&2
        [ -z "$VENV_PACKAGE" ] || { echo "bootstrap: error: $PYTHON cannot make a venv without $VENV_PACKAGE" >&2; exit 2; }
    else
        echo "bootstrap: installing Debian packages:$missing"
        $SUDO apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
    fi
fi

if [ ! -x .venv/bin/python ]; then
    echo "bootstrap: creating .venv with $($PYTHON --version)"
    "$PYTHON" -m venv .venv
    .venv/bin/python -m pip install -q --upgrade pip
fi
echo "bootstrap: installing whisker-pipeline into .venv"
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[dev]" 2>&1 | grep -v "is ignored: it is neither" || true
check=$(.venv/bin/python -c "import pipeline, open3d, pybullet, mujoco" 2>&1) \
    || { echo "$check" >&2; echo "bootstrap: error: the installed package does not import (above; a missing" \
              "lib*.so is a system library: docs/install.md)" >&2; exit 1; }
echo "bootstrap: ready"
