/* pdo_flood: send one PDO CAN-ID as fast as a SocketCAN interface takes it.
 *
 *   pdo_flood [-c] [-l LEN] [-s SECONDS] [-r RATE] IFACE CAN_ID
 *
 * Frames carry a 32-bit little-endian sequence number in bytes 0..3 (the rest
 * a pattern), LEN bytes (default 8; with FD frames, -c absent, up to 64).
 * sendmmsg of 32 frames per call; a refused send (EAGAIN/ENOBUFS) waits for
 * POLLOUT (at most 1 ms) and tries the same frames again, so the sender never
 * drops one: the count it prints is what the interface took. -r limits the
 * rate (frames/s); default: as fast as the kernel takes them. Prints
 * "sent N frames in T s = R frames/s" on stdout; exit 2 when the interface
 * cannot be used. The receivers under test count what they got. */
#define _GNU_SOURCE
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

enum { BATCH = 32 };

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

static int usage(void)
{
    fprintf(stderr, "usage: pdo_flood [-c] [-l LEN] [-s SECONDS] [-r RATE] IFACE CAN_ID\n");
    return 2;
}

int main(int argc, char **argv)
{
    int classic = 0, opt;
    unsigned len = 8;
    double seconds = 10.0, rate = 0.0;
    while ((opt = getopt(argc, argv, "cl:s:r:")) != -1) {
        switch (opt) {
        case 'c': classic = 1; break;
        case 'l': len = (unsigned)strtoul(optarg, NULL, 0); break;
        case 's': seconds = strtod(optarg, NULL); break;
        case 'r': rate = strtod(optarg, NULL); break;
        default: return usage();
        }
    }
    if (argc - optind != 2 || len < 4 || len > (classic ? 8u : 64u)) {
        return usage();
    }
    const char *iface = argv[optind];
    uint32_t can_id = (uint32_t)strtoul(argv[optind + 1], NULL, 0) & CAN_SFF_MASK;
    int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd < 0) {
        fprintf(stderr, "pdo_flood: no CAN in this kernel: %s\n", strerror(errno));
        return 2;
    }
    int on = 1;
    if (!classic && setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
        fprintf(stderr, "pdo_flood: no CAN FD frames: %s\n", strerror(errno));
        return 2;
    }
    can_err_mask_t none = 0;
    setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0);   /* we read nothing */
    setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &none, sizeof none);
    struct sockaddr_can addr = {.can_family = AF_CAN, .can_ifindex = (int)if_nametoindex(iface)};
    if (addr.can_ifindex == 0 || bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        fprintf(stderr, "pdo_flood: interface %s cannot be used\n", iface);
        return 2;
    }
    struct canfd_frame frames[BATCH];
    struct iovec iov[BATCH];
    struct mmsghdr msgs[BATCH];
    memset(frames, 0, sizeof frames);
    memset(msgs, 0, sizeof msgs);
    size_t mtu = classic ? CAN_MTU : CANFD_MTU;
    for (int i = 0; i < BATCH; i++) {
        frames[i].can_id = can_id;
        frames[i].len = (uint8_t)len;
        frames[i].flags = classic ? 0 : CANFD_BRS;
        for (unsigned b = 4; b < len; b++) {
            frames[i].data[b] = (uint8_t)(b * 7u);
        }
        iov[i] = (struct iovec){.iov_base = &frames[i], .iov_len = mtu};
        msgs[i].msg_hdr.msg_iov = &iov[i];
        msgs[i].msg_hdr.msg_iovlen = 1;
    }
    uint32_t seq = 0;
    uint64_t sent = 0, refused = 0;
    double start = now_s(), end = start + seconds;
    while (now_s() < end) {
        unsigned want = BATCH;
        if (rate > 0.0) {
            double due = (now_s() - start) * rate - (double)sent;
            if (due < 1.0) {
                struct timespec nap = {0, 100000};
                nanosleep(&nap, NULL);
                continue;
            }
            want = due < BATCH ? (unsigned)due : BATCH;
        }
        for (unsigned i = 0; i < want; i++) {
            uint32_t s = seq + i;
            memcpy(frames[i].data, &s, 4);   /* little-endian hosts (x86, ARM) */
        }
        int n = sendmmsg(fd, msgs, want, MSG_DONTWAIT);
        if (n > 0) {
            seq += (uint32_t)n;
            sent += (uint64_t)n;
            continue;
        }
        if (errno != EAGAIN && errno != ENOBUFS && errno != EINTR) {
            fprintf(stderr, "pdo_flood: sendmmsg: %s\n", strerror(errno));
            return 1;
        }
        refused++;
        struct pollfd p = {.fd = fd, .events = POLLOUT};
        poll(&p, 1, 1);
    }
    double took = now_s() - start;
    printf("sent %llu frames in %.3f s = %.0f frames/s (refused %llu times, retried)\n",
           (unsigned long long)sent, took, (double)sent / took, (unsigned long long)refused);
    close(fd);
    return 0;
}
