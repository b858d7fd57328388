/* The Monte Carlo slab random walk (profile_mc.h). */
#include "methods/bssrdf/profile_mc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/rng.h"
#include "kernels/lu_optics.h"

typedef struct mc_rng {
    uint64_t s;
} mc_rng;

static double mc_uniform(mc_rng *g) { return lu_rng_unit(&g->s); }

enum { MC_CHUNKS = 64, MC_MAX_EVENTS = 1000000 };
/* Per chunk: R bins, T bins, R bins of multiply scattered light, then
 * r_total, t_total, r_total^2 per path, r_total of multiple scattering, and
 * the weight of walks dropped at the event cap, and r_total of multiple
 * scattering with no face reflection between the first two events. */
#define TALLY(b) (3 * (b) + 6)

typedef struct mc_job {
    double sigma_t, albedo, eta, thickness;
    long long paths;
    unsigned long long seed;
    int bins;
    double dr;
    double *tally;       /* per chunk: TALLY(bins) doubles, laid out as below */
} mc_job;

static double fresnel_inside(double cos_i, double eta) {
    /* From inside (index eta) out to index 1: the relative index is 1 / eta. */
    return (double)lu_k_fresnel_reflectance((float)cos_i, (float)(1.0 / eta));
}

static void mc_chunk(void *vctx, int64_t begin, int64_t end, int thread) {
    mc_job *j = vctx;
    for (int64_t chunk = begin; chunk < end; chunk++) {
        double *tal = j->tally + (size_t)chunk * TALLY(j->bins);
        /* Each chunk starts at a hashed point of the generator's one cycle.
         * Starting states a multiple of its increment apart (as seed + chunk
         * times the increment would be) replay each other's draws shifted by
         * a few, which correlates the chunks' paths. */
        uint64_t h = j->seed * 0x2545F4914F6CDD1Dull ^ (uint64_t)chunk * 0xD1B54A32D192ED03ull;
        mc_rng g = {lu_rng_next(&h)};
        long long p0 = j->paths * chunk / MC_CHUNKS, p1 = j->paths * (chunk + 1) / MC_CHUNKS;
        for (long long p = p0; p < p1; p++) {
            double x = 0, y = 0, z = 0, dx = 0, dy = 0, dz = 1, w = 1.0, r_path = 0.0;
            int events = 0;
            bool reflected_after_first = false;
            /* A walk in a non-absorbing half-space returns with probability 1 but
             * its return time has a heavy tail: walks past 10^6 events are
             * dropped, which biases low by their weight (reported as `dropped`:
             * 2.4e-3 for a non-absorbing half-space at eta 1.3). */
            int ev = 0;
            for (; ev < MC_MAX_EVENTS; ev++) {
                double s = -log(1.0 - mc_uniform(&g)) / j->sigma_t;
                double zn = z + s * dz;
                if (zn < 0.0 || zn > j->thickness) {
                    bool top = zn < 0.0;
                    double t = ((top ? 0.0 : j->thickness) - z) / dz;
                    x += t * dx;
                    y += t * dy;
                    z = top ? 0.0 : j->thickness;
                    double f = fresnel_inside(fabs(dz), j->eta);
                    double out = w * (1.0 - f);
                    double r = sqrt(x * x + y * y);
                    int b = (int)(r / j->dr);
                    if (b >= j->bins) b = j->bins - 1;
                    tal[(top ? 0 : j->bins) + b] += out;
                    if (top) {
                        tal[3 * j->bins] += out;
                        r_path += out;
                        if (events >= 2) {
                            tal[2 * j->bins + b] += out;
                            tal[3 * j->bins + 3] += out;
                            if (!reflected_after_first) tal[3 * j->bins + 5] += out;
                        }
                    } else {
                        tal[3 * j->bins + 1] += out;
                    }
                    w *= f;
                    dz = -dz;
                    if (events == 1) reflected_after_first = true;
                } else {
                    x += s * dx;
                    y += s * dy;
                    z = zn;
                    w *= j->albedo;
                    events++;
                    double ct = 1.0 - 2.0 * mc_uniform(&g), st = sqrt(fmax(0.0, 1.0 - ct * ct));
                    double phi = 2.0 * M_PI * mc_uniform(&g);
                    dx = st * cos(phi);
                    dy = st * sin(phi);
                    dz = ct;
                }
                if (w < 1e-4) { /* Russian roulette keeps the estimate unbiased */
                    if (mc_uniform(&g) < 0.1) w *= 10.0;
                    else break;
                }
            }
            if (ev == MC_MAX_EVENTS) tal[3 * j->bins + 4] += w;
            tal[3 * j->bins + 2] += r_path * r_path;
        }
    }
}

