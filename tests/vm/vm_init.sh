#!/bin/busybox sh
# /init (PID 1) of the canopenfd test VM; baked into the initramfs by run_in_vm.sh.
#
# Console (ttyS0) gets diagnostics; the command's stdout/stderr go to ttyS1,
# which qemu connects to the host's stdout.  Per-run settings (interfaces, the
# job script) arrive on the writable 9p share "results"; the exit status goes
# back there as /results/rc.

/bin/busybox mkdir -p /proc /sys /dev /bin /sbin /lower /rw /newroot /results
/bin/busybox --install -s /bin
export PATH=/bin:/sbin

mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev

log() { echo "canopenfd-vm: [$(cut -d' ' -f1 /proc/uptime)] $*" > /dev/ttyS0; }
die() {
    log "FATAL: $*"
    echo "$*" > /results/error 2> /dev/null
    sync
    poweroff -f
}

# Modules, dependencies first (order computed on the host from modules.dep).
# A failure is reported but not fatal: the mounts below show what's missing.
while read -r m; do
    [ -n "$m" ] || continue
    insmod "/lib/modules/$m" 2> /dev/null || log "insmod $m failed"
done < /modules.order
log "modules loaded"

# msize: the largest the virtio transport allows (default is 128 KiB), so
# big reads take fewer round trips.
P9OPTS=trans=virtio,version=9p2000.L,msize=512000
mount -t 9p -o "$P9OPTS,cache=none" results /results || die "cannot mount results share"
. /results/config

# Host root, read-only.  cache=loose lets the guest keep pages and dentries
# (the host tree does not change under a test run): measured fastest for
# Python imports (pytest --version ~5.5 s, vs ~6.6 s none, ~7.9 s mmap).
mount -t 9p -o "$P9OPTS,cache=$P9CACHE,ro" host /lower || die "cannot mount host root"

# Make the chroot writable without touching the host: overlay with a tmpfs
# upper layer.  Anything written inside the VM is discarded at poweroff.  If
# overlay is unavailable, fall back to the read-only root plus a tmpfs /tmp.
mount -t tmpfs -o mode=755 tmpfs /rw
mkdir -p /rw/upper /rw/work
if [ "$OVERLAY" = 1 ] &&
    mount -t overlay overlay -o lowerdir=/lower,upperdir=/rw/upper,workdir=/rw/work /newroot 2> /dev/null; then
    :
else
    [ "$OVERLAY" = 1 ] && log "overlay mount failed; root is read-only, /tmp is a tmpfs"
    mount --bind /lower /newroot
    mount -t tmpfs -o mode=1777 tmpfs /newroot/tmp
fi
mount -t proc proc /newroot/proc
mount -t sysfs sysfs /newroot/sys
mount -t devtmpfs devtmpfs /newroot/dev
mkdir -p /newroot/dev/pts /newroot/dev/shm
mount -t devpts -o newinstance,ptmxmode=0666 devpts /newroot/dev/pts
mount -t tmpfs -o mode=1777 tmpfs /newroot/dev/shm # multiprocessing semaphores
ln -sf /proc/self/fd /newroot/dev/fd 2> /dev/null
mount -t tmpfs -o mode=755 tmpfs /newroot/run

# Kernel module autoloading (e.g. can-bcm, can-isotp on socket()) must use
# the chroot's modprobe: the host has /lib/modules for this kernel.
printf '#!/bin/sh\nexec chroot /newroot /sbin/modprobe "$@"\n' > /sbin/chroot-modprobe
chmod 755 /sbin/chroot-modprobe
echo /sbin/chroot-modprobe > /proc/sys/kernel/modprobe

ip link set lo up
# busybox ip may not know "type vcan"; fall back to the host's iproute2.
for spec in $IFACES; do
    name=${spec%%:*}
    mtu=${spec##*:}
    { ip link add dev "$name" type vcan 2> /dev/null ||
        chroot /newroot ip link add dev "$name" type vcan; } || die "cannot create $name"
    ip link set dev "$name" mtu "$mtu" up || die "cannot set $name mtu $mtu up"
done
log "ready to run the command"

# Command output goes through a FIFO (not the tty itself) so the command sees
# a pipe like under CI, and so "raw" can stop the tty turning \n into \r\n.
stty -F /dev/ttyS1 raw -echo
mkfifo /out.fifo
# (kill -0 cannot tell when cat is done: an unreaped child stays a zombie.)
{ cat /out.fifo > /dev/ttyS1; touch /out.done; } &
chroot /newroot /bin/sh -c "$(cat /results/job.sh)" > /out.fifo 2>&1 < /dev/null
rc=$?
echo "$rc" > /results/rc
# Let the output drain; background processes that still hold the FIFO open
# are cut off after 3 s.
i=0
while [ ! -e /out.done ] && [ $i -lt 30 ]; do
    usleep 100000
    i=$((i + 1))
done
log "command exited with status $rc"
sync
poweroff -f
