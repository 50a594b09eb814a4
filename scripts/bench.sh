#!/usr/bin/env bash
# The comparison benchmark: flexid against scipy/numpy on the same data, one core each.
#
#   scripts/bench.sh           full run (more repetitions)
#   scripts/bench.sh --quick   short run (CI, after the tests)
#
# 1. creates/reuses .venv (gitignored) with pinned numpy and scipy (idempotent);
# 2. builds the Rust side (benches/compare.rs) and runs the Python side
#    (benches/compare.py), which starts it: Rust simulates the data, writes it to
#    target/bench/data with its results; Python reads the same files, checks that both
#    sides computed the same numbers, then times the two sides interleaved (Rust, Python,
#    Rust, Python, ...), prints the median [min, max] ratio per computation and writes
#    target/bench/compare.md. FLEXID_BENCH_ONLY=compare stops after this stage.
# 3. runs the issue-17 identification benchmark: benches/manipulator_identify.py starts
#    benches/manipulator_identify.rs (--serve), which simulates the reference robot's two
#    identification poses and writes the cost's problem to target/bench/manipulator; the
#    Python side checks that its V equals flexid's, then times flexid's multi-start
#    identify against scipy's BFGS on the same cost from the same starts, interleaved, on
#    one core (both pinned to the same core by the script itself) and on all cores (every
#    thread / a process pool); target/bench/manipulator_identify.md. Full: 60 starts,
#    3 rounds, inverse-variance weights, then the paper's uniform weights (1 round,
#    appended); --quick: 8 starts, 1 round, inverse-variance only.
#    FLEXID_BENCH_ONLY=manipulator runs this stage alone.
# Both processes are pinned to the same core, BLAS/OpenMP to one thread. Ratios are
# reported, not asserted; the script fails when the two sides' numbers disagree.
# 4. runs the cycle-timing benchmark (benches/cycle_timing.rs): wake-up lateness of the
#    real-time cycle thread against a bare clock_nanosleep loop at 1, 2 and 4 kHz (4 s per
#    rate and loop, 1 s with --quick), written to target/bench/cycle_timing.md. It asks for
#    SCHED_FIFO, mlockall and the last core itself and reports what it was granted.
# 5. runs the cycle-rate benchmark (drivers/flexid-vdrive/benches/cycle_rate.rs): highest
#    overrun-free cycle rate on an emulated 1 Mbit/s bus, target/bench/cycle_rate.md.
# 6. runs the daemon-load benchmark (benches/daemon_load.rs) at 1, 2 and 4 kHz: the daemon's
#    CPU share per sweeping axis, the period-end -> Bode latency and the cycle thread's
#    wake-up lateness next to a bare loop, target/bench/daemon_load.md.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

NUMPY_VERSION=2.4.6
SCIPY_VERSION=1.17.1

mode=()
for a in "$@"; do
    case "$a" in
    --quick) mode=(--quick) ;;
    *) echo "usage: scripts/bench.sh [--quick]" >&2; exit 2 ;;
    esac
done

