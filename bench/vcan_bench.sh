#!/bin/bash
# SocketCAN benches on vcan0 (MTU 72): the raw frame rate (raw_socketcan, the
# yardstick) and the USDO throughput (usdo_bench), in the same run.
#
# Usage: bench/vcan_bench.sh [-n FRAMES] [-b BATCH] [-r RUNS] [-t SECONDS] [-Q QUEUE] [-q] [-s]
#                            [-v] [--raw-only | --usdo-only] [--asan] [IFACE]
#        (also: make -C bench vcan VCAN_ARGS="...")
#   -n, -r   both programs (frames per raw run, runs per figure)
#   -b       raw_socketcan only (frames per sendmmsg/recvmmsg)
#   -t, -Q, -q, -s, -v   usdo_bench only (seconds per timed run, queue capacity, quick,
#            steering figure only, verbose)
#   --raw-only / --usdo-only   run one of the two
#   --asan   run the sanitizer build of usdo_bench (build/bench/usdo_bench_asan)
#
#        bench/vcan_bench.sh --sdo [sdo_bench.py options] [IFACE]   (make -C bench sdo)
#        bench/vcan_bench.sh --pdo [pdo_bench.py options] [IFACE]   (make -C bench pdo)
#        bench/vcan_bench.sh --soak [soak.py options]               (make -C bench soak)
#   every service at once on vcan0 (fd) and vcan2 (classic) for --minutes (bench/soak.py)
#   PDO latency and a sustained stream (bench/pdo_bench.py, ours vs python-canopen)
#   on an FD interface (MTU 72; --classic: MTU 16).
#   classic SDO throughput instead (bench/sdo_bench.py: our client and python-canopen's,
#   against our server and python-canopen's, next to raw_socketcan -c): IFACE (default
#   vcan0) is a classic interface (MTU 16); everything after --sdo goes to sdo_bench.py.
#
# Builds build/bench/raw_socketcan and build/bench/usdo_bench on this host, then
# runs them one after the other
#   (a) here, when this kernel has vcan (tests/vm/have_vcan.sh; needs root):
#       IFACE (default vcan0) is created with MTU 72 if it is missing;
#   (b) otherwise inside the test VM (tests/vm/run_in_vm.sh: qemu, TCG, 1-2 vCPUs,
#       the host root mounted read-only), where IFACE is created with MTU 72.
# The VM is much slower than the host: compare figures from the same place only.
# Fails with a message (exit 2) when neither is possible; never installs anything.
# Exit status: the first non-zero status of the two programs (1 = frames lost or
# transfers failed, 2 = interface problem), else 0.
#
# Environment: CANOPENFD_VM_TIMEOUT (default here 900 s) and the other
# CANOPENFD_VM_* settings of tests/vm/run_in_vm.sh; CC, CFLAGS for the build.
set -euo pipefail

