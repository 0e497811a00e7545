/* main.c - radray's entry point: dispatches to the subcommands. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <errno.h>

#include "app.h"

static const char usage[] =
    "usage: radray <command> [options]\n"
    "\n"
    "radray is a hybrid radiosity + ray-tracing renderer.\n"
    "\n"
    "commands:\n"
    "  render SCENE   render a scene file to OpenEXR (linear) and PNG (preview)\n"
    "  info SCENE     print what a scene holds: triangles, lights, bounds, watertightness\n"
    "  energy SCENE   run the radiosity pass and print the energy ledger (--json)\n"
    "  compare SCENE  render several modes (or layers) into one labelled figure (PNG, PDF, SVG)\n"
    "  help [CMD]     show this help, or the help of CMD\n"
    "  version        print the version\n"
    "\n"
    "Run 'radray <command> --help' for the options of a command.\n"
    "Exit codes: 0 ok, 1 runtime error, 2 usage error or bad input.\n";

void app_error(const char *fmt, ...)
{
    char msg[RR_ERROR_MSG_MAX + 256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (!app_mpi_muted(msg)) /* under mpirun, rank 0 speaks for all */
        fprintf(stderr, "radray: %s\n", msg);
}

static void warn_to_stderr(void *user, const char *msg)
{
    (void)user;
    if (app_mpi_rank() == 0)
        fprintf(stderr, "radray: warning: %s\n", msg);
}

rr_warn_sink app_warn_sink(void)
{
    rr_warn_sink s = {warn_to_stderr, NULL};
    return s;
}

int app_parse_int(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end != '\0' || v < lo || v > hi)
        return -1;
    *out = v;
    return 0;
}

static int run(int argc, char **argv);

int main(int argc, char **argv)
{
    if (app_mpi_init(&argc, &argv) != 0)
        return APP_EXIT_RUNTIME;
    int rc;
    if (app_mpi_ranks() > 1 && (argc < 2 || strcmp(argv[1], "render") != 0)) {
        if (app_mpi_rank() == 0)
            fprintf(stderr, "radray: only 'render' runs on several MPI ranks (%d here); run '%s' without mpirun\n",
                    app_mpi_ranks(), argc >= 2 ? argv[1] : "radray");
        rc = APP_EXIT_USAGE;
    } else {
        rc = run(argc, argv);
    }
    app_mpi_finalize();
    return rc;
}

static int run(int argc, char **argv)
{
    if (argc < 2) {
        fputs(usage, stderr);
        return APP_EXIT_USAGE;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "render"))
        return app_cmd_render(argc - 1, argv + 1);
    if (!strcmp(cmd, "info"))
        return app_cmd_info(argc - 1, argv + 1);
    if (!strcmp(cmd, "energy"))
        return app_cmd_energy(argc - 1, argv + 1);
    if (!strcmp(cmd, "compare"))
        return app_cmd_compare(argc - 1, argv + 1);
    if (!strcmp(cmd, "version") || !strcmp(cmd, "--version")) {
        printf("radray 0.1.0\n");
        return APP_EXIT_OK;
    }
    if (!strcmp(cmd, "help") || !strcmp(cmd, "--help") || !strcmp(cmd, "-h")) {
        if (argc >= 3) {
            char *sub[] = {argv[2], "--help", NULL};
            if (!strcmp(argv[2], "render"))
                return app_cmd_render(2, sub);
            if (!strcmp(argv[2], "info"))
                return app_cmd_info(2, sub);
            if (!strcmp(argv[2], "energy"))
                return app_cmd_energy(2, sub);
            if (!strcmp(argv[2], "compare"))
                return app_cmd_compare(2, sub);
            app_error("unknown command '%s'", argv[2]);
            return APP_EXIT_USAGE;
        }
        fputs(usage, stdout);
        return APP_EXIT_OK;
    }
    app_error("unknown command '%s' (try 'radray --help')", cmd);
    return APP_EXIT_USAGE;
}
