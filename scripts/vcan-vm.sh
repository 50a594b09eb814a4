#!/usr/bin/env bash
# Runs a command with a SocketCAN `vcan0` interface available, on machines whose kernel
# has no AF_CAN/vcan (our CI and development machines): inside a small Linux VM under
# qemu (TCG, no KVM needed) that mounts this machine's root file system read-only over 9p
# and chroots into it, so the command sees the same files, binaries and working directory.
#
#   scripts/vcan-vm.sh setup                  install qemu/busybox/cpio if missing, fetch a
#                                             Debian 6.1 kernel, build the initramfs
#                                             (cached in target/vcan-vm/: cheap to re-run)
#   scripts/vcan-vm.sh run [OPTIONS] -- CMD [ARGS...]
#                                             run CMD in the current directory with vcan0 up;
#                                             its output is printed live, and the script
#                                             exits with CMD's exit code
#   scripts/vcan-vm.sh clean                  remove the cache directory
#
# run options:
#   --force-vm        always use the VM, even when this kernel has vcan
#   --no-setup        fail instead of running `setup` when the cache is incomplete
#   -e NAME[=VALUE]   pass NAME (with this value, or its value here) into the VM
#
# Without --force-vm, `run` first tries the host kernel: when vcan0 exists, or
# `ip link add dev vcan0 type vcan` works (root, vcan module available), CMD runs
# directly here, with no VM.
#
# Environment passed into the VM: FLEXID_*, RUST_*, CARGO_TERM_*, CI, NO_COLOR, TERM,
# PATH, HOME, USER, plus every -e. FLEXID_VCAN defaults to vcan0.
#
# Knobs (environment): VCAN_VM_DIR (cache, default <repo>/target/vcan-vm),
# VCAN_VM_KERNEL (kernel package, default the newest linux-image-6.1.0-N-amd64 apt
# knows), VCAN_VM_TIMEOUT (seconds for the whole VM, default 1200), VCAN_VM_MEM (MiB,
# default 1024), VCAN_VM_SMP (vCPUs, default 2), VCAN_VM_VERBOSE=1 (show the boot log),
# VCAN_VM_APPEND (more kernel arguments, e.g. "loglevel=7" with VCAN_VM_VERBOSE=1).
#
# Guest side: busybox init script (below, `guest_init`) loads virtio/9p/overlay/CAN
# modules, creates vcan0, mounts host / (9p, read-only) under a RAM overlay at /host (the
# command may write, e.g. cargo's lock file; nothing reaches the host), mounts proc,
# sysfs, devtmpfs and tmpfs (/run, /dev/shm; /tmp only without the overlay) inside it, chroots, cds and runs the
# command (stdin /dev/null, stdout and stderr through a pipe: no tty), prints
# `VCAN-VM-EXIT=<code> <nonce>` and powers off. The command and environment reach the guest as a
# small extra cpio archive appended to the initramfs (no kernel command line limits).
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/.." && pwd)
cache=${VCAN_VM_DIR:-$root/target/vcan-vm}
timeout_s=${VCAN_VM_TIMEOUT:-1200}
mem=${VCAN_VM_MEM:-1024}
smp=${VCAN_VM_SMP:-2}

# Modules, in insmod order (dependencies first). `setup` also adds anything their
# .modinfo says they depend on, so a kernel with a different split still loads.
MODULES=(virtio_ring virtio virtio_pci_legacy_dev virtio_pci_modern_dev virtio_pci
    netfs fscache 9pnet 9pnet_virtio 9p overlay can can-raw can-dev vcan)
PACKAGES=(qemu-system-x86 busybox-static cpio xz-utils)

log() { printf 'vcan-vm: %s\n' "$*" >&2; }
die() {
    log "error: $*"
    exit 2
}

# ---------------------------------------------------------------------------- setup --

apt_updated=0
apt_update_once() {
    if [ "$apt_updated" = 0 ]; then
        log "apt-get update"
        apt-get update -qq >&2
        apt_updated=1
    fi
}