main() {
    cd "$(dirname "${BASH_SOURCE[0]}")/.."
    local root=$PWD iface=vcan0 a why missing=() here=0 raw=1 usdo=1 asan=0
    local raw_args=() usdo_args=() args=("$@") i=0

    if [[ ${1:-} == --soak ]]; then
        shift
        run_soak "$root" "$@"
        return
    fi
    if [[ ${1:-} == --sdo || ${1:-} == --pdo ]]; then
        local kind=${1#--}
        shift
        run_python_bench "$kind" "$root" "$@"
        return
    fi

    # The interface is the one positional argument (options take a value).
    while ((i < ${#args[@]})); do
        a=${args[i]}
        case $a in
        -n | -r)
            [[ $((i + 1)) -lt ${#args[@]} ]] || die "$a needs a value"
            raw_args+=("$a" "${args[i + 1]}")
            usdo_args+=("$a" "${args[i + 1]}")
            i=$((i + 2))
            ;;
        -b)
            [[ $((i + 1)) -lt ${#args[@]} ]] || die "$a needs a value"
            raw_args+=("$a" "${args[i + 1]}")
            i=$((i + 2))
            ;;
        -t | -Q)
            [[ $((i + 1)) -lt ${#args[@]} ]] || die "$a needs a value"
            usdo_args+=("$a" "${args[i + 1]}")
            i=$((i + 2))
            ;;
        -q | -s | -v)
            usdo_args+=("$a")
            i=$((i + 1))
            ;;
        --raw-only) usdo=0 i=$((i + 1)) ;;
        --usdo-only) raw=0 i=$((i + 1)) ;;
        --asan) asan=1 i=$((i + 1)) ;;
        --here) here=1 i=$((i + 1)) ;; # internal: run now (inside the VM)
        -*) die "unknown option $a (see the head of bench/vcan_bench.sh)" ;;
        *)
            iface=$a
            i=$((i + 1))
            ;;
        esac
    done
    [[ $iface =~ ^[A-Za-z0-9_.-]{1,15}$ ]] || die "bad interface name '$iface'"
    ((raw || usdo)) || die "--raw-only and --usdo-only exclude each other"
    RAW_BIN=$root/build/bench/raw_socketcan
    USDO_BIN=$root/build/bench/usdo_bench
    ((asan == 0)) || USDO_BIN=$root/build/bench/usdo_bench_asan

    if ((here)); then
        run_both "$iface" "$raw" "$usdo"
        return
    fi

    echo "vcan_bench: building $RAW_BIN and $USDO_BIN" >&2
    make -s -C "$root/bench" raw "$USDO_BIN" > /dev/null || die "build of the benches failed"

    if why=$(bash tests/vm/have_vcan.sh -v 2>&1); then
        echo "vcan_bench: running on this kernel ($(uname -r), $(nproc) CPUs)" >&2
        if ! ip link show dev "$iface" > /dev/null 2>&1; then
            bash tests/vm/setup_vcan.sh --ifaces "$iface:72" || die "cannot create $iface"
        fi
        compiler_line
        run_both "$iface" "$raw" "$usdo"
        return
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
    echo "(host: $(cpu_name), $(nproc) CPUs, kernel $(uname -r))"
    local rc=0
    CANOPENFD_VM_TIMEOUT=${CANOPENFD_VM_TIMEOUT:-900} \
        bash tests/vm/run_in_vm.sh --ifaces "$iface:72" -- \
        bash "$root/bench/vcan_bench.sh" --here "$@" || rc=$?
    case $rc in
    0) ;;
    124) die "the VM timed out (CANOPENFD_VM_TIMEOUT=${CANOPENFD_VM_TIMEOUT:-900} s)" ;;
    125) die "the VM could not run the bench (see run_in_vm's message above)" ;;
    *) exit "$rc" ;; # the programs' own status (1 = frames lost / transfers failed, 2 = interface)
    esac
}