# 7. The EtherCAT cycle timing on the veth tier (it sets its threads' scheduling itself).
ecat_stage() {
    local eexe
    eexe=$(cargo build --release -p flexid-vdrive --bench ecat_cycle_timing --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*ecat_cycle_timing[^"]*\)".*/\1/p' | tail -n 1)
    if [ -z "$eexe" ] || [ ! -x "$eexe" ]; then
        cargo build --release -p flexid-vdrive --bench ecat_cycle_timing # shows the error
        echo "bench: could not find the ecat_cycle_timing executable" >&2
        exit 1
    fi
    "$eexe" "${mode[@]}" --out "$root/target/bench/ecat_cycle_timing.md"
}
if [ "${FLEXID_BENCH_ONLY:-}" = ecat ]; then
    ecat_stage
    exit 0
fi

venv="$root/.venv"
python="${PYTHON:-python3}"
if [ -x "$venv/bin/python" ] &&
    "$venv/bin/python" - "$NUMPY_VERSION" "$SCIPY_VERSION" <<'PY' 2>/dev/null; then
import sys
import numpy, scipy
sys.exit(0 if (numpy.__version__, scipy.__version__) == tuple(sys.argv[1:3]) else 1)
PY
    echo "bench: $venv up to date (numpy $NUMPY_VERSION, scipy $SCIPY_VERSION)"
else
    "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "numpy==$NUMPY_VERSION" "scipy==$SCIPY_VERSION"
    echo "bench: installed numpy $NUMPY_VERSION, scipy $SCIPY_VERSION into $venv"
fi

# The release build of the bench target (scripts/test.sh has built it already).
exe=$(cargo build --release --bench compare --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*compare[^"]*\)".*/\1/p' | tail -n 1)
if [ -z "$exe" ] || [ ! -x "$exe" ]; then
    cargo build --release --bench compare # shows the error
    echo "bench: could not find the compare executable" >&2
    exit 1
fi

# One core for both sides: the last one (core 0 takes most interrupts).
pin=()
if command -v taskset >/dev/null; then
    core=$(($(nproc) - 1))
    pin=(taskset -c "$core")
fi
# As root, both sides also run at a raised priority (nice -15): on a shared machine the
# other load then disturbs the timings much less (both sides alike).
if [ "$(id -u)" = 0 ]; then
    pin=(nice -n -15 "${pin[@]}")
fi
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
    VECLIB_MAXIMUM_THREADS=1 NUMEXPR_NUM_THREADS=1

# 3. The issue-17 identification against scipy (not pinned by taskset: the Python side
#    pins both processes itself for the one-core timings and frees them for all cores).
manipulator_stage() {
    local mexe mout margs=()
    mexe=$(cargo build --release --bench manipulator_identify --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*manipulator_identify[^"]*\)".*/\1/p' | tail -n 1)
    if [ -z "$mexe" ] || [ ! -x "$mexe" ]; then
        cargo build --release --bench manipulator_identify # shows the error
        echo "bench: could not find the manipulator_identify executable" >&2
        exit 1
    fi
    mout="$root/target/bench/manipulator"
    rm -rf "$mout"
    local nice=()
    [ "$(id -u)" = 0 ] && nice=(nice -n -15)
    "${nice[@]}" "$venv/bin/python" benches/manipulator_identify.py --rust "$mexe" \
        --out "$mout" "${mode[@]}" --report "$root/target/bench/manipulator_identify.md"
    if [ ${#mode[@]} -eq 0 ]; then
        "${nice[@]}" "$venv/bin/python" benches/manipulator_identify.py --rust "$mexe" \
            --out "$mout" --weighting uniform --reps 1 --report "$mout/uniform.md"
        { echo; echo "---"; echo; cat "$mout/uniform.md"; } >>"$root/target/bench/manipulator_identify.md"
    fi
}
if [ "${FLEXID_BENCH_ONLY:-}" = manipulator ]; then
    manipulator_stage
    exit 0
fi


data="$root/target/bench/data"
rm -rf "$data"
# The Python side starts the Rust side (--serve, on the same pinned core) and alternates
# them run by run: a timing of each side per round, the ratio per round, its median, min
# and max (a shared machine's load then hits both sides alike).
"${pin[@]}" "$venv/bin/python" benches/compare.py "$data" --rust "$exe" "${mode[@]}" \
    --report "$root/target/bench/compare.md"
if [ "${FLEXID_BENCH_ONLY:-}" = compare ]; then
    exit 0
fi
manipulator_stage

# The cycle-timing benchmark (not pinned by taskset: it pins its cycle threads itself).
cexe=$(cargo build --release --bench cycle_timing --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*cycle_timing[^"]*\)".*/\1/p' | tail -n 1)
if [ -z "$cexe" ] || [ ! -x "$cexe" ]; then
    cargo build --release --bench cycle_timing # shows the error
    echo "bench: could not find the cycle_timing executable" >&2
    exit 1
fi
"$cexe" "${mode[@]}" --out "$root/target/bench/cycle_timing.md"

# 5. The cycle-rate benchmark (drivers/flexid-vdrive/benches/cycle_rate.rs): master and
#    flexid-vdrive on an in-process bus paced at 1 Mbit/s, the highest cycle rate without
#    overruns against the bus limit of the default mapping; target/bench/cycle_rate.md.
rexe=$(cargo build --release -p flexid-vdrive --bench cycle_rate --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*cycle_rate[^"]*\)".*/\1/p' | tail -n 1)
if [ -z "$rexe" ] || [ ! -x "$rexe" ]; then
    cargo build --release -p flexid-vdrive --bench cycle_rate # shows the error
    echo "bench: could not find the cycle_rate executable" >&2
    exit 1
fi
"$rexe" "${mode[@]}" --out "$root/target/bench/cycle_rate.md"

# The withheld-effect benchmark of `flexid diagnose` (benches/withheld_effect.rs): random
# axes with one unmodelled effect each, simulated by the fine-step plant, diagnosed without
# the truth; prints the confusion matrix, the gap ratios and the time per case. --quick: 3
# cases per class; full: 20. Reports whether the targets (90 % per class, gap halved) are
# met; FLEXID_BENCH_STRICT=1 makes a miss fail the script.
if [ ${#mode[@]} -gt 0 ]; then
    cases=3
else
    cases=20
fi
wexe=$(cargo build --release --bench withheld_effect --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*withheld_effect[^"]*\)".*/\1/p' | tail -n 1)
"${pin[@]}" "$wexe" "$cases" | tee "$root/target/bench/withheld_effect.txt"

# Identification on chains it was never tuned on (benches/identify_unseen.rs) and its speed
# on 10^6-sample recordings (benches/identify_speed.rs). --quick: 4 held-out cases and one
# timing run; full: 40 held-out cases (seeds from 200000) and 5 runs.
if [ ${#mode[@]} -gt 0 ]; then
    unseen=4; runs=1
else
    unseen=40; runs=5
fi
uexe=$(cargo build --release --bench identify_unseen --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*identify_unseen[^"]*\)".*/\1/p' | tail -n 1)
"$uexe" "$unseen" --seed 200000 | tee "$root/target/bench/identify_unseen.txt"
sexe=$(cargo build --release --bench identify_speed --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*identify_speed[^"]*\)".*/\1/p' | tail -n 1)
"${pin[@]}" "$sexe" "$runs" | tee "$root/target/bench/identify_speed.txt"

# 6. The daemon under load (benches/daemon_load.rs): the real daemon with 1 and 2 axes
#    sweeping in real time on flexid-vdrive processes against itself idle: CPU share per
#    axis, the period-end -> Bode latency on the event stream (p50/p99) and the cycle
#    thread's wake-up lateness against a bare loop in the same run, at 1, 2 and 4 kHz;
#    target/bench/daemon_load.md. --quick: 3 s sweeps; full: 10 s.
cargo build --release -p flexid-vdrive --bin flexid-vdrive 2>/dev/null || true
dexe=$(cargo build --release --bench daemon_load --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*daemon_load[^"]*\)".*/\1/p' | tail -n 1)
if [ -z "$dexe" ] || [ ! -x "$dexe" ]; then
    cargo build --release --bench daemon_load # shows the error
    echo "bench: could not find the daemon_load executable" >&2
    exit 1
fi
"$dexe" "${mode[@]}" --out "$root/target/bench/daemon_load.md"

ecat_stage
