#!/bin/bash
# Exit 0 if the running kernel can host the vcan tests directly (we are root,
# a vcan interface can be created, and AF_CAN raw sockets work); else 1.
# Used to decide between running pytest here and tests/vm/run_in_vm.sh.
# Pass -v to say why not.
verbose=0
[[ ${1:-} == -v ]] && verbose=1
no() {
    [[ $verbose == 0 ]] || echo "have_vcan: $*" >&2
    exit 1
}

[[ $(id -u) -eq 0 ]] || no "not root"
command -v ip > /dev/null || no "no ip(8) (iproute2)"
# Best effort: autoloading usually works, but not always inside containers.
modprobe -q vcan 2> /dev/null
modprobe -q can-raw 2> /dev/null

probe=canopenfd_probe # 15 chars, the IFNAMSIZ limit
ip link del dev "$probe" 2> /dev/null # left over from an interrupted run
ip link add dev "$probe" type vcan 2> /dev/null || no "cannot create a vcan interface"
ip link del dev "$probe" 2> /dev/null

if command -v python3 > /dev/null; then
    python3 -c 'import socket; socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()' 2> /dev/null ||
        no "cannot create an AF_CAN raw socket"
else
    # can-raw registers itself here once loaded.
    grep -q '^CAN_RAW ' /proc/net/protocols 2> /dev/null || no "AF_CAN raw sockets unavailable"
fi
exit 0