lu_result lu_bssrdf_mc_slab(double sigma_sp, double sigma_a, double eta, double thickness, long long paths,
                            unsigned long long seed, int bins, double dr, lu_bssrdf_mc_result *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    if (!(sigma_sp > 0.0) || !(sigma_a >= 0.0) || paths < 1 || bins < 1 || !(dr > 0.0) || !(thickness > 0.0) ||
        !(eta >= 1.0))
        return lu_fail(err, LU_ERR_RANGE, "bssrdf: invalid Monte Carlo settings");
    mc_job j = {sigma_sp + sigma_a, sigma_sp / (sigma_sp + sigma_a), eta, thickness, paths, seed, bins, dr, NULL};
    j.tally = lu_calloc((size_t)MC_CHUNKS * TALLY(bins), sizeof(double));
    out->r_profile = lu_calloc((size_t)bins, sizeof(double));
    out->t_profile = lu_calloc((size_t)bins, sizeof(double));
    out->r_multiple = lu_calloc((size_t)bins, sizeof(double));
    out->r_profile_stderr = lu_calloc((size_t)bins, sizeof(double));
    if (!j.tally || !out->r_profile || !out->t_profile || !out->r_multiple || !out->r_profile_stderr) {
        lu_free(j.tally);
        lu_bssrdf_mc_destroy(out);
        return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    }
    lu_parallel_for(MC_CHUNKS, 1, mc_chunk, &j, "random walk");
    double sq = 0.0;
    for (int c = 0; c < MC_CHUNKS; c++) {
        const double *tal = j.tally + (size_t)c * TALLY(bins);
        for (int b = 0; b < bins; b++) {
            out->r_profile[b] += tal[b];
            out->t_profile[b] += tal[bins + b];
            out->r_multiple[b] += tal[2 * bins + b];
        }
        out->r_total += tal[3 * bins];
        out->t_total += tal[3 * bins + 1];
        sq += tal[3 * bins + 2];
        out->r_multiple_total += tal[3 * bins + 3];
        out->dropped += tal[3 * bins + 4];
        out->r_multiple_unreflected_total += tal[3 * bins + 5];
    }
    /* A path can leave through several bins (every internal hit lets some
     * out), so bins are not independent per path; the 64 chunks are, and
     * their per-path means scatter about the whole run's with variance
     * (chunks - 1) times its own. */
    for (int b = 0; b < bins; b++) {
        double mean = out->r_profile[b] / (double)paths, ss = 0.0;
        for (int c = 0; c < MC_CHUNKS; c++) {
            long long n = paths * (c + 1) / MC_CHUNKS - paths * c / MC_CHUNKS;
            double m = n > 0 ? j.tally[(size_t)c * TALLY(bins) + b] / (double)n : mean;
            ss += (m - mean) * (m - mean);
        }
        out->r_profile_stderr[b] = sqrt(ss / ((double)MC_CHUNKS * (MC_CHUNKS - 1)));
    }
    lu_free(j.tally);
    for (int b = 0; b < bins; b++) {
        double area = M_PI * dr * dr * ((b + 1.0) * (b + 1.0) - (double)b * b);
        out->r_profile_stderr[b] /= area;
        out->r_profile[b] /= (double)paths * area;
        out->t_profile[b] /= (double)paths * area;
        out->r_multiple[b] /= (double)paths * area;
    }
    out->r_total /= (double)paths;
    out->t_total /= (double)paths;
    out->r_multiple_total /= (double)paths;
    out->dropped /= (double)paths;
    out->r_multiple_unreflected_total /= (double)paths;
    out->r_stderr = sqrt(fmax(0.0, sq / (double)paths - out->r_total * out->r_total) / (double)paths);
    out->bins = bins;
    out->dr = dr;
    return LU_OK;
}

void lu_bssrdf_mc_destroy(lu_bssrdf_mc_result *r) {
    if (!r) return;
    lu_free(r->r_profile);
    lu_free(r->t_profile);
    lu_free(r->r_multiple);
    lu_free(r->r_profile_stderr);
    memset(r, 0, sizeof *r);
}
