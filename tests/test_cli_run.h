/* test_cli_run.h - running the radray binary from a test (header-only):
 * shared by the CLI-level test files. */
#ifndef TEST_CLI_RUN_H
#define TEST_CLI_RUN_H

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "rr_core.h"

/* Starts RR_RADRAY_BIN with args (NULL-terminated, at most 60), its stdout
 * and stderr going to the file log. */
static inline pid_t test_cli_start(const char *log, const char *const *args)
{
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 1);
        dup2(fd, 2);
        const char *argv[64];
        int n = 0;
        argv[n++] = RR_RADRAY_BIN;
        for (; args[n - 1] && n < 62; n++)
            argv[n] = args[n - 1];
        argv[n] = NULL;
        execv(RR_RADRAY_BIN, (char *const *)argv);
        _exit(127);
    }
    return pid;
}

/* Waits for pid, copies the log into out (truncated, NUL-terminated) and
 * returns the exit code (128 + signal when killed). */
static inline int test_cli_finish(pid_t pid, const char *log, char *out, size_t out_size)
{
    int status = 0;
    waitpid(pid, &status, 0);
    char *data = NULL;
    out[0] = '\0';
    if (rr_file_read_all(log, &data, NULL, NULL) == RR_OK) {
        snprintf(out, out_size, "%s", data);
        free(data);
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/* Runs radray to completion: exit code, output in out. */
static inline int test_cli_run(const char *log, const char *const *args, char *out, size_t out_size)
{
    return test_cli_finish(test_cli_start(log, args), log, out, out_size);
}

#endif
