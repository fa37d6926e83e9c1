#!/bin/bash
# Run a command inside a throwaway qemu VM whose kernel has vcan, against the
# host's own root filesystem.  For machines whose kernel has no CAN at all.
#
# Usage: tests/vm/run_in_vm.sh [--ifaces "vcan0:72 vcan1:72 vcan2:16"] -- CMD [ARGS...]
#
# Each --ifaces entry is NAME:MTU (72 = CAN FD, 16 = classic CAN); they are
# created and set up before CMD starts.  CMD runs chrooted into the host root
# (9p, read-only on the host side; an in-VM overlay makes it writable, and
# those writes are discarded), in the host's $PWD, with only PATH,
# HOME=/tmp/home, PYTHONDONTWRITEBYTECODE=1, CANOPENFD_* and CANOPENFD_IN_VM=1
# in its environment.  Its stdout+stderr (merged) stream live to our stdout;
# we exit with its status.  VM failures exit 125, a timeout exits 124.
#
# Environment:
#   CANOPENFD_VM_TIMEOUT    overall limit in seconds (default 1500)
#   CANOPENFD_VM_VERBOSE=1  copy the VM console (kernel + init log) to stderr
#   CANOPENFD_VM_KERNEL     kernel version to boot (default: newest with vcan)
#   CANOPENFD_VM_SMP, CANOPENFD_VM_MEM   CPUs (default min(nproc,2)), MiB (2048)
#   CANOPENFD_VM_CPU        qemu -cpu model (default max)
#   CANOPENFD_VM_9P_CACHE   9p cache mode for the host root (default loose)
#   CANOPENFD_VM_OVERLAY=0  read-only root + tmpfs /tmp instead of the overlay
#   CANOPENFD_VM_APPEND, CANOPENFD_VM_QEMU_ARGS   extra kernel / qemu arguments
#
# The whole script is one function so that editing this file while a run is
# in progress cannot confuse bash (it reads scripts incrementally).
set -euo pipefail

main() {
    HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
    IFACES="vcan0:72 vcan1:72 vcan2:16"
    TIMEOUT=${CANOPENFD_VM_TIMEOUT:-1500}
    CACHE_DIR=${XDG_CACHE_HOME:-${HOME:-/root}/.cache}/canopenfd-vm
    # Modules to load in the VM; their dependencies come from modules.dep.
    MODULES="virtio_pci 9pnet_virtio 9p overlay can can-raw vcan"
    APT_PACKAGES="qemu-system-x86 linux-image-amd64 busybox-static"

    parse_args "$@"
    shift $((ARGS_USED))
    ensure_deps
    KVER=$(find_kernel)
    MODDIR=/lib/modules/$KVER
    BUSYBOX=$(find_busybox)
    mkdir -p "$CACHE_DIR"
    prepare_kernel
    prepare_initramfs

    WORK=$(mktemp -d "${TMPDIR:-/tmp}/canopenfd-vm.XXXXXX")
    QPID=
    trap cleanup EXIT
    trap 'msg "interrupted"; exit 130' INT TERM HUP
    mkdir "$WORK/share"
    write_job "$@"
    boot_vm
}

msg() { echo "run_in_vm: $*" >&2; }
die() {
    msg "error: $*"
    exit 125
}
usage() { die "$1 (usage: $0 [--ifaces \"vcan0:72 vcan1:72 vcan2:16\"] -- CMD [ARGS...])"; }

