#!/usr/bin/env bash
# Creates .venv-pinocchio (gitignored) with Pinocchio (`pin` on PyPI, which brings its own
# dependencies: eigenpy, coal and the cmeel wheels) and numpy, for the independent check
# of the rigid-body dynamics of crates/flexid-core/src/robot (tests/robot_pinocchio.rs,
# tests/interop/pinocchio_dynamics.py). Idempotent: an existing venv with the pinned
# versions is left as it is.
set -euo pipefail

PIN_VERSION=4.1.0
NUMPY_VERSION=2.4.6

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv-pinocchio"
python="${PYTHON:-python3}"

if [ -x "$venv/bin/python" ] &&
    "$venv/bin/python" - "$PIN_VERSION" "$NUMPY_VERSION" <<'PY' 2>/dev/null; then
import sys
import numpy, pinocchio
sys.exit(0 if (pinocchio.__version__, numpy.__version__) == (sys.argv[1], sys.argv[2]) else 1)
PY
    echo "pyenv-pinocchio: $venv up to date (pin $PIN_VERSION, numpy $NUMPY_VERSION)"
else
    "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "pin==$PIN_VERSION" "numpy==$NUMPY_VERSION"
    "$venv/bin/python" -c 'import pinocchio, numpy; print("pyenv-pinocchio: installed pin", pinocchio.__version__, "numpy", numpy.__version__)'
fi
