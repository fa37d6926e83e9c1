/* Raw SocketCAN frame rate: the yardstick for USDO throughput.
 *
 * Two CAN_RAW sockets with CAN_RAW_FD_FRAMES on one interface (default vcan0):
 * one sends N (default 200 000) 64-byte CAN FD frames with BRS as fast as the
 * socket accepts them, the other receives them, interleaved on one thread
 * (both non-blocking). Every frame carries a sequence number (bytes 0..3, LE),
 * so the receiver counts each frame once and finds lost, duplicated or
 * reordered ones. The sender never drops a frame: on EAGAIN/ENOBUFS it waits
 * (poll, draining the receiver meanwhile) and sends the same frame again.
 *
 * Two figures, N frames per run, best of 3 runs (-r): one frame per
 * write()/read() call, and batches through sendmmsg()/recvmmsg() (what the
 * stack's SocketCAN driver uses). Lost frames are counted over all runs.
 * frames/s = N / (first send .. last receive); payload MB/s counts 60 bytes
 * per frame (the data of one USDO segment), so USDO bulk bytes/s divided by it
 * is the share of the raw frame rate USDO reaches.
 *
 *   raw_socketcan [-c] [-n FRAMES] [-b BATCH] [-r RUNS] [IFACE]
 *
 * -c: classic CAN instead: 8-byte classic frames (CAN_MTU 16), payload counted
 * as 7 bytes per frame (the data of one classic SDO segment / block segment),
 * the yardstick of bench/sdo_bench.py; the interface may have MTU 16 or 72.
 *
 * Exit status: 0 ok, 1 frames lost/duplicated/corrupted (the table is still
 * printed), 2 usage or interface problem (missing, not CAN, not CAN FD
 * capable, down, no CAN in the kernel). */
#define _GNU_SOURCE /* sendmmsg, recvmmsg */

#include <errno.h>
#include <net/if.h>
#include <net/if_arp.h>
#include <poll.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <linux/can.h>
#include <linux/can/raw.h>

#include "bench_util.h"

#define BENCH_ID 0x555u            /* CAN-ID of the bench frames (11-bit) */
#define PAYLOAD_PER_FRAME 60.0     /* USDO segment data bytes per 64-byte frame */
#define RCVBUF_BYTES (32 << 20)    /* receive buffer asked for (SO_RCVBUFFORCE) */
#define MAX_BATCH 256
#define STALL_S 5.0                /* no progress for this long: give up */
#define DRAIN_IDLE_MS 500          /* after the last send: wait this long for stragglers */

static const char *prog = "raw_socketcan";
static int classic;                   /* -c: classic 8-byte frames */
static unsigned frame_mtu = CANFD_MTU; /* bytes per frame written / read */
static unsigned frame_dlen = CANFD_MAX_DLEN;
static double payload = PAYLOAD_PER_FRAME;

typedef struct result {
    uint64_t sent;
    uint64_t received;    /* distinct sequence numbers seen */
    uint64_t duplicates;  /* a sequence number seen again */
    uint64_t reordered;   /* arrived after a higher sequence number */
    uint64_t corrupted;   /* wrong length, flags, id or payload */
    uint64_t retries;     /* sends refused with EAGAIN/ENOBUFS (then retried) */
    double seconds;
} result_t;

typedef struct bench {
    int tx;
    int rx;
    uint64_t frames;
    unsigned batch;
    unsigned runs;       /* per figure; the best one is shown */
    unsigned char *seen; /* one byte per sequence number */
    uint32_t highest;
    int any;
    uint64_t read_total; /* frames read in this run (good or not) */
    double last_rx;      /* time of the last read */
    result_t r;
} bench_t;

/* Print "raw_socketcan: <message>" on stderr and exit 2. */
static void fail(const char *fmt, ...) __attribute__((format(printf, 1, 2), noreturn));
static void fail(const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "%s: ", prog);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    exit(2);
}

/* ------------------------------------------------------------ sockets */

