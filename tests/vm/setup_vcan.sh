#!/bin/bash
# Create and bring up vcan interfaces on a kernel that supports them (the
# direct counterpart of what run_in_vm.sh does inside its VM).  Idempotent.
#
# Usage: tests/vm/setup_vcan.sh [--ifaces "vcan0:72 vcan1:72 vcan2:16"]
# Each entry is NAME:MTU; 72 = CAN FD, 16 = classic CAN.  Needs root.
set -euo pipefail

IFACES="vcan0:72 vcan1:72 vcan2:16"
case ${1:-} in
--ifaces) IFACES=${2:?--ifaces needs an argument} ;;
--ifaces=*) IFACES=${1#*=} ;;
"") ;;
*)
    echo "usage: $0 [--ifaces \"vcan0:72 vcan1:72 vcan2:16\"]" >&2
    exit 2
    ;;
esac

modprobe -q vcan 2> /dev/null || true # may be built in, or autoloaded
for spec in $IFACES; do
    if [[ ! $spec =~ ^[A-Za-z0-9_.-]{1,15}:[0-9]+$ ]]; then
        echo "setup_vcan: bad --ifaces entry '$spec' (want NAME:MTU)" >&2
        exit 2
    fi
    name=${spec%%:*}
    mtu=${spec##*:}
    if ! ip link show dev "$name" > /dev/null 2>&1 && ! ip link add dev "$name" type vcan; then
        echo "setup_vcan: cannot create $name (no vcan in this kernel? use tests/vm/run_in_vm.sh)" >&2
        exit 1
    fi
    # vcan refuses MTU changes while the interface is up.
    ip link set dev "$name" down
    ip link set dev "$name" mtu "$mtu"
    ip link set dev "$name" up
done
