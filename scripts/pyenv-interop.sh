#!/usr/bin/env bash
# Creates .venv-interop (gitignored) with python-can, msgpack and python-canopen for the
# interop tests (drivers/flexid-can/tests/udp_interop.rs, drivers/flexid-vdrive/tests/
# {pycan,canopen402}_interop.rs), and numpy + scipy for the independent IDIM-LS check of the
# trajectory path (tests/real_data.rs, tests/interop/idim_ls.py). Idempotent: an existing venv
# with the pinned versions is left as it is.
#
# The test also needs multicast on the loopback interface (this machine has no route for
# 239.0.0.0/8 off the default interface, and we never want test traffic on eth0):
#   ip link set lo multicast on
#   ip route add 239.0.0.0/8 dev lo
# The Rust test adds both itself when run as root (see tests/common/mod.rs); this script
# does the same when it can, so that a manual python-can session works too.
set -euo pipefail

PYCAN_VERSION=4.6.1
MSGPACK_VERSION=1.1.1
CANOPEN_VERSION=2.4.1
NUMPY_VERSION=2.4.6
SCIPY_VERSION=1.17.1

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv-interop"
python="${PYTHON:-python3}"

if [ -x "$venv/bin/python" ] &&
    "$venv/bin/python" - "$PYCAN_VERSION" "$MSGPACK_VERSION" "$CANOPEN_VERSION" "$NUMPY_VERSION" "$SCIPY_VERSION" <<'PY' 2>/dev/null; then
import sys
import can, canopen, msgpack, numpy, scipy
ok = (can.__version__ == sys.argv[1] and ".".join(map(str, msgpack.version)) == sys.argv[2]
      and canopen.__version__ == sys.argv[3] and numpy.__version__ == sys.argv[4]
      and scipy.__version__ == sys.argv[5])
sys.exit(0 if ok else 1)
PY
    echo "pyenv-interop: $venv up to date (python-can $PYCAN_VERSION, msgpack $MSGPACK_VERSION, canopen $CANOPEN_VERSION, numpy $NUMPY_VERSION, scipy $SCIPY_VERSION)"
else
    "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "python-can==$PYCAN_VERSION" "msgpack==$MSGPACK_VERSION" "canopen==$CANOPEN_VERSION" \
        "numpy==$NUMPY_VERSION" "scipy==$SCIPY_VERSION"
    echo "pyenv-interop: installed python-can $PYCAN_VERSION, msgpack $MSGPACK_VERSION, canopen $CANOPEN_VERSION, numpy $NUMPY_VERSION, scipy $SCIPY_VERSION into $venv"
fi

# Multicast on loopback (needs root; harmless when already set up).
if [ "$(id -u)" = 0 ] && command -v ip >/dev/null; then
    ip link set lo multicast on || true
    ip route show 239.0.0.0/8 dev lo | grep -q . || ip route add 239.0.0.0/8 dev lo || true
fi
