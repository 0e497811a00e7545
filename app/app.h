/* app.h - the radray command line (private to app/).
 *
 * Exit codes, the same for every subcommand:
 *   0  success
 *   1  runtime error (a render or a write failed after the input was accepted)
 *   2  usage error or bad input (bad options, unreadable or invalid scene or
 *      mesh, an output path that cannot be written)
 */
#ifndef APP_H
#define APP_H

#include "rr_core.h"

enum { APP_EXIT_OK = 0, APP_EXIT_RUNTIME = 1, APP_EXIT_USAGE = 2 };

int app_cmd_render(int argc, char **argv);
int app_cmd_info(int argc, char **argv);
int app_cmd_energy(int argc, char **argv);

/* Prints "radray: <msg>" on stderr. */
void app_error(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;

/* Warning sink printing "radray: warning: <msg>" on stderr. */
rr_warn_sink app_warn_sink(void);

/* Writes a log-scale plot of res[0..n) (residual per iteration) to path, PNG
 * or SVG by extension, atomically. 0 on success. */
int app_plot_residuals(const char *path, const double *res, int n, const char *title, rr_error *err);

/* Parses a whole decimal integer in [lo, hi]; 0 on success. */
int app_parse_int(const char *s, long lo, long hi, long *out);

#endif
