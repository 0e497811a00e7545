/* rr_error.h - result codes, user-facing error messages, warnings, programmer checks
 * (part of core, see rr_core.h).
 *
 * Two different things:
 *  - User errors (bad scene, unreadable mesh, unwritable output) are *returned*:
 *    every fallible function returns an rr_status and fills an rr_error whose
 *    message names the file, the place in it and what was wrong. Library code
 *    never exits; only main() decides how the program ends.
 *  - Programmer errors (a broken invariant) abort through RR_CHECK, printing the
 *    failed expression and its location.
 */
#ifndef RR_ERROR_H
#define RR_ERROR_H

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef enum rr_status {
    RR_OK = 0,
    RR_ERR_IO,       /* a file could not be read or written */
    RR_ERR_PARSE,    /* malformed input (JSON syntax, truncated mesh...) */
    RR_ERR_INVALID,  /* well-formed input with a wrong or missing value */
    RR_ERR_NOMEM,    /* an allocation failed */
    RR_ERR_LIMIT,    /* the request exceeds a resource limit (memory estimate...) */
    RR_ERR_INTERRUPTED,
    RR_ERR_INTERNAL
} rr_status;

#define RR_ERROR_MSG_MAX 1024

/* The message is one line, without a trailing newline, already prefixed by
 * where the problem is (e.g. "scenes/a.json: objects[3].material: expected a
 * string"). */
typedef struct rr_error {
    rr_status code;
    char msg[RR_ERROR_MSG_MAX];
} rr_error;

/* Records code and a printf-style message in err (err may be NULL) and returns
 * code, so that callers can write `return rr_error_set(err, RR_ERR_IO, ...)`. */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
rr_status rr_error_set(rr_error *err, rr_status code, const char *fmt, ...);

/* Prepends "prefix: " to an existing message (used to add a file name on the
 * way up). Returns err->code. err may be NULL. */
#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
rr_status rr_error_prefix(rr_error *err, const char *fmt, ...);

void rr_error_clear(rr_error *err);
/* A byte count for a message: "6.1 GiB", "512.0 MiB", "12.0 KiB", "100 bytes"
 * (MiB up to 1 GiB: "0.1 GiB" said 100 to 150 MiB; TiB from 10). */
const char *rr_size_text(double bytes, char *buf, size_t n);
const char *rr_status_name(rr_status code);

/* Warnings (not fatal: e.g. a dropped zero-area triangle) go to a sink chosen by
 * the caller; a NULL sink or NULL fn discards them. */
typedef struct rr_warn_sink {
    void (*fn)(void *user, const char *msg);
    void *user;
} rr_warn_sink;

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
void rr_warn(const rr_warn_sink *sink, const char *fmt, ...);

/* Programmer-error check: aborts with the expression and location. */
#define RR_CHECK(cond)                                                                      \
    do {                                                                                    \
        if (!(cond)) {                                                                      \
            fprintf(stderr, "%s:%d: internal check failed: %s\n", __FILE__, __LINE__, #cond); \
            abort();                                                                        \
        }                                                                                   \
    } while (0)

#endif
