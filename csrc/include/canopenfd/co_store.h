/* Store and restore of parameters (0x1010 "save", 0x1011 "load") over a
 * pluggable backend that keeps one image. The image carries a magic, a format
 * version, a signature of the OD layout it was made for (information only) and
 * a CRC-32, so a damaged or foreign image is detected and the node starts from
 * defaults instead of garbage. Records carry key, type and length and are
 * applied one by one, so values survive a firmware update that adds or removes
 * entries (the format is described at the top of co_store.c). Atomicity (old
 * or new image after a power cut, never a mix) is the backend's promise: see
 * co_store_file.h. */
#ifndef CO_STORE_H
#define CO_STORE_H

#include "canopenfd/co_od.h"

/* cffi:begin */
typedef enum co_store_status {
    CO_STORE_OK = 0,
    CO_STORE_EMPTY = 1,        /* nothing saved yet */
    CO_STORE_DAMAGED = 2,      /* bad CRC, truncated, malformed records */
    CO_STORE_FOREIGN = 3,      /* other magic or format version (another OD
                                  layout is tolerated record by record) */
    CO_STORE_IO = 4,           /* the backend failed */
    CO_STORE_TOO_BIG = 5       /* larger than this OD's image can be */
} co_store_status_t;
/* cffi:end */

enum {
    CO_STORE_SAVE_SIGNATURE = 0x65766173,   /* "save", LSB first */
    CO_STORE_LOAD_SIGNATURE = 0x64616F6C    /* "load", LSB first */
};

typedef struct co_store_backend {
    /* Replace the saved image atomically. Returns CO_STORE_OK or CO_STORE_IO. */
    co_store_status_t (*save)(void *user, const uint8_t *image, uint32_t length);
    /* Read the saved image into image[0..capacity): CO_STORE_OK (*length set),
     * CO_STORE_EMPTY, CO_STORE_TOO_BIG or CO_STORE_IO. */
    co_store_status_t (*load)(void *user, uint8_t *image, uint32_t capacity, uint32_t *length);
} co_store_backend_t;

typedef struct co_store {
    co_od_t *od;
    const co_store_backend_t *backend;
    void *user;
    uint8_t *image;            /* caller storage, buffer_size / 2 bytes each: */
    uint8_t *previous;         /* the new image and the one saved before */
    uint32_t image_capacity;
    co_store_status_t last_load;   /* what the last load found (EMPTY before any) */
    uint32_t records_skipped;      /* records of the loaded groups the last load
                                      did not apply: entry missing or not
                                      CO_OD_STORE, other type, too long, or
                                      refused by co_od_check_value */
} co_store_t;

/* Bytes of one image of this (sealed) OD. */
uint32_t co_store_image_need(const co_od_t *od);
/* buffer must hold at least 2 * co_store_image_need(od) (more lets images of
 * an older OD layout with more entries load instead of being TOO_BIG). Hooks
 * 0x1010 and 0x1011 sub 1..4 when they exist (reads report "saves/restores on
 * command"; writes need the signature, otherwise CO_ABORT_DATA_STORE). False
 * on a bad argument, an unsealed OD, a small buffer or no subscription room. */
bool co_store_init(co_store_t *s, co_od_t *od, const co_store_backend_t *backend, void *user,
                   uint8_t *buffer, uint32_t buffer_size);
/* Unhook 0x1010/0x1011 (the OD outlives the store). */
void co_store_deinit(co_store_t *s);
/* 0x1010: save the CO_STORE entries of the groups in group_mask (the other
 * groups keep what was saved before). 0 or an abort code. */
uint32_t co_store_save(co_store_t *s, uint8_t group_mask);
/* 0x1011: forget the saved values of the groups, so the next reset loads
 * their defaults. 0 or an abort code. */
uint32_t co_store_restore_defaults(co_store_t *s, uint8_t group_mask);
/* At a reset: load the defaults of the groups, then the saved values over
 * them. A damaged or foreign image leaves the defaults and says so. */
co_store_status_t co_store_load(co_store_t *s, uint8_t group_mask);

#endif
