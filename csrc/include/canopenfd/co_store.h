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

#include "canopenfd/co_line.h"
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

/* cffi:begin */
/* A parameter group's mode: the bits a 0x1010 read reports (CiA 301 bit 0
 * "saves on command", bit 1 "saves autonomously"); 0 = disabled. */
enum co_store_mode {
    CO_STORE_MODE_DISABLED = 0,
    CO_STORE_MODE_ON_COMMAND = 1,
    CO_STORE_MODE_AUTONOMOUS = 2,
    CO_STORE_MODE_BOTH = 3
};

/* When a group's saved values come back: at a reset node (and boot) only, or
 * at every reset communication too (a reset node includes one). */
enum co_store_reset {
    CO_STORE_RESET_NODE = 0,
    CO_STORE_RESET_COMMUNICATION = 1
};

/* One block of a declared parameter group: the entries with key (index << 8
 * | sub) in first_key..last_key. Rows with the same sub form one group (the
 * default manufacturer group has two blocks); blocks never overlap, so an
 * entry belongs to one group at most. Group sub-indices run 2, 3, ... without
 * gaps (0x1010/0x1011 sub 1 is "all"), CO_STORE_MAX_GROUPS at most: group
 * `sub` is bit (sub - 2) of a group mask. */
typedef struct co_store_group {
    uint32_t first_key;
    uint32_t last_key;
    uint8_t sub;
    uint8_t mode;      /* enum co_store_mode */
    uint8_t reset;     /* enum co_store_reset */
} co_store_group_t;
/* cffi:end */

enum {
    CO_STORE_MAX_GROUPS = 8,
    CO_STORE_MAX_GROUP_ROWS = 32
};

struct co_store;
/* Told after each autonomous save: abort 0 (saved) or the abort code of the
 * refused save (retried one interval later). */
typedef void (*co_store_saved_fn)(struct co_store *s, uint32_t abort, void *user);

typedef struct co_store_config {
    /* NULL: the default declaration, CiA 301's groups by index range: sub 2
     * communication (0x1000..0x1FFF, reset communication), sub 3 application
     * (0x6000..0x9FFF), sub 4 manufacturer (0x2000..0x5FFF, 0xA000..0xFFFF),
     * all on command. Not copied: it outlives the store. */
    const co_store_group_t *groups;
    uint8_t group_rows;
    /* The clock and timers of autonomous saves (needed when a group is
     * AUTONOMOUS): a write to a member marks its group changed; the changed
     * groups are saved min_interval_ms after the previous autonomous save at
     * the earliest, so a value written 1000 times a second costs one write of
     * the medium per interval. */
    co_line_t *line;
    uint32_t min_interval_ms;
    co_store_saved_fn autonomous_saved;   /* may be NULL */
    void *autonomous_user;
} co_store_config_t;

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
    const co_store_group_t *groups;
    uint8_t group_rows;
    uint8_t last_sub;              /* of the groups: 0x1010/0x1011 sub 1..last_sub are hooked */
    co_line_t *line;               /* autonomous saves: clock and timers, or NULL */
    uint64_t min_interval_us;
    uint64_t last_autonomous_us;   /* when the last autonomous save ran */
    bool autonomous_ran;           /* one ran already (last_autonomous_us is set) */
    uint8_t changed;               /* autonomous groups written since their last save */
    co_timer_t autonomous_timer;
    uint32_t autonomous_saves;     /* autonomous saves done */
    uint32_t autonomous_failures;  /* autonomous saves the backend refused (retried) */
    co_store_saved_fn autonomous_saved;
    void *autonomous_user;
} co_store_t;

/* Bytes of one image of this (sealed) OD. */
uint32_t co_store_image_need(const co_od_t *od);
/* The same plus what the entries co_od_add_live may still add could store
 * (a record per free entry slot, the free pool bytes): the image capacity of
 * a node whose OD grows at run time. */
uint32_t co_store_image_need_grown(const co_od_t *od);
/* buffer must hold at least 2 * co_store_image_need(od) (more lets images of
 * an older OD layout with more entries load instead of being TOO_BIG). Hooks
 * 0x1010 and 0x1011 sub 1..4 when they exist (the default groups, see
 * co_store_config_t: reads report "saves/restores on command"; writes need the
 * signature, otherwise CO_ABORT_DATA_STORE). False on a bad argument, an
 * unsealed OD, a small buffer or no subscription room. */
bool co_store_init(co_store_t *s, co_od_t *od, const co_store_backend_t *backend, void *user,
                   uint8_t *buffer, uint32_t buffer_size);
/* The same with declared groups (config NULL: co_store_init). False also
 * when the declaration is not valid: overlapping blocks, a block that is
 * empty or outside 0x1000..0xFFFF, sub-indices not 2, 3, ... without gaps,
 * an unknown mode or reset type, an AUTONOMOUS group without a line, or no
 * subscription room for the autonomous hook. */
bool co_store_init_config(co_store_t *s, co_od_t *od, const co_store_backend_t *backend,
                          void *user, uint8_t *buffer, uint32_t buffer_size,
                          const co_store_config_t *config);
/* Whether co_store_init_config accepts this declaration (line aside). */
bool co_store_groups_valid(const co_store_group_t *groups, uint8_t rows);
/* The group mask of the entry with this key (index << 8 | sub), 0 for none. */
uint8_t co_store_group_of(const co_store_t *s, uint32_t key);
/* The groups whose saved values a reset loads (reset_node: a reset node or
 * the boot, else a reset communication). */
uint8_t co_store_reset_groups(const co_store_t *s, bool reset_node);
/* A reset: co_store_load of co_store_reset_groups; entries of no declared
 * group load their defaults when their index range (co_od_group_of) is the
 * reset's (communication area at a reset communication, all at a reset node). */
co_store_status_t co_store_load_at_reset(co_store_t *s, bool reset_node);
/* Mark autonomous groups changed as a write to a member does (a value
 * changed behind the OD's back, or a save that did not reach the medium). */
void co_store_changed(co_store_t *s, uint8_t groups);
/* Unhook 0x1010/0x1011 (the OD outlives the store). */
void co_store_deinit(co_store_t *s);
/* 0x1010: save the CO_STORE entries of the groups in group_mask (the other
 * groups keep what was saved before; whatever the mode, but a disabled group
 * is never saved). 0 or an abort code. */
uint32_t co_store_save(co_store_t *s, uint8_t group_mask);
/* 0x1011: forget the saved values of the groups, so the next reset loads
 * their defaults. 0 or an abort code. */
uint32_t co_store_restore_defaults(co_store_t *s, uint8_t group_mask);
/* At a reset: load the defaults of the groups, then the saved values over
 * them. A damaged or foreign image leaves the defaults and says so. */
co_store_status_t co_store_load(co_store_t *s, uint8_t group_mask);

#endif
