/* rr_error.c - result codes and messages. */
#include "rr_error.h"

#include <string.h>

rr_status rr_error_set(rr_error *err, rr_status code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        err->code = code;
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}

rr_status rr_error_prefix(rr_error *err, const char *fmt, ...)
{
    if (!err)
        return RR_ERR_INTERNAL;
    char prefix[RR_ERROR_MSG_MAX];
    char old[RR_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, err->msg, sizeof old);
    size_t n = strlen(prefix);
    if (n > sizeof err->msg - 3)
        n = sizeof err->msg - 3;
    memcpy(err->msg, prefix, n);
    memcpy(err->msg + n, ": ", 2);
    size_t room = sizeof err->msg - n - 3;
    size_t ol = strlen(old);
    if (ol > room)
        ol = room;
    memcpy(err->msg + n + 2, old, ol);
    err->msg[n + 2 + ol] = '\0';
    return err->code;
}

void rr_error_clear(rr_error *err)
{
    if (err) {
        err->code = RR_OK;
        err->msg[0] = '\0';
    }
}

const char *rr_status_name(rr_status code)
{
    switch (code) {
    case RR_OK: return "ok";
    case RR_ERR_IO: return "i/o error";
    case RR_ERR_PARSE: return "parse error";
    case RR_ERR_INVALID: return "invalid input";
    case RR_ERR_NOMEM: return "out of memory";
    case RR_ERR_LIMIT: return "resource limit";
    case RR_ERR_INTERRUPTED: return "interrupted";
    case RR_ERR_INTERNAL: return "internal error";
    }
    return "unknown error";
}

void rr_warn(const rr_warn_sink *sink, const char *fmt, ...)
{
    if (!sink || !sink->fn)
        return;
    char msg[RR_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    sink->fn(sink->user, msg);
}

const char *rr_size_text(double bytes, char *buf, size_t n)
{
    const double kib = 1024.0, mib = kib * kib, gib = mib * kib, tib = gib * kib;
    if (bytes >= 10.0 * tib)
        snprintf(buf, n, "%.3g TiB", bytes / tib);
    else if (bytes >= gib)
        snprintf(buf, n, "%.1f GiB", bytes / gib);
    else if (bytes >= mib)
        snprintf(buf, n, "%.1f MiB", bytes / mib);
    else if (bytes >= kib)
        snprintf(buf, n, "%.1f KiB", bytes / kib);
    else
        snprintf(buf, n, "%.0f bytes", bytes);
    return buf;
}
