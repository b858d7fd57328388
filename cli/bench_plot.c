/* `lucent bench --plot FILE.png`: the error-time scatter, drawn by gnuplot
 * from a data file and a script written to a temporary folder; one panel per
 * scene and motion (docs/bench.md "The plot"). */
#define _POSIX_C_SOURCE 200809L /* mkdtemp */

#include <errno.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench_truth.h"

extern char **environ;

bool lu_bench_have_gnuplot(void) {
    const char *path = getenv("PATH");
    if (!path) return false;
    char dir[1024], exe[1100];
    for (const char *p = path;;) {
        const char *colon = strchr(p, ':');
        size_t n = colon ? (size_t)(colon - p) : strlen(p);
        if (n < sizeof dir) {
            snprintf(dir, sizeof dir, "%.*s", (int)n, n ? p : ".");
            snprintf(exe, sizeof exe, "%s/gnuplot", dir);
            struct stat st;
            if (stat(exe, &st) == 0 && S_ISREG(st.st_mode) && access(exe, X_OK) == 0) return true;
        }
        if (!colon) return false;
        p = colon + 1;
    }
}

/* A gnuplot single-quoted string: '' stands for a quote. */
static void gp_quoted(FILE *f, const char *s) {
    fputc('\'', f);
    for (; *s; s++) {
        if (*s == '\'') fputc('\'', f);
        if (*s != '\n') fputc(*s, f);
    }
    fputc('\'', f);
}

/* A gnuplot double-quoted string, where \n is a line break. */
static void gp_dquoted(FILE *f, const char *s) {
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '\n') fputs("\\n", f);
        else {
            if (*s == '"' || *s == '\\') fputc('\\', f);
            fputc(*s, f);
        }
    }
    fputc('"', f);
}

/* A data-file string column: double quotes, none inside. */
static void data_quoted(FILE *f, const char *s) {
    fputc('"', f);
    for (; *s; s++) fputc(*s == '"' ? '\'' : (*s == '\n' || *s == '\t') ? ' ' : *s, f);
    fputc('"', f);
}

#define MAX_PANELS 64
#define MAX_KINDS 64

static int find_or_add(const char **list, int *n, int max, const char *s) {
    for (int i = 0; i < *n; i++)
        if (strcmp(list[i], s) == 0) return i;
    if (*n == max) return -1;
    list[*n] = s;
    return (*n)++;
}

static bool plottable(const lu_plot_point *p) { return p->rel_l2 >= 0.0 && p->ms > 0.0 && isfinite(p->rel_l2); }

/* The point's shape: 0 a CPU row, 1 a GPU row, 2 the truth's own row (error 0). */
static int kind_of(const lu_plot_point *p) { return p->rel_l2 > 0.0 ? (p->gpu ? 1 : 0) : 2; }
static const int k_shape[3] = {7, 9, 12};
static const char *const k_kind_note[3] = {"", " (GPU)", " (= the truth)"};

