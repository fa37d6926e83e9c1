#!/bin/bash
# Raw SocketCAN frame rate on vcan0 (MTU 72): the yardstick for USDO throughput.
#
# Usage: bench/vcan_bench.sh [-n FRAMES] [-b BATCH] [-r RUNS] [IFACE]   (also: make -C bench vcan)
#
# Builds build/bench/raw_socketcan on this host, then runs it
#   (a) here, when this kernel has vcan (tests/vm/have_vcan.sh; needs root):
#       IFACE (default vcan0) is created with MTU 72 if it is missing;
#   (b) otherwise inside the test VM (tests/vm/run_in_vm.sh: qemu, TCG, 1-2 vCPUs,
#       the host root mounted read-only), where IFACE is created with MTU 72.
# The VM is much slower than the host: compare figures from the same place only.
# Fails with a message (exit 2) when neither is possible; never installs anything.
#
# Environment: CANOPENFD_VM_TIMEOUT (default here 600 s) and the other
# CANOPENFD_VM_* settings of tests/vm/run_in_vm.sh; CC, CFLAGS for the build.
set -euo pipefail

main() {
    cd "$(dirname "${BASH_SOURCE[0]}")/.."
    local root=$PWD bin=$PWD/build/bench/raw_socketcan iface=vcan0 a why missing=()

    # The interface is the one positional argument (options take a value).
    local args=("$@") i=0
    while ((i < ${#args[@]})); do
        a=${args[i]}
        case $a in
        -n | -b | -r) i=$((i + 2)) ;;
        -*) i=$((i + 1)) ;;
        *)
            iface=$a
            i=$((i + 1))
            ;;
        esac
    done
    [[ $iface =~ ^[A-Za-z0-9_.-]{1,15}$ ]] || die "bad interface name '$iface'"

    echo "vcan_bench: building $bin" >&2
    make -s -C "$root/bench" raw > /dev/null || die "build of bench/raw_socketcan failed"

    if why=$(bash tests/vm/have_vcan.sh -v 2>&1); then
        echo "vcan_bench: running on this kernel ($(uname -r), $(nproc) CPUs)" >&2
        if ! ip link show dev "$iface" > /dev/null 2>&1; then
            bash tests/vm/setup_vcan.sh --ifaces "$iface:72" || die "cannot create $iface"
        fi
        compiler_line
        exec "$bin" "$@"
    fi
    why=${why#have_vcan: }

    # (b) the VM: check what run_in_vm.sh needs, without installing it.
    command -v qemu-system-x86_64 > /dev/null || missing+=("qemu-system-x86_64 (qemu-system-x86)")
    vm_kernel || missing+=("a kernel in /boot with the vcan module (linux-image-amd64)")
    static_elf /bin/busybox || static_elf /usr/bin/busybox ||
        missing+=("a static busybox (busybox-static)")
    if ((${#missing[@]})); then
        die "cannot run the bench: this kernel has no vcan ($why) and the VM cannot start," \
            "missing: $(
                IFS=,
                echo "${missing[*]}"
            ); as root: apt-get install qemu-system-x86 linux-image-amd64 busybox-static"
    fi
    echo "vcan_bench: this kernel has no vcan ($why): running inside the qemu VM" \
        "(tests/vm/run_in_vm.sh; TCG, slower than the host)" >&2
    compiler_line
    local rc=0
    CANOPENFD_VM_TIMEOUT=${CANOPENFD_VM_TIMEOUT:-600} \
        bash tests/vm/run_in_vm.sh --ifaces "$iface:72" -- \
        sh -c 'echo "(VM: kernel $(uname -r), $(nproc) vCPU)"; exec "$0" "$@"' "$bin" "$@" || rc=$?
    case $rc in
    0) ;;
    124) die "the VM timed out (CANOPENFD_VM_TIMEOUT=${CANOPENFD_VM_TIMEOUT:-600} s)" ;;
    125) die "the VM could not run the bench (see run_in_vm's message above)" ;;
    *) exit "$rc" ;; # raw_socketcan's own status (1 = frames lost, 2 = interface problem)
    esac
}

# What run_in_vm.sh looks for (checked here so that it never starts installing).
vm_kernel() {
    local v
    for v in $(ls /boot 2> /dev/null | sed -n 's/^vmlinuz-//p'); do
        compgen -G "/lib/modules/$v/kernel/drivers/net/can/vcan.ko*" > /dev/null && return 0
    done
    return 1
}

# An x86-64 ELF without PT_INTERP (no dynamic loader needed).
static_elf() {
    local f=$1 phoff phentsize phnum i
    [[ -x $f && $(head -c 4 "$f" | od -An -c | tr -d ' ') == 177ELF ]] || return 1
    phoff=$(od -An -t u8 -j 32 -N 8 "$f")
    phentsize=$(od -An -t u2 -j 54 -N 2 "$f")
    phnum=$(od -An -t u2 -j 56 -N 2 "$f")
    for ((i = 0; i < phnum; i++)); do
        [[ $(od -An -t u4 -j $((phoff + i * phentsize)) -N 4 "$f") -ne 3 ]] || return 1
    done
}

compiler_line() {
    echo "compiler: $(${CC:-cc} --version | head -n 1), flags: ${CFLAGS:--O2}"
}

die() {
    echo "vcan_bench: error: $*" >&2
    exit 2
}

main "$@"
exit
