#!/usr/bin/env bash
# Remakes the pictures of README.md from the release build (cargo build --release
# --workspace first):
#   docs/bode-demo.svg      `flexid demo` on the embedded default plant (over the bus when
#                           it can be used, else the simulated drive in-process)
#   docs/diagnose-gap.svg   `flexid diagnose` of two levels measured on
#                           plants/e2e_backlash.toml (odd random-phase multisine 1-400 Hz
#                           at 0.1 and 0.5 N m peak, amplitude rising with frequency)
#   docs/ethercat-vs-can-600hz.svg  tests/ethercat_vs_can_600hz.rs with FLEXID_DOCS_PICTURES=1
#                           (EtherCAT at 4 kHz against CAN with 4 axes at 1 Mbit/s)
set -euo pipefail
cd "$(dirname "$0")/.."
flexid=target/release/flexid
[ -x "$flexid" ] || { echo "build first: cargo build --release --workspace" >&2; exit 2; }
work=target/pictures
rm -rf "$work"
mkdir -p "$work"

"$flexid" demo --out "$work/demo" >"$work/demo.txt"
cp "$work/demo/bode.svg" docs/bode-demo.svg

for level in 0.1 0.5; do
    "$flexid" excite multisine --fs 1000 --period-samples 2000 --band 1 400 \
        --phases odd-random --amplitude-exponent 1 --peak-nm "$level" \
        --periods 4 --transient-periods 1 --out "$work/exc-$level.csv"
    "$flexid" simulate --plant plants/e2e_backlash.toml --excitation "$work/exc-$level.csv" \
        --out "$work/rec-$level.csv"
done
"$flexid" diagnose "$work/rec-0.1.csv" "$work/rec-0.5.csv" --masses 3 \
    --json "$work/diagnosis.json" --svg docs/diagnose-gap.svg | tee "$work/diagnosis.txt"
"$flexid" robot --starts 8 --svg docs/robot-bode-matrix.svg | tee "$work/robot.txt"
FLEXID_DOCS_PICTURES=1 cargo test --release --test ethercat_vs_can_600hz -- --nocapture \
    2>&1 | tee "$work/ethercat-vs-can.txt"
echo "wrote docs/bode-demo.svg, docs/diagnose-gap.svg, docs/robot-bode-matrix.svg and docs/ethercat-vs-can-600hz.svg (reports in $work)"