# --sdo / --pdo: build the C helper (raw_socketcan / pdo_flood), run
# bench/sdo_bench.py / bench/pdo_bench.py here (vcan + root) or in the VM.
run_python_bench() {
    local kind=$1 root=$2 a iface=vcan0 py rc=0 mtu=16 target=raw
    shift 2
    if [[ $kind == pdo ]]; then
        mtu=72 target=pdo_flood
    fi
    local skip=0
    for a in "$@"; do
        if ((skip)); then
            skip=0
            continue
        fi
        case $a in
        -t | -e | -n | -s | --sizes | --servers) skip=1 ;;
        --classic) mtu=16 ;;
        -*) ;;
        *) iface=$a ;;
        esac
    done
    [[ $iface =~ ^[A-Za-z0-9_.-]{1,15}$ ]] || die "bad interface name '$iface'"
    py=$(command -v python3) || die "python3 not found"
    echo "vcan_bench: building $root/build/bench ($target)" >&2
    make -s -C "$root/bench" "$target" > /dev/null || die "build of $target failed"
    if [[ ${CANOPENFD_IN_VM:-} == 1 ]] || bash tests/vm/have_vcan.sh 2> /dev/null; then
        if [[ ${CANOPENFD_IN_VM:-} != 1 ]] && ! ip link show dev "$iface" > /dev/null 2>&1; then
            bash tests/vm/setup_vcan.sh --ifaces "$iface:$mtu" || die "cannot create $iface"
        fi
        echo "(kernel $(uname -r), $(nproc) CPUs, $(cpu_name))"
        exec python3 "$root/bench/${kind}_bench.py" "$@"
    fi
    echo "vcan_bench: this kernel has no vcan: running bench/${kind}_bench.py inside the qemu" \
        "VM (tests/vm/run_in_vm.sh; TCG, far slower than the host)" >&2
    compiler_line
    echo "(host: $(cpu_name), $(nproc) CPUs, kernel $(uname -r))"
    CANOPENFD_VM_TIMEOUT=${CANOPENFD_VM_TIMEOUT:-1200} \
        bash tests/vm/run_in_vm.sh --ifaces "$iface:$mtu" -- \
        bash "$root/bench/vcan_bench.sh" "--$kind" "$@" || rc=$?
    case $rc in
    0) ;;
    124) die "the VM timed out (CANOPENFD_VM_TIMEOUT=${CANOPENFD_VM_TIMEOUT:-1200} s)" ;;
    125) die "the VM could not run the bench (see run_in_vm's message above)" ;;
    *) exit "$rc" ;;
    esac
    exit 0
}

# --soak: bench/soak.py on vcan0 (fd, MTU 72) and vcan2 (classic, MTU 16), here (vcan +
# root) or in the VM, which gets the soak's minutes plus 10 minutes.
run_soak() {
    local root=$1 minutes=60 prev="" a rc=0
    shift
    for a in "$@"; do
        [[ $prev != --minutes ]] || minutes=$a
        prev=$a
    done
    [[ $minutes =~ ^[0-9]+([.][0-9]+)?$ ]] || die "bad --minutes '$minutes'"
    if [[ ${CANOPENFD_IN_VM:-} == 1 ]] || bash tests/vm/have_vcan.sh 2> /dev/null; then
        if [[ ${CANOPENFD_IN_VM:-} != 1 ]]; then
            bash tests/vm/setup_vcan.sh --ifaces "vcan0:72 vcan2:16" || die "cannot create vcan"
        fi
        echo "(kernel $(uname -r), $(nproc) CPUs, $(cpu_name))"
        exec python3 "$root/bench/soak.py" "$@"
    fi
    echo "vcan_bench: this kernel has no vcan: running bench/soak.py inside the qemu VM" >&2
    echo "(host: $(cpu_name), $(nproc) CPUs, kernel $(uname -r))"
    CANOPENFD_VM_TIMEOUT=${CANOPENFD_VM_TIMEOUT:-$(awk -v m="$minutes" 'BEGIN { print int(m * 60) + 600 }')} \
        bash tests/vm/run_in_vm.sh --ifaces "vcan0:72 vcan2:16" -- \
        bash "$root/bench/vcan_bench.sh" --soak "$@" || rc=$?
    exit "$rc"
}

# Run raw_socketcan, then usdo_bench, on $1; exit with the first non-zero status.
run_both() {
    local iface=$1 raw=$2 usdo=$3 rc=0 r
    if [[ ${CANOPENFD_IN_VM:-} == 1 ]]; then
        echo "(VM: kernel $(uname -r), $(nproc) vCPU, $(cpu_name))"
    fi
    if ((raw)); then
        r=0
        "$RAW_BIN" "${raw_args[@]}" "$iface" || r=$?
        ((rc != 0)) || rc=$r
        ((r != 2)) || exit 2 # the interface cannot be used: usdo_bench could not either
        echo
    fi
    if ((usdo)); then
        r=0
        "$USDO_BIN" "${usdo_args[@]}" "$iface" || r=$?
        ((rc != 0)) || rc=$r
    fi
    exit "$rc"
}

cpu_name() {
    sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo 2> /dev/null | head -n 1
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