static int open_socket(const char *ifname, unsigned ifindex, int receiver)
{
    struct sockaddr_can addr;
    int on = 1;
    int s = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK, CAN_RAW);
    if (s < 0) {
        fail("socket(AF_CAN, CAN_RAW): %s - this kernel has no CAN support "
             "(bench/vcan_bench.sh runs the bench in a VM)", strerror(errno));
    }
    if (!classic && setsockopt(s, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
        fail("%s: CAN_RAW_FD_FRAMES refused (%s): kernel without CAN FD support",
             ifname, strerror(errno));
    }
    if (receiver) {
        struct can_filter f;
        int size = RCVBUF_BYTES;
        f.can_id = BENCH_ID;
        f.can_mask = CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK;
        if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f) < 0) {
            fail("CAN_RAW_FILTER: %s", strerror(errno));
        }
        /* FORCE needs CAP_NET_ADMIN; otherwise the plain one (capped by
         * net.core.rmem_max). */
        if (setsockopt(s, SOL_SOCKET, SO_RCVBUFFORCE, &size, sizeof size) < 0) {
            (void)setsockopt(s, SOL_SOCKET, SO_RCVBUF, &size, sizeof size);
        }
    } else {
        /* The sender receives nothing (an empty filter list). */
        if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0) < 0) {
            fail("CAN_RAW_FILTER: %s", strerror(errno));
        }
    }
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)ifindex;
    if (bind(s, (struct sockaddr *)&addr, sizeof addr) < 0) {
        fail("bind to %s: %s", ifname, strerror(errno));
    }
    return s;
}

/* Interface exists, is CAN, can carry CAN FD frames and is up; else exit 2. */
static unsigned check_interface(int s, const char *ifname)
{
    struct ifreq ifr;
    unsigned ifindex;

    if (strlen(ifname) >= IFNAMSIZ) {
        fail("interface name '%s' too long (at most %d characters)", ifname, IFNAMSIZ - 1);
    }
    ifindex = if_nametoindex(ifname);
    if (ifindex == 0) {
        fail("interface %s not found (%s)", ifname, strerror(errno));
    }
    memset(&ifr, 0, sizeof ifr);
    strcpy(ifr.ifr_name, ifname);
    if (ioctl(s, SIOCGIFHWADDR, &ifr) == 0 && ifr.ifr_hwaddr.sa_family != ARPHRD_CAN) {
        fail("%s is not a CAN interface", ifname);
    }
    if (ioctl(s, SIOCGIFMTU, &ifr) < 0) {
        fail("%s: cannot read the MTU: %s", ifname, strerror(errno));
    }
    if (!classic && ifr.ifr_mtu < (int)CANFD_MTU) {
        fail("%s: MTU %d, not CAN FD capable (needs MTU %d: ip link set %s mtu %d)", ifname,
             ifr.ifr_mtu, (int)CANFD_MTU, ifname, (int)CANFD_MTU);
    }
    if (ioctl(s, SIOCGIFFLAGS, &ifr) < 0) {
        fail("%s: cannot read the flags: %s", ifname, strerror(errno));
    }
    if (!(ifr.ifr_flags & IFF_UP)) {
        fail("%s is down (ip link set %s up)", ifname, ifname);
    }
    return ifindex;
}

/* ------------------------------------------------------------ frames */

static void make_frame(struct canfd_frame *f, uint32_t seq)
{
    unsigned i;
    memset(f, 0, sizeof *f);
    f->can_id = BENCH_ID;
    f->len = (uint8_t)frame_dlen;
    f->flags = classic ? 0 : CANFD_BRS;
    f->data[0] = (uint8_t)seq;
    f->data[1] = (uint8_t)(seq >> 8);
    f->data[2] = (uint8_t)(seq >> 16);
    f->data[3] = (uint8_t)(seq >> 24);
    for (i = 4; i < frame_dlen; i++) {
        f->data[i] = (uint8_t)(seq + i);
    }
}

