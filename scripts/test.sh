#!/usr/bin/env bash
# The project's test command (README, .ci/run): sets up what the tests need on a fresh
# machine, builds once in release mode, and runs every test stage on that build.
#
#   scripts/test.sh            all tests, then a short benchmark smoke run
#   FLEXID_SKIP_BENCH=1 ...    tests only
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
export CARGO_TERM_COLOR=${CARGO_TERM_COLOR:-never}
# The measured data sets live beside the checkout (../shared/data); tests skip with a
# message where they are absent.
export FLEXID_SHARED_DATA=${FLEXID_SHARED_DATA:-$root/../shared/data}

step() { printf '\n== %s ==\n' "$*"; }

step "toolchain"
cargo --version
rustc --version

step "python peers for the interop tests (python-can, msgpack) and loopback multicast"
scripts/pyenv-interop.sh

step "pinocchio for the rigid-body dynamics check (tests/robot_pinocchio.rs)"
scripts/pyenv-pinocchio.sh

step "mosquitto for the MQTT test (tests/daemon_mqtt.rs)"
if command -v mosquitto >/dev/null 2>&1 || [ -x /usr/sbin/mosquitto ]; then
    echo "mosquitto: present"
elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -q --no-remove mosquitto || { apt-get update -q && apt-get install -y -q --no-remove mosquitto; }
else
    echo "mosquitto: missing and not root: the MQTT test skips (and fails under CI=true)"
fi

step "iproute2 for the EtherCAT veth tier (drivers/flexid-vdrive/tests/ecat_veth.rs)"
# The test makes a network namespace and a veth pair with `ip` (as root); without either it
# skips, and under CI=true it fails.
if command -v ip >/dev/null 2>&1; then
    echo "ip: present"
elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -q --no-remove iproute2 || { apt-get update -q && apt-get install -y -q --no-remove iproute2; }
else
    echo "ip: missing and not root: the veth tier skips (and fails under CI=true)"
fi

step "chromium and playwright-core for the browser test (tests/daemon_web.rs)"
if [ -x /usr/bin/chromium ] && command -v npm >/dev/null 2>&1; then
    echo "chromium, node: present"
elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    pkgs="chromium"
    command -v npm >/dev/null 2>&1 || pkgs="$pkgs nodejs npm"
    # shellcheck disable=SC2086
    apt-get install -y -q --no-remove $pkgs || { apt-get update -q && apt-get install -y -q --no-remove $pkgs; }
else
    echo "chromium/node: missing and not root: the browser test skips (and fails under CI=true)"
fi
if command -v npm >/dev/null 2>&1; then
    # the version pinned in tests/browser/package-lock.json (one package, a few seconds)
    (cd tests/browser && npm ci --no-audit --no-fund --prefer-offline --loglevel=error)
fi

step "reserve the tests' UDP bus ports (43100-43400) from the kernel's ephemeral ports"
# The tests' user-space buses bind fixed multicast ports inside Linux's ephemeral range
# (43113 is python-can's default): a send socket of another test that happens to get one
# of them as its ephemeral port makes the bind fail (seen once: "bind: Address already in
# use" on 43322). ip_local_reserved_ports takes them out of the ephemeral allocation.
reserved=/proc/sys/net/ipv4/ip_local_reserved_ports
if [ -w "$reserved" ]; then
    cur=$(cat "$reserved")
    case ",$cur," in
    *,43100-43400,*) ;;
    *) echo "${cur:+$cur,}43100-43400" >"$reserved" ;;
    esac
    echo "reserved ports: $(cat "$reserved")"
else
    echo "cannot write $reserved (not root): a rare port clash between tests stays possible"
fi

step "build (release, once for every stage)"
cargo build --release --workspace --all-targets

step "unit and integration tests"
# The property tests over every reader of outside input also run for a bounded time in CI
# (tests/bad_input/props.rs, fuzz_for_a_bounded_time: issue 16 asks for at least 60 s with
# no finding); unset, as locally, that test says so and returns at once.
if [ "${CI:-}" = "true" ]; then
    export FLEXID_FUZZ_SECONDS=${FLEXID_FUZZ_SECONDS:-70}
fi
cargo test --release --workspace 2>&1 | tee target/test-output.txt
# (cargo's own summary lines above are what CI reads)
# The browser test's screenshot of the live Bode page (tests/daemon_web.rs):
if [ -s target/browser/bode-live.png ]; then
    echo "screenshot of the live Bode page: $(pwd)/target/browser/bode-live.png ($(stat -c %s target/browser/bode-live.png) bytes)"
elif [ "${CI:-}" = "true" ]; then
    echo "test: the browser test left no screenshot (target/browser/bode-live.png)" >&2
    exit 1
fi

# Tests that need a real SocketCAN interface: run with FLEXID_VCAN=vcan0 inside a small
# qemu VM (scripts/vcan-vm.sh: this kernel has no vcan), on the release build above. One
# line per test binary, "PACKAGE TEST-TARGET" (the target of `cargo test --test`); the VM
# sees the whole checkout read-only, so a test may start binaries from target/release/.
VCAN_TESTS=(
    "flexid-can socketcan"
    "flexid e2e_vcan"
)

# The release executable of integration test $2 of package $1 (built above: --workspace
# keeps the features, hence the file, of the build stage); the test target only, not the
# package's binaries built beside it.
test_binary() {
    cargo test --release --workspace --test "$2" --no-run --message-format=json 2>/dev/null |
        grep -E "\"package_id\":\"[^\"]*[/#]$1[#@]" |
        grep -F '"kind":["test"]' | grep -F "\"name\":\"$2\"" |
        sed -n 's/.*"executable":"\([^"]*\)".*/\1/p' | head -1 || true
}

step "SocketCAN tests on vcan0 (scripts/vcan-vm.sh)"
if scripts/vcan-vm.sh setup; then
    vcan_bins=()
    for t in "${VCAN_TESTS[@]}"; do
        read -r pkg name <<<"$t"
        bin=$(test_binary "$pkg" "$name")
        [ -x "$bin" ] || { echo "no test binary for $pkg --test $name" >&2; exit 1; }
        vcan_bins+=("$bin")
    done
    # One VM for all of them; FLEXID_VCAN_REQUIRED turns the tests' skips into failures.
    FLEXID_VCAN=vcan0 FLEXID_VCAN_REQUIRED=1 scripts/vcan-vm.sh run --no-setup -- \
        bash -c 'rc=0; for b; do echo "     Running ${b#"$PWD"/} (vcan0, VM)"; "$b" || rc=1; done; exit $rc' \
        vcan-tests "${vcan_bins[@]}" 2>&1 | tee -a target/test-output.txt
elif [ "${CI:-}" = true ]; then
    echo "FAILED: the SocketCAN test VM could not be set up (scripts/vcan-vm.sh setup); required under CI=true" >&2
    exit 1
else
    echo "skipped: SocketCAN tests: scripts/vcan-vm.sh setup failed (needs root and Debian's apt for qemu-system-x86, busybox-static, cpio and a linux-image-6.1.0 package)"
fi

if [ "${FLEXID_SKIP_BENCH:-0}" != "1" ] && [ -x scripts/bench.sh ]; then
    step "benchmark smoke run (numbers reported, not asserted)"
    scripts/bench.sh --quick
fi
