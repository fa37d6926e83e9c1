/* co_led: the CiA 303-3 indicators of the local node, a green run LED and a
 * red error LED, computed from what the node is doing.
 *
 * Inputs: the NMT state, the LSS state (configuration in progress) and the
 * error causes the error LED shows (co_led_cause_t). Each LED shows one
 * pattern at a time, the cause with the highest precedence:
 *
 *   run LED:   LSS in progress: flickering > stopped: single flash >
 *              pre-operational: blinking > operational: on > else off
 *   error LED: bus-off: on > LSS in progress: flickering >
 *              event-timer error: quadruple flash > SYNC error: triple flash >
 *              error control event: double flash > warning limit (or error
 *              passive): single flash > invalid configuration: blinking > off
 *
 * Timing (a timer on the line's timer list, on a 50 ms grid, armed for the
 * next tick where a LED changes and only while some pattern is not steady
 * and an indication listens): flickering 50 ms on / 50 ms off (the two LEDs in
 * antiphase); blinking 200 ms on / 200 ms off; an n-flash is n flashes of
 * 200 ms with 200 ms between them, then 1000 ms off. Both LEDs follow one
 * timebase started when the first non-steady pattern appears, so their
 * patterns start together; by default the run LED runs one 200 ms slot
 * behind the error LED (the two never light in the same slot, as a
 * bi-colour LED needs), or in the same slots when the config asks for it.
 * Evidence and open points: docs/protocol-notes.md "LED indicators (CiA 303-3)".
 *
 * An indication tells every change of a LED (on/off or pattern), so an
 * application can drive its GPIOs from it; the timer runs only while an
 * indication is set. co_led_pattern / co_led_is_on say the current state
 * at any time.
 */
#ifndef CO_LED_H
#define CO_LED_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"

#include <stdbool.h>
#include <stdint.h>

/* cffi:begin */
/* What a LED shows. */
typedef enum co_led_pattern {
    CO_LED_OFF = 0,
    CO_LED_ON = 1,
    CO_LED_FLICKERING = 2,       /* 10 Hz: 50 ms on, 50 ms off */
    CO_LED_BLINKING = 3,         /* 2.5 Hz: 200 ms on, 200 ms off */
    CO_LED_SINGLE_FLASH = 4,     /* 200 ms on, 1000 ms off */
    CO_LED_DOUBLE_FLASH = 5,     /* 2 x 200 ms on (200 ms between), 1000 ms off */
    CO_LED_TRIPLE_FLASH = 6,
    CO_LED_QUADRUPLE_FLASH = 7
} co_led_pattern_t;

/* The two indicators. */
typedef enum co_led_which {
    CO_LED_RUN = 0,              /* green */
    CO_LED_ERROR = 1             /* red */
} co_led_which_t;

/* What the error LED shows, one bit each (several may be active). */
typedef enum co_led_cause {
    CO_LED_CAUSE_BUS_OFF = 0x01,         /* on */
    CO_LED_CAUSE_WARNING = 0x02,         /* warning limit or error passive: single flash */
    CO_LED_CAUSE_ERROR_CONTROL = 0x04,   /* heartbeat or guarding lost: double flash */
    CO_LED_CAUSE_SYNC = 0x08,            /* SYNC error: triple flash */
    CO_LED_CAUSE_EVENT_TIMER = 0x10,     /* an RPDO missed its deadline: quadruple flash */
    CO_LED_CAUSE_CONFIG = 0x20           /* invalid configuration: blinking */
} co_led_cause_t;
/* cffi:end */

enum {
    CO_LED_TICK_US = 50000,      /* flickering half period, the timer's step */
    CO_LED_SLOT_TICKS = 4,       /* 200 ms: a blink or flash phase */
    /* ticks after which every pattern repeats (lcm of their cycles) */
    CO_LED_CYCLE_TICKS = 480,
    CO_LED_CAUSES = 0x3F
};

typedef struct co_led co_led_t;

/* A LED changed: it is now on or off, showing pattern. */
typedef void (*co_led_fn)(co_led_t *led, co_led_which_t which, bool on,
                          co_led_pattern_t pattern, void *user);

typedef struct co_led_config {
    /* false (default): the run LED's blinks and flashes one 200 ms slot after
     * the error LED's; true: in the same slots. Flickering is always in
     * antiphase. */
    bool same_phase;
    co_led_fn changed;           /* may be NULL (no timer then) */
    void *user;
} co_led_config_t;

struct co_led {
    co_line_t *line;
    co_timer_t timer;
    co_led_fn changed;
    void *user;
    bool same_phase;
    bool lss;                    /* LSS configuration in progress */
    co_nmt_state_t nmt_state;
    uint8_t causes;              /* co_led_cause_t bits */
    bool timebase;               /* a non-steady pattern runs: tick counts */
    uint64_t timebase_us;        /* when tick 0 began */
    co_led_pattern_t pattern[2];
    bool on[2];                  /* what the indication was told last */
};

/* Both LEDs off (NMT initialising, no cause). */
void co_led_init(co_led_t *led, co_line_t *line, const co_led_config_t *config);
void co_led_deinit(co_led_t *led);
/* Set (or clear, NULL) the indication; the timer runs only with one. A new
 * indication hears nothing of the state so far: read it with co_led_is_on. */
void co_led_set_indication(co_led_t *led, co_led_fn changed, void *user);

/* Inputs (the node and the LSS slave call these; an application may too). */
void co_led_set_nmt_state(co_led_t *led, co_nmt_state_t state);
void co_led_set_lss(co_led_t *led, bool configuring);
/* cause: one or more co_led_cause_t bits; unknown bits are ignored. */
void co_led_set_cause(co_led_t *led, uint8_t cause, bool active);
/* Several causes at once (one change, one indication): the bits of `mask`
 * take their values from `active`. */
void co_led_set_causes(co_led_t *led, uint8_t mask, uint8_t active);
static inline uint8_t co_led_causes(const co_led_t *led) { return led->causes; }

/* What the LED shows now, and whether it is lit at the line's time. */
co_led_pattern_t co_led_pattern(const co_led_t *led, co_led_which_t which);
bool co_led_is_on(const co_led_t *led, co_led_which_t which);
/* The pattern's name ("off", "on", "flickering", "blinking", "single flash", ...). */
const char *co_led_pattern_name(co_led_pattern_t pattern);
/* Whether a pattern lights the LED in tick `tick` (50 ms units) of the
 * timebase: the timeline itself, for tests and applications with their own
 * timer. */
bool co_led_lit(co_led_pattern_t pattern, co_led_which_t which, bool same_phase,
                uint32_t tick);

#endif
