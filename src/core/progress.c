/* Progress for long work, through the log (stderr by default): silent under
 * a second, then a bar. */
#include <lucent/core.h>

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

double lu_time_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

size_t lu_peak_rss_bytes(void) {
    /* VmHWM honours clear_refs resets; getrusage's ru_maxrss does not. */
    FILE *f = fopen("/proc/self/status", "r");
    if (f) {
        char line[256];
        unsigned long kb = 0;
        while (fgets(line, sizeof line, f))
            if (sscanf(line, "VmHWM: %lu kB", &kb) == 1) break;
        fclose(f);
        if (kb) return (size_t)kb * 1024u;
    }
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) return 0;
    return (size_t)ru.ru_maxrss * 1024u;
}

bool lu_peak_rss_reset(void) {
    FILE *f = fopen("/proc/self/clear_refs", "w");
    if (!f) return false;
    bool ok = fputs("5", f) >= 0;
    return fclose(f) == 0 && ok;
}


void lu_progress_begin(lu_progress *p, const char *label, int64_t total) {
    p->label = label;
    p->total = total > 0 ? total : 1;
    p->start_s = lu_time_seconds();
    p->last_print_s = 0.0;
    p->last_quarter = 0;
    p->printed = false;
}

void lu_progress_update(lu_progress *p, int64_t done) {
    if (!lu_log_enabled(LU_LOG_PROGRESS)) return;
    double now = lu_time_seconds();
    double elapsed = now - p->start_s;
    if (elapsed < 1.0) return;
    double frac = (double)done / (double)p->total;
    if (frac > 1.0) frac = 1.0;
    double eta = frac > 0.0 ? elapsed * (1.0 - frac) / frac : 0.0;
    if (isatty(STDERR_FILENO)) {
        if (now - p->last_print_s < 0.1 && frac < 1.0) return;
        char bar[31];
        int filled = (int)(frac * 30.0);
        for (int i = 0; i < 30; i++) bar[i] = i < filled ? '#' : '.';
        bar[30] = '\0';
        lu_log_msg(LU_LOG_PROGRESS, "\r%s [%s] %5.1f%%  %6.1fs elapsed  ETA %6.1fs ", p->label, bar, 100.0 * frac, elapsed, eta);
        p->last_print_s = now;
        p->printed = true;
    } else {
        int quarter = (int)(frac * 4.0);
        if (quarter > p->last_quarter) {
            p->last_quarter = quarter;
            lu_log_msg(LU_LOG_PROGRESS, "%s: %3.0f%% after %.1fs, ETA %.1fs\n", p->label, 100.0 * frac, elapsed, eta);
        }
    }
}

void lu_progress_end(lu_progress *p) {
    if (p->printed) {
        lu_log_msg(LU_LOG_PROGRESS, "\r%s done in %.1fs%40s\n", p->label, lu_time_seconds() - p->start_s, "");
        p->printed = false;
    }
}
