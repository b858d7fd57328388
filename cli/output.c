/* Output files of the CLI: checked before the work starts, and cleaned up
 * when the work is interrupted. */
#define _POSIX_C_SOURCE 200809L /* sigaction */

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"

int lu_cli_check_output(const char *cmd, const char *path) {
    lu_error err = {0};
    char dir[1024];
    const char *slash = strrchr(path, '/');
    if (!slash) {
        snprintf(dir, sizeof dir, ".");
    } else if (slash == path) {
        snprintf(dir, sizeof dir, "/");
    } else {
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
    }
    struct stat st;
    if (strlen(path) >= 1024) {
        lu_fail(&err, LU_ERR_INVALID_ARG, "%.64s...: output path longer than 1023 bytes", path);
    } else if (slash && slash[1] == '\0') {
        lu_fail(&err, LU_ERR_INVALID_ARG, "%s: the output names a folder, not a file", path);
    } else if (stat(dir, &st) != 0) {
        lu_fail(&err, LU_ERR_IO, "%s: the output folder %s: %s", path, dir, strerror(errno));
    } else if (!S_ISDIR(st.st_mode)) {
        lu_fail(&err, LU_ERR_IO, "%s: %s is not a folder", path, dir);
    } else if (access(dir, W_OK | X_OK) != 0) {
        lu_fail(&err, LU_ERR_IO, "%s: the output folder %s is not writable: %s", path, dir, strerror(errno));
    } else if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
        lu_fail(&err, LU_ERR_IO, "%s: the output is a folder", path);
    }
    return err.code == LU_OK ? LU_EXIT_OK : lu_cli_error(cmd, &err);
}

/* The temporary name lu_atomic_open writes under ("<path>.tmp.<pid>"),
 * formatted before any signal can arrive: the handler only unlinks. */
static char g_temp_path[1100];

static void on_interrupt(int sig) {
    if (g_temp_path[0]) unlink(g_temp_path);
    _exit(128 + sig);
}

void lu_cli_guard_output(const char *path) {
    snprintf(g_temp_path, sizeof g_temp_path, "%s.tmp.%ld", path, (long)getpid());
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_interrupt;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}