static void check_frame(bench_t *b, const struct canfd_frame *f, ssize_t n)
{
    uint32_t seq;
    unsigned i;
    if (n != (ssize_t)frame_mtu || f->can_id != BENCH_ID || f->len != frame_dlen ||
        (!classic && !(f->flags & CANFD_BRS))) {
        b->r.corrupted++;
        return;
    }
    seq = (uint32_t)f->data[0] | ((uint32_t)f->data[1] << 8) | ((uint32_t)f->data[2] << 16) |
          ((uint32_t)f->data[3] << 24);
    if (seq >= b->frames) {
        b->r.corrupted++;
        return;
    }
    for (i = 4; i < frame_dlen; i++) {
        if (f->data[i] != (uint8_t)(seq + i)) {
            b->r.corrupted++;
            return;
        }
    }
    if (b->seen[seq]) {
        b->r.duplicates++;
        return;
    }
    b->seen[seq] = 1;
    b->r.received++;
    if (b->any && seq < b->highest) {
        b->r.reordered++;
    }
    if (!b->any || seq > b->highest) {
        b->highest = seq;
    }
    b->any = 1;
}

/* Read what waits on the receiver, at most `limit` frames (the frames sent
 * and not read yet: so no read ends in EAGAIN while the receiver keeps up);
 * returns the frames read. */
static uint64_t drain(bench_t *b, int batched, uint64_t limit)
{
    static struct canfd_frame frames[MAX_BATCH];
    static struct mmsghdr msgs[MAX_BATCH];
    static struct iovec iov[MAX_BATCH];
    uint64_t got = 0;
    while (got < limit) {
        if (batched) {
            unsigned i, want = b->batch;
            int n;
            if ((uint64_t)want > limit - got) {
                want = (unsigned)(limit - got);
            }
            for (i = 0; i < want; i++) {
                iov[i].iov_base = &frames[i];
                iov[i].iov_len = sizeof frames[i];
                memset(&msgs[i], 0, sizeof msgs[i]);
                msgs[i].msg_hdr.msg_iov = &iov[i];
                msgs[i].msg_hdr.msg_iovlen = 1;
            }
            n = recvmmsg(b->rx, msgs, want, MSG_DONTWAIT, NULL);
            if (n <= 0) {
                if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
                    fail("recvmmsg: %s", strerror(errno));
                }
                break;
            }
            for (i = 0; i < (unsigned)n; i++) {
                check_frame(b, &frames[i], (ssize_t)msgs[i].msg_len);
            }
            got += (uint64_t)n;
        } else {
            ssize_t n = read(b->rx, &frames[0], sizeof frames[0]);
            if (n < 0) {
                if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
                    fail("read: %s", strerror(errno));
                }
                break;
            }
            check_frame(b, &frames[0], n);
            got++;
        }
    }
    if (got > 0) {
        b->read_total += got;
        b->last_rx = now_s();
    }
    return got;
}

/* Frames sent and not read yet. */
static uint64_t outstanding(const bench_t *b, uint64_t sent)
{
    return sent > b->read_total ? sent - b->read_total : 0;
}

/* The sender was refused (EAGAIN/ENOBUFS): wait until it may be writable or
 * the receiver has frames (read here, so the receiver never holds the sender
 * up), at most 1 ms. */
static void wait_writable(bench_t *b, int batched, uint64_t sent)
{
    struct pollfd p[2];
    p[0].fd = b->tx;
    p[0].events = POLLOUT;
    p[1].fd = b->rx;
    p[1].events = POLLIN;
    b->r.retries++;
    if (poll(p, 2, 1) < 0 && errno != EINTR) {
        fail("poll: %s", strerror(errno));
    }
    drain(b, batched, outstanding(b, sent));
}

static int refused(int err)
{
    return err == EAGAIN || err == EWOULDBLOCK || err == ENOBUFS || err == EINTR;
}