lu_result lu_bench_plot(const char *path, const lu_plot_point *pts, int n, const char *truth, const char *note,
                        lu_error *err) {
    const char *panels[MAX_PANELS], *methods[MAX_KINDS];
    int npanels = 0, nmethods = 0;
    for (int i = 0; i < n; i++) {
        if (!plottable(&pts[i])) continue;
        if (find_or_add(panels, &npanels, MAX_PANELS, pts[i].panel) < 0 ||
            find_or_add(methods, &nmethods, MAX_KINDS, pts[i].method) < 0)
            return lu_fail(err, LU_ERR_LIMIT, "--plot: more than %d panels or methods", MAX_PANELS);
    }
    if (npanels == 0) return lu_fail(err, LU_ERR_INVALID_ARG, "--plot: no row has both a frame time and an error");
    const char *tmpdir = getenv("TMPDIR");
    char dir[1024], data[1100], script[1100], png[1100];
    snprintf(dir, sizeof dir, "%s/lucent-plot-XXXXXX", tmpdir && *tmpdir ? tmpdir : "/tmp");
    if (!mkdtemp(dir)) return lu_fail(err, LU_ERR_IO, "--plot: temporary folder %s: %s", dir, strerror(errno));
    snprintf(data, sizeof data, "%s/points.dat", dir);
    snprintf(script, sizeof script, "%s/plot.gp", dir);
    /* Where lu_atomic_file would write: the signal guard and a reader both
     * see the same temporary name as for every other output. */
    snprintf(png, sizeof png, "%s.tmp.%ld", path, (long)getpid());
    lu_result r = LU_OK;
    FILE *fd = fopen(data, "w"), *fs = fopen(script, "w");
    if (!fd || !fs) r = lu_fail(err, LU_ERR_IO, "--plot: cannot write in %s: %s", dir, strerror(errno));
    /* One data block per panel (gnuplot's "index"); rows: x, y, label,
     * method index, point type. Errors of 0 (the truth's own row) go on
     * the panel's floor, a third of its smallest error, marked as such. */
    for (int pi = 0; pi < npanels && r == LU_OK; pi++) {
        double lo = INFINITY;
        for (int i = 0; i < n; i++)
            if (plottable(&pts[i]) && strcmp(pts[i].panel, panels[pi]) == 0 && pts[i].rel_l2 > 0.0 && pts[i].rel_l2 < lo)
                lo = pts[i].rel_l2;
        double floor_y = isfinite(lo) ? lo / 3.0 : 1e-6;
        for (int i = 0; i < n; i++) {
            const lu_plot_point *p = &pts[i];
            if (!plottable(p) || strcmp(p->panel, panels[pi]) != 0) continue;
            int mi = find_or_add(methods, &nmethods, MAX_KINDS, p->method);
            char label[200];
            snprintf(label, sizeof label, "%s%s", p->label, p->rel_l2 > 0.0 ? "" : " (the truth: 0)");
            fprintf(fd, "%.6g\t%.6g\t", p->ms, p->rel_l2 > 0.0 ? p->rel_l2 : floor_y);
            data_quoted(fd, label);
            fprintf(fd, "\t%d\t%d\n", mi, kind_of(p));
        }
        fprintf(fd, "\n\n");
    }
    if (r == LU_OK) {
        fprintf(fs, "set terminal pngcairo size 1000,%d font 'sans,10'\nset output ", 80 + 560 * npanels);
        gp_quoted(fs, png);
        fprintf(fs, "\nset encoding utf8\nset logscale xy\nset grid\nset key outside right top noenhanced\n"
                    "set xlabel 'frame time, ms (median of the timed frames)'\nset ylabel ");
        char yl[160];
        snprintf(yl, sizeof yl, "rel-L2 against the truth (%s)", truth);
        gp_quoted(fs, yl);
        fprintf(fs, " noenhanced\nset offsets graph 0.05, graph 0.25, graph 0.3, graph 0.15\n"
                    "set multiplot layout %d,1\n",
                npanels);
        for (int pi = 0; pi < npanels; pi++) {
            char title[600];
            snprintf(title, sizeof title, "%s\n%s", panels[pi], note);
            fprintf(fs, "set title ");
            gp_dquoted(fs, title);
            fprintf(fs, " noenhanced\nplot ");
            /* one clause per method and shape present, so the key shows each */
            for (int mi = 0; mi < nmethods; mi++)
                for (int k = 0; k < 3; k++) {
                    bool any = false;
                    for (int i = 0; i < n && !any; i++)
                        any = plottable(&pts[i]) && strcmp(pts[i].panel, panels[pi]) == 0 &&
                              strcmp(pts[i].method, methods[mi]) == 0 && kind_of(&pts[i]) == k;
                    if (!any) continue;
                    gp_quoted(fs, data);
                    fprintf(fs, " index %d using 1:($4 == %d && $5 == %d ? $2 : 1/0) with points pt %d ps 1.6 lc %d title ",
                            pi, mi, k, k_shape[k], mi + 1);
                    char t[160];
                    snprintf(t, sizeof t, "%s%s", methods[mi], k_kind_note[k]);
                    gp_quoted(fs, t);
                    fprintf(fs, ", \\\n     ");
                }
            gp_quoted(fs, data);
            fprintf(fs, " index %d using 1:2:3 with labels rotate by 25 offset char 0.8,0.6 left font ',8' noenhanced notitle\n", pi);
        }
        fprintf(fs, "unset multiplot\nset output\n");
    }
    if (fd && fclose(fd) != 0 && r == LU_OK) r = lu_fail(err, LU_ERR_IO, "--plot: %s: write failed", data);
    if (fs && fclose(fs) != 0 && r == LU_OK) r = lu_fail(err, LU_ERR_IO, "--plot: %s: write failed", script);
    if (r == LU_OK) {
        char *argv[] = {"gnuplot", script, NULL};
        pid_t pid;
        int rc = posix_spawnp(&pid, "gnuplot", NULL, NULL, argv, environ), status = 0;
        if (rc != 0) r = lu_fail(err, LU_ERR_IO, "--plot: cannot run gnuplot: %s", strerror(rc));
        else if (waitpid(pid, &status, 0) < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
            r = lu_fail(err, LU_ERR_IO, "--plot: gnuplot failed (script %s)", script);
    }
    if (r == LU_OK) {
        /* gnuplot reports some failures only on stderr: check what it wrote. */
        static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
        unsigned char head[8] = {0};
        FILE *fp = fopen(png, "rb");
        bool ok = fp && fread(head, 1, 8, fp) == 8 && memcmp(head, sig, 8) == 0;
        if (fp) fclose(fp);
        if (!ok) r = lu_fail(err, LU_ERR_IO, "--plot: gnuplot wrote no PNG to %s", png);
        else if (rename(png, path) != 0) r = lu_fail(err, LU_ERR_IO, "--plot: %s: %s", path, strerror(errno));
    }
    unlink(png);
    /* A failed plot keeps its script and data for a look; a good one leaves nothing. */
    if (r == LU_OK) {
        unlink(data);
        unlink(script);
        rmdir(dir);
    }
    return r;
}
