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

step "build (release, once for every stage)"
cargo build --release --workspace --all-targets

step "unit and integration tests"
cargo test --release --workspace 2>&1 | tee target/test-output.txt
# (cargo's own summary lines above are what CI reads)

if [ "${FLEXID_SKIP_BENCH:-0}" != "1" ] && [ -x scripts/bench.sh ]; then
    step "benchmark smoke run (numbers reported, not asserted)"
    scripts/bench.sh --quick
fi