# Installs what is missing, never removing a package already on the machine (apt's
# --no-remove). When apt can only install qemu-system-x86 by removing something (a newer
# qemu-utils from backports breaks bookworm's qemu-system-common), the qemu packages are
# unpacked into the cache instead ($cache/qemu, used by qemu_bin) and only their
# libraries and firmware are installed.
install_packages() {
    local missing=() p
    for p in "${PACKAGES[@]}"; do
        [ "$p" = qemu-system-x86 ] && qemu_bin >/dev/null 2>&1 && continue
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'ok installed' ||
            missing+=("$p")
    done
    [ ${#missing[@]} = 0 ] && return 0
    command -v apt-get >/dev/null || die "missing ${missing[*]} and no apt-get"
    [ "$(id -u)" = 0 ] || die "missing ${missing[*]}: run 'scripts/vcan-vm.sh setup' as root"
    log "installing ${missing[*]}"
    apt_install "${missing[@]}" && return 0
    printf '%s\n' "${missing[@]}" | grep -qx qemu-system-x86 ||
        die "apt cannot install ${missing[*]} without removing packages"
    local rest=()
    for p in "${missing[@]}"; do [ "$p" = qemu-system-x86 ] || rest+=("$p"); done
    [ ${#rest[@]} = 0 ] || apt_install "${rest[@]}" ||
        die "apt cannot install ${rest[*]} without removing packages"
    private_qemu
}

# apt-get install that never removes an installed package; the lists are updated only
# when apt cannot find the packages with the ones it has.
apt_install() {
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-remove "$@" >&2 && return 0
    apt_update_once
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-remove "$@" >&2
}

# qemu-system-x86 and qemu-system-common unpacked into $cache/qemu (dpkg -x, nothing
# registered with dpkg); their dependencies installed except the qemu packages
# themselves.
private_qemu() {
    local q="$cache/qemu" dl deps
    log "qemu-system-x86 conflicts with installed packages: unpacking it into $q"
    deps=$(apt-cache depends --no-recommends --no-suggests --no-conflicts --no-breaks \
        --no-replaces --no-enhances qemu-system-x86 qemu-system-common |
        sed -n 's/^ *\(Pre\)\?Depends: //p' | grep -v '^<' |
        grep -vx 'qemu-system-common\|qemu-system-x86' | sort -u)
    # shellcheck disable=SC2086
    apt_install $deps || die "apt cannot install qemu's libraries without removing packages"
    dl=$(mktemp -d)
    (cd "$dl" && apt-get download -qq qemu-system-x86 qemu-system-common 2>/dev/null) ||
        { apt_update_once && (cd "$dl" && apt-get download -qq qemu-system-x86 qemu-system-common); }
    rm -rf "$q.tmp"
    mkdir -p "$q.tmp"
    for p in "$dl"/*.deb; do dpkg -x "$p" "$q.tmp"; done
    rm -rf "$dl" "$q"
    mv "$q.tmp" "$q"
    qemu_bin >/dev/null || die "no qemu-system-x86_64 in the unpacked packages"
}

# The qemu binary to run: the installed one, else the one unpacked into the cache.
qemu_bin() {
    if command -v qemu-system-x86_64; then
        return 0
    elif [ -x "$cache/qemu/usr/bin/qemu-system-x86_64" ]; then
        echo "$cache/qemu/usr/bin/qemu-system-x86_64"
    else
        return 1
    fi
}

# Sets QEMU_CMD to the command that runs qemu (installed or unpacked; the unpacked one
# finds its firmware and modules in the cache first, then in the installed
# qemu-system-data, seabios and ipxe-qemu). An array, so that `timeout` can run it.
qemu_cmd() {
    local bin
    bin=$(qemu_bin) || die "qemu-system-x86_64 is missing: run 'scripts/vcan-vm.sh setup'"
    if [ "$bin" = "$cache/qemu/usr/bin/qemu-system-x86_64" ]; then
        QEMU_CMD=(env "QEMU_MODULE_DIR=$cache/qemu/usr/lib/x86_64-linux-gnu/qemu" "$bin"
            -L "$cache/qemu/usr/share/qemu" -L /usr/share/qemu -L /usr/share/seabios)
    else
        QEMU_CMD=("$bin")
    fi
}

# The newest Debian 6.1 amd64 kernel package apt knows (signed or unsigned image: both
# hold the same vmlinuz and modules).
pick_kernel_package() {
    local list
    kernel_packages() {
        apt-cache search --names-only '^linux-image-6\.1\.0-[0-9]+-amd64(-unsigned)?$' |
            awk '{print $1}' | sort -V
    }
    list=$(kernel_packages)
    if [ -z "$list" ]; then
        apt_update_once
        list=$(kernel_packages)
    fi
    [ -n "$list" ] || die "apt knows no linux-image-6.1.0-*-amd64 package"
    # newest version; prefer the unsigned package of that version (no shim metadata)
    local newest
    newest=$(sed 's/-unsigned$//' <<<"$list" | sort -V | tail -1)
    if grep -qx "$newest-unsigned" <<<"$list"; then echo "$newest-unsigned"; else echo "$newest"; fi
}

fetch_kernel() {
    # Cached: target/vcan-vm/kernel/{vmlinuz,modules/} and kernel/package (its name).
    if [ -f "$cache/kernel/vmlinuz" ] && [ -f "$cache/kernel/package" ] &&
        { [ -z "${VCAN_VM_KERNEL:-}" ] || [ "$(cat "$cache/kernel/package")" = "$VCAN_VM_KERNEL" ]; }; then
        return 0
    fi
    local pkg=${VCAN_VM_KERNEL:-}
    [ -n "$pkg" ] || pkg=$(pick_kernel_package)
    log "downloading $pkg"
    local dl="$cache/download"
    rm -rf "$dl" "$cache/kernel"
    mkdir -p "$dl/x"
    # (as root apt warns that the download is unsandboxed: harmless)
    (cd "$dl" && apt-get download -qq "$pkg" 2>/dev/null) ||
        { apt_update_once && (cd "$dl" && apt-get download -qq "$pkg"); }
    dpkg-deb -x "$dl"/*.deb "$dl/x"
    local vmlinuz kver
    vmlinuz=$(ls "$dl"/x/boot/vmlinuz-* | head -1)
    kver=${vmlinuz##*/vmlinuz-}
    [ -d "$dl/x/lib/modules/$kver" ] || die "$pkg has no lib/modules/$kver"
    mkdir -p "$cache/kernel"
    cp "$vmlinuz" "$cache/kernel/vmlinuz"
    mv "$dl/x/lib/modules/$kver" "$cache/kernel/modules"
    echo "$kver" >"$cache/kernel/version"
    echo "$pkg" >"$cache/kernel/package"
    rm -rf "$dl"
}

# The uncompressed kernel (ELF vmlinux) boots through qemu's PVH entry and saves the
# bzImage's self-decompression, which takes 5-10 s under TCG. Extracted like the kernel's
# scripts/extract-vmlinux; kept only when qemu accepts it (probe: load, paused, quit).
# kernel/boot names the image `run` boots: vmlinux, or vmlinuz as the fallback.
choose_boot_image() {
    [ -f "$cache/kernel/boot" ] && return 0
    local k="$cache/kernel" off
    echo vmlinuz >"$k/boot.tmp"
    for off in $(LC_ALL=C grep -obUaP '\xfd7zXZ\x00|\x28\xb5\x2f\xfd|\x1f\x8b\x08' "$k/vmlinuz" |
        cut -d: -f1 | head -20); do
        tail -c +$((off + 1)) "$k/vmlinuz" |
            { xz -dc --single-stream 2>/dev/null || zstd -qdc 2>/dev/null || gzip -dc 2>/dev/null; } >"$k/vmlinux" || true
        qemu_cmd
        if [ "$(head -c 4 "$k/vmlinux")" = $'\x7fELF' ] &&
            echo quit | timeout 60 "${QEMU_CMD[@]}" -accel tcg -nodefaults -display none -S \
                -monitor stdio -kernel "$k/vmlinux" >/dev/null 2>&1; then
            echo vmlinux >"$k/boot.tmp"
            break
        fi
    done
    [ "$(cat "$k/boot.tmp")" = vmlinux ] || rm -f "$k/vmlinux"
    mv "$k/boot.tmp" "$k/boot"
    log "boot image: $(cat "$k/boot")"
}

# Prints a module file decompressed (busybox insmod may not read .ko.xz).
mod_cat() {
    case $1 in
    *.ko.xz) xz -dc "$1" ;;
    *.ko.zst) zstd -qdc "$1" ;;
    *.ko.gz) gzip -dc "$1" ;;
    *.ko) cat "$1" ;;
    *) die "unknown module file $1" ;;
    esac
}

