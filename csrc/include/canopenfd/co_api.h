/* The CANopen API of seed 004 (ESAcademy Recommended Practice "CANopen
 * API") in C: the host sees only a process image of at most 255 bytes and
 * asks the CANopen task for its identification, its status, its start
 * (InitCANopen) and for reads and writes of image bytes; the task tells the
 * host of NMT changes, of image bytes the network wrote (RPDO, SDO/USDO)
 * and of fatal errors through callbacks.
 *
 * It sits on the node assembly (co_stack): the caller sets up the line's
 * stack and an OD whose process image (co_od_reserve_image) holds the
 * entries added with co_od_add_in_image; InitCANopen creates and boots the
 * node over that OD. The image is the OD's own storage, so PDOs and SDO/USDO
 * work on it in the core, frame by frame, with no copy. Nothing is
 * allocated here; like the rest of the core it is called from the one
 * thread that runs the line. */
#ifndef CANOPENFD_CO_API_H
#define CANOPENFD_CO_API_H

#include "canopenfd/co_stack.h"

#include <stdbool.h>
#include <stdint.h>

/* Seed 004 §1.1: TRUE is FFh, FALSE is 00h. */
#define CO_API_TRUE 0xFFu
#define CO_API_FALSE 0x00u
/* The largest process image (seed 004 §3.1). */
#define CO_API_IMAGE_MAX 255u

/* GetStatus bits 0-1 (seed 004 §4.1.2). */
enum co_api_state {
    CO_API_STATE_INITIALISING = 0,
    CO_API_STATE_READY = 1,        /* waiting for InitCANopen */
    CO_API_STATE_OPERATING = 2
};

/* NMTChange values (seed 004 §4.2.1): the NMT states keep their CiA 301
 * values; these two are the resets. */
#define CO_API_NMT_RESET_NODE 0x81u
#define CO_API_NMT_RESET_COMMUNICATION 0x82u

/* FatalError codes: the seed leaves them to the implementation. */
enum co_api_fatal {
    CO_API_FATAL_BUS_OFF = 0x01,
    CO_API_FATAL_INTERFACE_DOWN = 0x02
};

/* The host's callbacks (each may be NULL), called from the line's thread. */
typedef struct co_api_callbacks {
    void (*nmt_change)(uint8_t nmt_state, void *user);
    /* image bytes offset..offset+length-1 were written by the network */
    void (*received_data)(uint8_t offset, uint8_t length, void *user);
    void (*fatal_error)(uint8_t code, void *user);
    /* InitCANopen's bit rate code 1..8 for the driver (the line's bit rate
     * is the driver's business); false refuses it. NULL: any code is taken. */
    bool (*set_bit_rate)(uint8_t bps, void *user);
} co_api_callbacks_t;

typedef struct co_api_config {
    uint8_t id[4];               /* GetID: manufacturer id (LE), minor, major version */
    uint8_t default_bps;         /* 1..8: InitCANopen with bps 0 */
    /* The node InitCANopen creates: node_id is the default (InitCANopen with
     * node-id 0); od is sealed and has the image; ind/user, when given, are
     * still called (the API hears the node first). */
    co_stack_node_config_t node;
    /* The image's initial content (co_od_image_size bytes; NULL: as the OD
     * holds it): copied in at co_api_init and at every reset node. Image
     * entries' defaults should be these bytes (a reset loads both). */
    const uint8_t *initial_image;
    const co_api_callbacks_t *cb;
    void *user;
} co_api_config_t;

typedef struct co_api {
    co_stack_t *stack;
    co_api_config_t config;
    co_node_indications_t node_ind;   /* the API's own, forwarding to config.node.ind */
    uint8_t bps;                 /* the bit rate code in use */
    bool started;
    bool own_reset;              /* InitCANopen's reset: no 81h for it */
    uint32_t refused_reads;      /* ReadProcessData / WriteProcessData that copied nothing */
    uint32_t refused_writes;
} co_api_t;

/* Ready to serve the host (GetStatus: READY) on `stack`, a line set up with
 * co_stack_init and no node yet. False when the configuration is wrong
 * (no OD, OD not sealed, image larger than 255, bit rate code or node-id out
 * of range, no OD subscription left). */
bool co_api_init(co_api_t *api, co_stack_t *stack, const co_api_config_t *config);
void co_api_deinit(co_api_t *api);

/* ---- requests (seed 004 §4.1) */
void co_api_get_id(const co_api_t *api, uint8_t id[4]);
uint8_t co_api_get_status(const co_api_t *api);
/* bps 1..8 (0 = default), node_id 1..127 (0 = default); again = re-initialise
 * (reset node, under node_id when it differs: seed 004 §4.1.3). CO_API_TRUE or
 * CO_API_FALSE (out of range, the bit rate refused, the stack refusing). */
uint8_t co_api_init_canopen(co_api_t *api, uint8_t bps, uint8_t node_id);
/* Copy image bytes out / in: the number copied, fewer at the end of the
 * image, 0 from offset past it; nothing outside the image is touched. A
 * write that changes bytes a TPDO maps triggers that TPDO once, after all
 * bytes are in (event-driven types, in operational). */
uint8_t co_api_read(co_api_t *api, uint8_t offset, uint8_t length, uint8_t *data);
uint8_t co_api_write(co_api_t *api, uint8_t offset, uint8_t length, const uint8_t *data);

/* The line's communication events, from the caller's stack indication:
 * bus-off and interface down become FatalError. */
void co_api_comm_event(co_api_t *api, co_comm_event_t event);

#endif
