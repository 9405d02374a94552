/*
 * con_fixture: the console the lib/console tests share (g_con on the byte I/O
 * fake g_serial), with a handler for every command that records its call in
 * g_app and answers what g_app asks for.
 */
#ifndef HALLHOME_CON_FIXTURE_H
#define HALLHOME_CON_FIXTURE_H

#include <stddef.h>
#include <stdint.h>

#include "con_fake.h"
#include "console/console.h"

/* What the handlers saw and what they are told to do (the console's ctx). */
typedef struct {
    int calls[CON_CMD_COUNT];
    int total;
    uint8_t last_cmd;
    con_args_t last;
    char s0[CON_LINE_MAX + 1];
    int8_t result;           /* what every handler returns */
    uint8_t report;          /* emit a report before returning */
    uint8_t complete_inside; /* call con_complete() from inside the handler */
    int8_t inner_rc;         /* what that call returned */
} con_fix_app_t;

extern con_fake_t g_serial;
extern con_t g_con;
extern con_rt_t g_rt;
extern con_fix_app_t g_app;
extern uint16_t g_clock_ms; /* advances 1 ms per poll */
extern con_handler_fn g_handlers[CON_CMD_COUNT];

/* cmocka setup: a cleared g_app and g_rt, a fresh g_serial, every command's
 * handler in g_handlers and g_con initialised on them. */
int con_fix_setup(void **state);

/* Feeds input, polls until everything is read and nothing is pending (or
 * a command stays pending), and returns the output written meanwhile. */
const char *con_fix_run_bytes(const void *in, size_t n);

/* con_fix_run_bytes() of a NUL-terminated string. */
const char *con_fix_run(const char *in);

#endif /* HALLHOME_CON_FIXTURE_H */