parse_args() {
    ARGS_USED=0
    while [[ $# -gt 0 ]]; do
        case $1 in
        --ifaces)
            [[ $# -ge 2 ]] || usage "--ifaces needs an argument"
            IFACES=$2
            shift 2
            ARGS_USED=$((ARGS_USED + 2))
            ;;
        --ifaces=*)
            IFACES=${1#*=}
            shift
            ARGS_USED=$((ARGS_USED + 1))
            ;;
        --)
            ARGS_USED=$((ARGS_USED + 1))
            shift
            break
            ;;
        *) usage "unexpected argument '$1'" ;;
        esac
    done
    [[ $# -gt 0 ]] || usage "no command given"
    local spec
    for spec in $IFACES; do
        [[ $spec =~ ^[A-Za-z0-9_.-]{1,15}:[0-9]+$ ]] || usage "bad --ifaces entry '$spec' (want NAME:MTU)"
    done
    [[ $TIMEOUT =~ ^[0-9]+$ ]] || die "CANOPENFD_VM_TIMEOUT must be a number of seconds"
}

# --- dependencies ------------------------------------------------------------

# Newest installed kernel that ships vcan (or CANOPENFD_VM_KERNEL).
find_kernel() {
    local v
    if [[ -n ${CANOPENFD_VM_KERNEL:-} ]]; then
        echo "$CANOPENFD_VM_KERNEL"
        return
    fi
    for v in $(ls /boot 2> /dev/null | sed -n 's/^vmlinuz-//p' | sort -rV); do
        if compgen -G "/lib/modules/$v/kernel/drivers/net/can/vcan.ko*" > /dev/null; then
            echo "$v"
            return
        fi
    done
}

# True if the x86-64 ELF file $1 has no PT_INTERP program header, i.e. needs
# no dynamic loader.  (ldd is not reliable for static-pie binaries.)
is_static_elf() {
    local f=$1 phoff phentsize phnum i
    [[ $(head -c 4 "$f" | od -An -c | tr -d ' ') == 177ELF ]] || return 1
    phoff=$(od -An -t u8 -j 32 -N 8 "$f")
    phentsize=$(od -An -t u2 -j 54 -N 2 "$f")
    phnum=$(od -An -t u2 -j 56 -N 2 "$f")
    for ((i = 0; i < phnum; i++)); do
        [[ $(od -An -t u4 -j $((phoff + i * phentsize)) -N 4 "$f") -ne 3 ]] || return 1
    done
}

# The initramfs has no libc, so busybox must be the static build.
find_busybox() {
    local b
    for b in /bin/busybox /usr/bin/busybox; do
        if [[ -x $b ]] && is_static_elf "$b"; then
            echo "$b"
            return
        fi
    done
}

deps_ok() {
    command -v qemu-system-x86_64 > /dev/null && [[ -n $(find_kernel) ]] && [[ -n $(find_busybox) ]]
}

ensure_deps() {
    deps_ok && return
    [[ $(id -u) -eq 0 ]] || die "need qemu-system-x86_64, a kernel with vcan and a static busybox; as root: apt-get install $APT_PACKAGES"
    msg "installing $APT_PACKAGES ..."
    # Another apt/dpkg run (e.g. provisioning) may hold the lock: wait for it.
    while pgrep -x apt-get > /dev/null || pgrep -x dpkg > /dev/null; do sleep 5; done
    export DEBIAN_FRONTEND=noninteractive
    apt-get update >&2 || die "apt-get update failed"
    # shellcheck disable=SC2086
    apt-get install -y $APT_PACKAGES >&2 || die "apt-get install failed"
    deps_ok || die "dependencies still missing after apt-get install"
}

# --- kernel ------------------------------------------------------------------

# Under TCG the kernel's own xz decompressor takes ~5 s.  Unpack vmlinux once
# on the host and boot it through its PVH entry point instead (no firmware
# real-mode setup, no decompression).  Falls back to the bzImage.
prepare_kernel() {
    local bz=/boot/vmlinuz-$KVER magic off out=$CACHE_DIR/vmlinux-$KVER
    [[ -r $bz ]] || die "cannot read $bz"
    KERNEL=$bz
    grep -qx 'CONFIG_PVH=y' "/boot/config-$KVER" 2> /dev/null || return 0
    if [[ ! -s $out ]]; then
        for magic in '\xfd7zXZ\x00:xz -dc --single-stream' '\x28\xb5\x2f\xfd:zstd -qdc' '\x1f\x8b\x08:gzip -dc'; do
            off=$(LC_ALL=C grep -obUaP "${magic%%:*}" "$bz" 2> /dev/null | head -1 | cut -d: -f1) || true
            [[ -n $off ]] || continue
            # gzip/zstd complain about the trailing bzImage bytes; ignore that.
            tail -c +$((off + 1)) "$bz" | ${magic#*:} > "$out.tmp.$$" 2> /dev/null || true
            if [[ $(head -c 4 "$out.tmp.$$" | od -An -c | tr -d ' ') == 177ELF ]]; then
                mv "$out.tmp.$$" "$out"
                break
            fi
        done
        rm -f "$out.tmp.$$"
    fi
    [[ -s $out ]] && KERNEL=$out || msg "note: cannot unpack $bz, booting it as is (slower)"
}

# --- initramfs (cached per kernel version) -----------------------------------

# Collect module paths (relative to $MODDIR) in load order, dependencies first.
add_module_path() {
    local path=$1 line d
    [[ -z ${SEEN[$path]:-} ]] || return 0
    SEEN[$path]=1
    line=$(grep -m1 "^$path:" "$MODDIR/modules.dep") || return 0
    for d in ${line#*:}; do add_module_path "$d"; done
    MOD_ORDER+=("$path")
}
resolve_modules() {
    local m re line
    declare -gA SEEN=()
    MOD_ORDER=()
    for m in $MODULES; do
        re="(^|/)${m//[-_]/[-_]}\\.ko(\\.(xz|gz|zst))?"
        if grep -qE "$re\$" "$MODDIR/modules.builtin" 2> /dev/null; then
            msg "note: module $m is built into $KVER"
        elif line=$(grep -m1 -E "$re:" "$MODDIR/modules.dep"); then
            add_module_path "${line%%:*}"
        else
            msg "warning: module $m not found for $KVER"
        fi
    done
}

build_initramfs() {
    local out=$1 root p base
    root=$(mktemp -d)
    mkdir -p "$root/bin" "$root/lib/modules"
    cp "$BUSYBOX" "$root/bin/busybox"
    cp "$HERE/vm_init.sh" "$root/init"
    chmod 755 "$root/init"
    : > "$root/modules.order"
    for p in "${MOD_ORDER[@]}"; do
        base=$(basename "$p")
        # busybox insmod cannot read compressed modules: unpack them here.
        case $p in
        *.ko.xz) xz -dc "$MODDIR/$p" > "$root/lib/modules/${base%.xz}" ;;
        *.ko.zst) zstd -qdc "$MODDIR/$p" > "$root/lib/modules/${base%.zst}" ;;
        *.ko.gz) gzip -dc "$MODDIR/$p" > "$root/lib/modules/${base%.gz}" ;;
        *) cp "$MODDIR/$p" "$root/lib/modules/$base" ;;
        esac
        echo "${base%.ko*}.ko" >> "$root/modules.order"
    done
    # Uncompressed cpio (~3 MB): the kernel would decompress slowly under TCG.
    (cd "$root" && find . | LC_ALL=C sort | "$BUSYBOX" cpio -o -H newc 2> /dev/null) > "$out.tmp.$$"
    mv "$out.tmp.$$" "$out" # atomic, so concurrent runs are safe
    rm -rf "$root"
}

prepare_initramfs() {
    # Key: kernel version plus a hash of the init script, module list and
    # busybox, so editing any of them rebuilds automatically.
    local key
    key=$( (cat "$HERE/vm_init.sh" "$BUSYBOX"; echo "$MODULES") | sha256sum | cut -c1-12)
    INITRD=$CACHE_DIR/initramfs-$KVER-$key.cpio
    [[ -s $INITRD ]] && return
    resolve_modules
    msg "building $INITRD (${#MOD_ORDER[@]} modules)"
    build_initramfs "$INITRD"
    # Drop stale builds for this kernel (but not one a parallel run is using
    # right now: only those older than a day).
    find "$CACHE_DIR" -maxdepth 1 -name "initramfs-$KVER-*.cpio" ! -name "${INITRD##*/}" -mtime +1 -delete 2> /dev/null || true
}

# --- per-run share: config in, exit status out -------------------------------

cleanup() {
    [[ -z ${QPID:-} ]] || kill "$QPID" 2> /dev/null || true
    rm -rf "$WORK"
}

# POSIX-sh single quoting: the job runs under the host's /bin/sh.
q() { printf "'%s'" "${1//\'/\'\\\'\'}"; }

write_job() {
    local vm_path=$PATH pybin name a
    {
        echo "IFACES=$(q "$IFACES")"
        echo "P9CACHE=$(q "${CANOPENFD_VM_9P_CACHE:-loose}")"
        echo "OVERLAY=$(q "${CANOPENFD_VM_OVERLAY:-1}")"
    } > "$WORK/share/config"

    # pyenv shims are bash scripts forking a dozen helpers per call: ~7 s
    # under TCG versus ~2 s for python itself.  Put the interpreter the shim
    # would pick here (same $PWD) first on PATH so the VM skips the shim.
    if [[ $(command -v python3 || true) == */shims/python3 ]] && command -v pyenv > /dev/null; then
        pybin=$(pyenv which python3 2> /dev/null || true)
        [[ -z $pybin ]] || vm_path=$(dirname "$pybin"):$PATH
    fi

    {
        echo "cd $(q "$PWD") || exit 125"
        echo "mkdir -p /tmp/home"
        printf 'exec env -i --'
        printf ' %s' "$(q "PATH=$vm_path")" "HOME=/tmp/home" "PYTHONDONTWRITEBYTECODE=1"
        while IFS= read -r name; do
            [[ $name == CANOPENFD_IN_VM ]] || printf ' %s' "$(q "$name=${!name}")"
        done < <(compgen -e | grep '^CANOPENFD_' || true)
        printf ' %s' "CANOPENFD_IN_VM=1"
        for a in "$@"; do printf ' %s' "$(q "$a")"; done
        echo
    } > "$WORK/share/job.sh"
}

# --- boot --------------------------------------------------------------------

show_console() {
    msg "---- VM console ----"
    sed 's/\r$//' "$WORK/console.log" >&2 2> /dev/null || true
    msg "--------------------"
}

boot_vm() {
    local nproc smp mem start qrc verbose=${CANOPENFD_VM_VERBOSE:-0}
    nproc=$(nproc)
    smp=${CANOPENFD_VM_SMP:-$((nproc < 2 ? nproc : 2))}
    mem=${CANOPENFD_VM_MEM:-2048}

    # /dev/kvm exists on our hosts but hangs (no nested virtualisation), so
    # always use TCG; multi-threaded TCG lets -smp 2 really use 2 host CPUs.
    # -cpu max: host binaries may use newer instructions than qemu64 has
    # (qemu64 or max,-avx,-avx2 may be a little faster; too noisy to tell).
    # ttyS0 = console -> log file; ttyS1 = command output -> our stdout.
    # shellcheck disable=SC2206
    local qemu=(
        qemu-system-x86_64
        -accel tcg,thread=multi -cpu "${CANOPENFD_VM_CPU:-max}" -smp "$smp" -m "$mem"
        -nodefaults -no-user-config -display none -monitor none -no-reboot
        -kernel "$KERNEL" -initrd "$INITRD"
        -append "console=ttyS0 quiet loglevel=3 panic=-1 mitigations=off ${CANOPENFD_VM_APPEND:-}"
        -virtfs "local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap"
        -virtfs "local,path=$WORK/share,mount_tag=results,security_model=none,multidevs=remap"
        -chardev "file,id=con,path=$WORK/console.log" -serial chardev:con
        -chardev stdio,id=out,signal=off -serial chardev:out
        ${CANOPENFD_VM_QEMU_ARGS:-}
    )

    start=$(date +%s)
    # In the background, so that a trapped Ctrl-C still runs cleanup.
    timeout -k 10 "$TIMEOUT" "${qemu[@]}" < /dev/null &
    QPID=$!
    qrc=0
    wait "$QPID" || qrc=$?
    QPID=

    if [[ -s $WORK/share/rc ]]; then
        [[ $verbose == 0 ]] || show_console
        exit "$(cat "$WORK/share/rc")"
    fi
    show_console
    if [[ $qrc -eq 124 || $qrc -eq 137 ]]; then
        msg "error: timed out after $TIMEOUT s (CANOPENFD_VM_TIMEOUT)"
        exit 124
    fi
    [[ ! -s $WORK/share/error ]] || die "VM setup failed: $(cat "$WORK/share/error")"
    die "VM stopped (qemu status $qrc, after $(($(date +%s) - start)) s) without reporting the command's exit status"
}

main "$@"
exit