/* Send b->frames frames (never dropping one) and read them back. */
static void run(bench_t *b, int batched)
{
    static struct canfd_frame frames[MAX_BATCH];
    static struct mmsghdr msgs[MAX_BATCH];
    static struct iovec iov[MAX_BATCH];
    uint64_t next = 0;
    double t0;

    drain(b, batched, UINT64_MAX); /* nothing stale from an earlier run */
    memset(b->seen, 0, (size_t)b->frames);
    memset(&b->r, 0, sizeof b->r);
    b->any = 0;
    b->highest = 0;
    b->read_total = 0;

    t0 = now_s();
    b->last_rx = t0;
    while (next < b->frames) {
        unsigned want = batched ? b->batch : 1, i;
        if ((uint64_t)want > b->frames - next) {
            want = (unsigned)(b->frames - next);
        }
        if (batched) {
            int n;
            for (i = 0; i < want; i++) {
                make_frame(&frames[i], (uint32_t)(next + i));
                iov[i].iov_base = &frames[i];
                iov[i].iov_len = frame_mtu;
                memset(&msgs[i], 0, sizeof msgs[i]);
                msgs[i].msg_hdr.msg_iov = &iov[i];
                msgs[i].msg_hdr.msg_iovlen = 1;
            }
            n = sendmmsg(b->tx, msgs, want, MSG_DONTWAIT);
            if (n < 0) {
                if (!refused(errno)) {
                    fail("sendmmsg: %s", strerror(errno));
                }
                wait_writable(b, batched, next);
            } else {
                next += (uint64_t)n; /* a partial batch: the rest goes again */
                if ((unsigned)n < want) {
                    wait_writable(b, batched, next);
                }
            }
        } else {
            ssize_t n;
            make_frame(&frames[0], (uint32_t)next);
            n = write(b->tx, &frames[0], frame_mtu);
            if (n < 0) {
                if (!refused(errno)) {
                    fail("write: %s", strerror(errno));
                }
                wait_writable(b, batched, next);
            } else if (n != (ssize_t)frame_mtu) {
                fail("write: short write (%ld of %u bytes)", (long)n, frame_mtu);
            } else {
                next++;
            }
        }
        if (drain(b, batched, outstanding(b, next)) == 0 && outstanding(b, next) > 0 &&
            now_s() - b->last_rx > STALL_S) {
            fprintf(stderr, "%s: nothing received for %.0f s (sent %llu, received %llu): "
                    "stalled\n", prog, STALL_S, (unsigned long long)next,
                    (unsigned long long)b->r.received);
            exit(2);
        }
    }
    b->r.sent = next;
    /* Stragglers: on vcan everything sent is queued already, a real
     * interface may still be sending. */
    while (b->r.received < b->frames) {
        struct pollfd p;
        int rc;
        p.fd = b->rx;
        p.events = POLLIN;
        rc = poll(&p, 1, DRAIN_IDLE_MS);
        if (rc < 0 && errno != EINTR) {
            fail("poll: %s", strerror(errno));
        }
        if (rc == 0) {
            break;
        }
        drain(b, batched, UINT64_MAX);
    }
    b->r.seconds = b->last_rx - t0;
}

/* ------------------------------------------------------------ output */

static void header(const char *ifname, const bench_t *b)
{
    printf("raw SocketCAN on %s: %s, sender and receiver socket on one "
           "thread, %llu frames per run, best of %u run%s\n\n", ifname,
           classic ? "8-byte classic CAN frames" : "64-byte CAN FD frames (BRS)",
           (unsigned long long)b->frames, b->runs, b->runs == 1 ? "" : "s");
    printf("%-40s %9s %8s %12s %12s %9s %7s\n", "figure", "frames", "time s", "frames/s",
           classic ? "MB/s @7 B" : "MB/s @60 B", "ns/frame", "lost");
    printf("%-40s %9s %8s %12s %12s %9s %7s\n", "------", "------", "------", "--------",
           "----------", "--------", "----");
}

/* Run one figure b->runs times; print the best run's figures and the problems
 * of all runs (lost = over all runs). Returns the count of bad frames. */