# Resolves MODULES plus their dependencies (the `depends=` of each module's .modinfo:
# Debian's package has no modules.dep, and depmod may be missing) into load order;
# prints the module paths, one per line.
module_order() {
    local mdir=$1 f n
    declare -A path=() seen=()
    local -a order=()
    while read -r f; do
        n=${f##*/}
        n=${n%%.ko*}
        path[${n//-/_}]=$f
    done < <(find "$mdir/kernel" -name '*.ko*')
    visit() {
        local n=${1//-/_} d
        [ -n "${seen[$n]:-}" ] && return
        seen[$n]=1
        local f=${path[$n]:-}
        if [ -z "$f" ]; then
            grep -q "/$1\.ko\$\|/$n\.ko\$" "$mdir/modules.builtin" ||
                die "module $1 neither in the package nor built in"
            return # built into this kernel
        fi
        for d in $(mod_cat "$f" | tr '\0' '\n' | sed -n 's/^depends=//p' | head -1 | tr ',' ' '); do
            visit "$d"
        done
        order+=("$f")
    }
    local m
    for m in "${MODULES[@]}"; do visit "$m"; done
    printf '%s\n' "${order[@]}"
}

# The guest's /init (busybox sh). Job parameters come from /job.sh (appended per run).
guest_init() {
    cat <<'EOF'
#!/bin/busybox sh
/bin/busybox mkdir -p /bin /sbin /usr/bin /usr/sbin /proc /sys /dev /host
/bin/busybox --install -s
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
fail() { echo "vcan-vm guest: $*"; echo "VCAN-VM-EXIT=125 $VCAN_VM_NONCE"; poweroff -f; }
. /job.sh
for m in $(cat /modules/order); do
    insmod "/modules/$m" || fail "insmod $m"
done
ip link set lo up
ip link add dev vcan0 type vcan || fail "ip link add vcan0"
ip link set up vcan0 || fail "ip link set up vcan0"
mkdir -p /hostro /rw
mount -t 9p -o trans=virtio,version=9p2000.L,msize=512000,cache=loose,ro hostroot /hostro ||
    fail "mount host root over 9p"
# A throwaway writable layer (RAM) over the read-only host root, so that commands which
# write beside their files (cargo's lock file in target/) work; nothing reaches the host.
overlay=1
mount -t tmpfs rw /rw && mkdir -p /rw/upper /rw/work &&
    mount -t overlay overlay -o lowerdir=/hostro,upperdir=/rw/upper,workdir=/rw/work /host ||
    { echo "vcan-vm guest: no overlay, host root read-only"; mount --bind /hostro /host; overlay=0; }
mount -t proc proc /host/proc
mount -t sysfs sys /host/sys
mount -t devtmpfs dev /host/dev
mkdir -p /host/dev/shm /host/dev/pts
mount -t tmpfs shm /host/dev/shm
mount -t devpts devpts /host/dev/pts
# The overlay already makes /tmp writable and keeps the host's files there visible (a
# checkout under /tmp, as CI may use, must stay reachable); only a read-only root needs a
# fresh tmpfs.
if [ "$overlay" = 0 ]; then
    mount -t tmpfs tmp /host/tmp
    chmod 1777 /host/tmp
fi
[ -d /host/run ] && mount -t tmpfs run /host/run
chmod 1777 /host/dev/shm
echo "VCAN-VM-BEGIN $VCAN_VM_NONCE"
# Through a pipe, not the console tty: what the command prints is read by the host (no
# colours, no tty handling); stderr joins stdout in order.
{
    chroot /host /bin/sh -c 'cd "$0" && exec "$@"' "$VCAN_VM_CWD" "$@"
    echo $? >/rc
} 2>&1 </dev/null | cat
rc=$(cat /rc 2>/dev/null || echo 126)
sync
echo "VCAN-VM-EXIT=$rc $VCAN_VM_NONCE"
poweroff -f
EOF
}

build_initramfs() {
    local img="$cache/initramfs.cpio.gz"
    # Rebuilt when missing, or when this script (the init, the module list) changed.
    if [ -f "$img" ] && [ "$img" -nt "${BASH_SOURCE[0]}" ] && [ "$img" -nt "$cache/kernel/vmlinuz" ]; then
        return 0
    fi
    log "building initramfs"
    local mdir="$cache/kernel/modules" st="$cache/initramfs.d"
    rm -rf "$st"
    mkdir -p "$st/bin" "$st/modules"
    cp /bin/busybox "$st/bin/busybox"
    local m base order=() paths
    paths=$(module_order "$mdir")
    while read -r m; do
        base=${m##*/}
        base=${base%%.ko*}.ko
        mod_cat "$m" >"$st/modules/$base"
        order+=("$base")
    done <<<"$paths"
    printf '%s\n' "${order[@]}" >"$st/modules/order"
    guest_init >"$st/init"
    chmod +x "$st/init"
    (cd "$st" && find . | cpio -o -H newc --quiet | gzip -1) >"$img.tmp"
    mv "$img.tmp" "$img"
    rm -rf "$st"
    log "modules: ${order[*]}"
}

setup() {
    mkdir -p "$cache"
    install_packages
    fetch_kernel
    choose_boot_image
    build_initramfs
    log "ready: $(cat "$cache/kernel/package") ($(cat "$cache/kernel/version")) in $cache"
}

ready() {
    [ -f "$cache/kernel/boot" ] && [ -f "$cache/initramfs.cpio.gz" ] &&
        [ "$cache/initramfs.cpio.gz" -nt "${BASH_SOURCE[0]}" ] &&
        qemu_bin >/dev/null
}

# ------------------------------------------------------------------------------ run --

# Single-quotes a value for sh.
q() { printf "'%s'" "${1//\'/\'\\\'\'}"; }

host_has_vcan() {
    ip link show vcan0 >/dev/null 2>&1 && return 0
    { ip link add dev vcan0 type vcan && ip link set up vcan0; } >/dev/null 2>&1
}

run() {
    local force_vm=0 no_setup=0 extra=()
    while [ $# -gt 0 ]; do
        case $1 in
        --force-vm) force_vm=1 ;;
        --no-setup) no_setup=1 ;;
        -e) extra+=("$2"); shift ;;
        -e*) extra+=("${1#-e}") ;;
        --) shift; break ;;
        *) die "unknown run option $1 (command goes after --)" ;;
        esac
        shift
    done
    [ $# -gt 0 ] || die "usage: $0 run [--force-vm] [-e NAME[=VALUE]] -- CMD [ARGS...]"
    export FLEXID_VCAN=${FLEXID_VCAN:-vcan0}
    local e
    for e in "${extra[@]}"; do
        case $e in *=*) export "${e%%=*}=${e#*=}" ;; esac
    done

    if [ "$force_vm" = 0 ] && host_has_vcan; then
        log "this kernel has vcan: running directly, no VM"
        ip link set up vcan0 2>/dev/null || true
        exec "$@"
    fi

    if ! ready; then
        [ "$no_setup" = 0 ] || die "not set up: run scripts/vcan-vm.sh setup"
        setup
    fi

    # The job: working directory, environment and command, as sh for the guest's init.
    local job
    job=$(mktemp -d "${TMPDIR:-/tmp}/vcan-vm.XXXXXX")
    trap 'rm -rf "$job"' EXIT
    # A per-run nonce on the marker lines: the command's own output cannot fake them.
    local nonce="$$-$RANDOM$RANDOM"
    {
        echo "VCAN_VM_CWD=$(q "$PWD")"
        echo "VCAN_VM_NONCE=$nonce"
        local name names
        names=$(compgen -e | grep -E '^(FLEXID_|RUST_|CARGO_TERM_)|^(CI|NO_COLOR|TERM|PATH|HOME|USER)$' || true)
        for e in "${extra[@]}"; do names+=$'\n'"${e%%=*}"; done
        for name in $(sort -u <<<"$names"); do
            [ -n "${!name+x}" ] && echo "export $name=$(q "${!name}")"
        done
        printf 'set --'
        local a
        for a in "$@"; do printf ' %s' "$(q "$a")"; done
        echo
    } >"$job/job.sh"
    (cd "$job" && echo job.sh | cpio -o -H newc --quiet | gzip -1) >"$job/job.cpio.gz"
    # The kernel unpacks concatenated archives in order: base initramfs, then the job.
    cat "$cache/initramfs.cpio.gz" "$job/job.cpio.gz" >"$job/initrd"

    local verbose=${VCAN_VM_VERBOSE:-0} consolelog="$cache/last-console.log"
    local t0=$SECONDS
    log "booting VM ($(cat "$cache/kernel/version"), ${mem} MiB, ${smp} vCPU, TCG, timeout ${timeout_s}s)"
    # The console (ttyS0) is the serial port on stdio; kernel messages are kept quiet.
    # Everything up to VCAN-VM-BEGIN is boot noise (shown with VCAN_VM_VERBOSE=1 and,
    # when the boot fails, from target/vcan-vm/last-console.log).
    local rc_file="$job/rc" status=0
    set +e
    qemu_cmd
    timeout -k 10 "$timeout_s" "${QEMU_CMD[@]}" \
        -accel tcg -m "$mem" -smp "$smp" \
        -nodefaults -nographic -monitor none -serial stdio -no-reboot \
        -kernel "$cache/kernel/$(cat "$cache/kernel/boot")" -initrd "$job/initrd" \
        -append "console=ttyS0 quiet loglevel=3 panic=-1 rdinit=/init ${VCAN_VM_APPEND:-}" \
        -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
        </dev/null 2>&1 |
        tee "$consolelog" | {
        begun=0
        while IFS= read -r line || [ -n "$line" ]; do
            line=${line%$'\r'} # the serial console ends lines with CR LF
            case $line in
            *"VCAN-VM-BEGIN $nonce")
                begun=1
                log "booted in $((SECONDS - t0)) s"
                continue
                ;;
            "VCAN-VM-EXIT="*" $nonce")
                line=${line#VCAN-VM-EXIT=}
                echo "${line% *}" >"$rc_file"
                begun=0 # what follows is the power-off
                continue
                ;;
            esac
            if [ "$begun" = 1 ] || [ "$verbose" = 1 ]; then printf '%s\n' "$line"; fi
        done
    }
    status=${PIPESTATUS[0]}
    set -e
    if [ "$status" = 124 ] || [ "$status" = 137 ]; then
        log "VM timed out after ${timeout_s}s (VCAN_VM_TIMEOUT)"
        exit 124
    fi
    if [ ! -s "$rc_file" ]; then
        log "VM ended (qemu status $status) without an exit code; console tail:"
        tail -n 40 "$consolelog" >&2
        exit 125
    fi
    local rc
    rc=$(cat "$rc_file")
    log "command exited $rc; VM total $((SECONDS - t0)) s"
    exit "$rc"
}

case ${1:-} in
setup) setup ;;
run) shift; run "$@" ;;
clean) rm -rf "$cache" ;;
*)
    sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//' >&2
    exit 2
    ;;
esac
