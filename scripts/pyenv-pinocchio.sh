#!/usr/bin/env bash
# Creates .venv-pinocchio (gitignored) with Pinocchio (`pin` on PyPI, which brings its own
# dependencies: eigenpy, hpp-fcl/coal, cmeel wheels) and numpy, for the independent check
# of the rigid-body dynamics of crates/flexid-core/src/robot (tests/robot_pinocchio.rs,
# tests/interop/pinocchio_dynamics.py). Idempotent: an existing venv with the pinned
# versions is left as it is.
set -euo pipefail

PIN_VERSION=4.1.0

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv-pinocchio"
python="${PYTHON:-python3}"

if [ -x "$venv/bin/python" ] &&
    "$venv/bin/python" - "$PIN_VERSION" <<'PY' 2>/dev/null; then
import sys
import numpy, pinocchio
sys.exit(0 if pinocchio.__version__ == sys.argv[1] else 1)
PY
    echo "pyenv-pinocchio: $venv up to date (pin $PIN_VERSION)"
else
    "$python" -m venv "$venv"
    # numpy is left to pin's own requirement (its wheels are built against a numpy range).
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "pin==$PIN_VERSION" numpy
    "$venv/bin/python" -c 'import pinocchio, numpy; print("pyenv-pinocchio: installed pin", pinocchio.__version__, "numpy", numpy.__version__)'
fi
