/* Tiny assertion helpers shared by the C tests. Each test is one program; exit 0 = pass. */
#ifndef PLX_FFI_CHECK_H
#define PLX_FFI_CHECK_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "parallax.h"

static int plx_failures = 0;

#define CHECK(cond)                                                                  \
    do {                                                                             \
        if (!(cond)) {                                                               \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
            plx_failures++;                                                          \
        }                                                                            \
    } while (0)

/* Expects `call` to return `expected`; prints the library's message otherwise. */
#define CHECK_STATUS(handle, call, expected)                                              \
    do {                                                                                  \
        plx_status got_ = (call);                                                         \
        if (got_ != (expected)) {                                                         \
            char msg_[512];                                                               \
            plx_last_error_message((handle), msg_, sizeof msg_, NULL);                    \
            fprintf(stderr, "%s:%d: %s returned %d (%s), expected %d; message: %s\n",     \
                    __FILE__, __LINE__, #call, (int)got_, plx_status_str((uint32_t)got_), \
                    (int)(expected), msg_);                                               \
            plx_failures++;                                                               \
        }                                                                                 \
    } while (0)

/* Expects the last error message on `handle` to contain `needle`. */
#define CHECK_MESSAGE(handle, needle)                                                 \
    do {                                                                              \
        char msg_[512];                                                               \
        plx_last_error_message((handle), msg_, sizeof msg_, NULL);                    \
        if (strstr(msg_, (needle)) == NULL) {                                         \
            fprintf(stderr, "%s:%d: message \"%s\" lacks \"%s\"\n", __FILE__, __LINE__, \
                    msg_, (needle));                                                  \
            plx_failures++;                                                           \
        }                                                                             \
    } while (0)

#define TEST_EXIT()                                                    \
    do {                                                               \
        if (plx_failures) fprintf(stderr, "%d check(s) failed\n", plx_failures); \
        return plx_failures ? 1 : 0;                                   \
    } while (0)

#endif
