#!/usr/bin/env bash
# Install what tools/render/mitsuba_captures.py needs. Idempotent; safe to re-run.
#   * Python: mitsuba 3.9.1 (brings drjit 1.5.0) and numpy, from PyPI.
#   * System: libllvm19 (Debian), which the fast llvm_ad_* variants load at run time. Dr.Jit
#     aborts with LLVM 15, so the system default is not enough. Without it the tool falls back to
#     the scalar_rgb variant, which is roughly 40x slower.
set -euo pipefail

MITSUBA_VERSION=3.9.1
PYTHON=${PYTHON:-python3}

have_mitsuba=$("$PYTHON" -c "import mitsuba, numpy; print(mitsuba.__version__)" 2>/dev/null || true)
if [ "$have_mitsuba" = "$MITSUBA_VERSION" ]; then
    echo "mitsuba $MITSUBA_VERSION and numpy already installed"
else
    "$PYTHON" -m pip install --quiet "mitsuba==$MITSUBA_VERSION" numpy
fi

if dpkg -s libllvm19 >/dev/null 2>&1; then
    echo "libllvm19 already installed"
elif [ "$(id -u)" = 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19
else
    echo "WARNING: libllvm19 is missing and installing it needs root: run 'sudo apt-get install -y libllvm19'." >&2
    echo "         Until then mitsuba_captures.py falls back to the slow scalar_rgb variant." >&2
fi

# The tool finds libLLVM 16-19 by itself; export DRJIT_LIBLLVM_PATH to override.
"$PYTHON" -c "import mitsuba as mi; print('mitsuba', mi.__version__, 'variants:', ', '.join(mi.variants()))"