static uint64_t figure(bench_t *b, int batched, const char *what)
{
    result_t best, sum;
    double seconds, rate;
    uint64_t lost = 0;
    unsigned i;
    memset(&best, 0, sizeof best);
    memset(&sum, 0, sizeof sum);
    for (i = 0; i < b->runs; i++) {
        run(b, batched);
        lost += b->frames - b->r.received;
        sum.duplicates += b->r.duplicates;
        sum.reordered += b->r.reordered;
        sum.corrupted += b->r.corrupted;
        sum.retries += b->r.retries;
        /* best = most frames per second */
        if (i == 0 || (double)b->r.received * best.seconds > (double)best.received * b->r.seconds) {
            best = b->r;
        }
    }
    seconds = best.seconds > 0 ? best.seconds : 1e-9;
    rate = (double)best.received / seconds;
    printf("%-40s %9llu %8.3f %12.0f %12.2f %9.1f %7llu\n", what,
           (unsigned long long)best.received, best.seconds, rate, rate * payload / 1e6,
           seconds * 1e9 / (double)(best.received ? best.received : 1),
           (unsigned long long)lost);
    if (lost || sum.duplicates || sum.reordered || sum.corrupted) {
        printf("  ! in %u run%s: %llu lost, %llu duplicated, %llu reordered, %llu corrupted\n",
               b->runs, b->runs == 1 ? "" : "s", (unsigned long long)lost,
               (unsigned long long)sum.duplicates, (unsigned long long)sum.reordered,
               (unsigned long long)sum.corrupted);
    }
    if (sum.retries) {
        printf("  (sender refused %llu times with EAGAIN/ENOBUFS, waited and retried)\n",
               (unsigned long long)sum.retries);
    }
    fflush(stdout);
    return lost + sum.duplicates + sum.corrupted;
}

static void usage(void)
{
    fprintf(stderr, "usage: %s [-c] [-n FRAMES] [-b BATCH] [-r RUNS] [IFACE]   (defaults: -n "
            "200000 -b 32 -r 3 vcan0; -c = classic 8-byte frames)\n", prog);
    exit(2);
}

static unsigned long parse_number(const char *text, unsigned long low, unsigned long high)
{
    char *end;
    unsigned long v;
    errno = 0;
    v = strtoul(text, &end, 10);
    if (errno || end == text || *end || v < low || v > high) {
        usage();
    }
    return v;
}

int main(int argc, char **argv)
{
    const char *ifname = "vcan0";
    bench_t b;
    char label[64];
    unsigned ifindex;
    uint64_t bad = 0;
    int opt, probe;

    memset(&b, 0, sizeof b);
    b.frames = 200000;
    b.batch = 32;
    b.runs = 3;
    while ((opt = getopt(argc, argv, "cn:b:r:h")) != -1) {
        switch (opt) {
        case 'c':
            classic = 1;
            frame_mtu = CAN_MTU;
            frame_dlen = CAN_MAX_DLEN;
            payload = 7.0;
            break;
        case 'n':
            b.frames = parse_number(optarg, 1, 100000000ul);
            break;
        case 'b':
            b.batch = (unsigned)parse_number(optarg, 1, MAX_BATCH);
            break;
        case 'r':
            b.runs = (unsigned)parse_number(optarg, 1, 100);
            break;
        default:
            usage();
        }
    }
    if (optind < argc) {
        ifname = argv[optind++];
    }
    if (optind < argc) {
        usage();
    }

    probe = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (probe < 0) {
        fail("socket(AF_CAN, CAN_RAW): %s - this kernel has no CAN support "
             "(bench/vcan_bench.sh runs the bench in a VM)", strerror(errno));
    }
    ifindex = check_interface(probe, ifname);
    close(probe);

    b.seen = calloc((size_t)b.frames, 1);
    if (b.seen == NULL) {
        fail("out of memory");
    }
    b.rx = open_socket(ifname, ifindex, 1);
    b.tx = open_socket(ifname, ifindex, 0);

    header(ifname, &b);
    bad += figure(&b, 0, "write + read, 1 frame per call");
    snprintf(label, sizeof label, "sendmmsg + recvmmsg, %u per call", b.batch);
    bad += figure(&b, 1, label);

    close(b.tx);
    close(b.rx);
    free(b.seen);
    if (bad) {
        fprintf(stderr, "%s: frames were lost, duplicated or corrupted (see the table)\n", prog);
        return 1;
    }
    return 0;
}
