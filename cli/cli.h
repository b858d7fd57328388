/* Shared pieces of the lucent command-line tool. */
#ifndef LU_CLI_H
#define LU_CLI_H

#include <lucent/lucent.h>
#include <stdio.h>

/* Exit codes (documented in `lucent --help` and the README). */
enum { LU_EXIT_OK = 0, LU_EXIT_FAIL = 1, LU_EXIT_USAGE = 2, LU_EXIT_THRESHOLD = 3 };

/* A renderer's stats (zeros for NULL). */
static inline lu_renderer_stats lu_cli_stats(const lu_renderer *r) {
    lu_renderer_stats st = {0};
    if (r) lu_renderer_get_stats(r, &st, NULL);
    return st;
}

/* Reads lucent's environment variables into the library's lu_host (the
 * library reads none): LU_EXIT_OK, or the exit code after a message. */
int lu_cli_host_from_env(void);
/* Whether LUCENT_THREADS chose the thread count (else a rank of a job
 * divides its node's processors, cli/mpi.c). */
extern bool lu_cli_threads_from_env;

int lu_cmd_render(int argc, char **argv);
int lu_cmd_compare(int argc, char **argv);
int lu_cmd_info(int argc, char **argv);
int lu_cmd_bench(int argc, char **argv);
int lu_cmd_methods(int argc, char **argv);
int lu_cmd_profile(int argc, char **argv);
int lu_cmd_view(int argc, char **argv);
int lu_cmd_export_grid(int argc, char **argv);

/* One line on stderr: "lucent <cmd>: error: <message>"; returns LU_EXIT_FAIL. */
int lu_cli_error(const char *cmd, const lu_error *err);
/* Usage error: prints the message and a pointer to --help; returns LU_EXIT_USAGE. */
int lu_cli_usage(const char *cmd, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
bool lu_cli_is_help(const char *arg);
/* Parses "WxH". */
bool lu_cli_parse_size(const char *s, int *w, int *h);
/* Parses "cpu" / "gpu" / "auto" (LU_BACKEND_AUTO). */
bool lu_cli_parse_backend(const char *s, lu_backend *b);
/* The backend --backend b means for method m (NULL: for whichever method, as
 * a list of backends needs): lu_backend_resolve, plus one note line on stderr
 * (once per process) when auto falls to the CPU for want of a hardware GPU. */
lu_backend lu_cli_resolve_backend(const char *cmd, lu_backend b, const lu_method *m);
/* Before any work: the folder of `path` exists and is writable, and path is
 * not a folder; otherwise one line naming the path and LU_EXIT_FAIL. */
int lu_cli_check_output(const char *cmd, const char *path);
/* SIGINT or SIGTERM from here on removes the temporary file of an output
 * being written to `path` (lu_atomic_file) and exits with 128 + the signal
 * (130 for SIGINT). The output itself is only ever a complete image: renamed
 * into place whole, or not there. */
void lu_cli_guard_output(const char *path);
/* Loads a scene and applies --size overrides. */
int lu_cli_load_scene(const char *cmd, const char *path, int width, int height, lu_scene *scene);
/* Lists every method, its backends and parameters (for --help texts). */
void lu_cli_print_methods(FILE *out);
/* bench's fixed measure of the machine (cli/yardstick.c): the median of
 * `repetitions` timed passes, in G trilinear samples per second, on all
 * processors (their number in *threads). 0 if out of memory. */
double lu_yardstick_gsps(int repetitions, int *threads);

#endif
