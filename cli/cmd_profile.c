/* lucent profile — diffusion profiles of a translucent material (the tables
 * the bssrdf method splats), their energy against the closed forms, and a
 * Monte Carlo random walk of the same slab to show where diffusion departs. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "methods/bssrdf/lu_diffusion.h"
#include "methods/bssrdf/bssrdf_profile.h"
#include "methods/bssrdf/profile_mc.h"

static void usage(void) {
    printf("usage: lucent profile [--preset NAME | --sigma-s R,G,B --sigma-a R,G,B] [options]\n"
           "\n"
           "Builds the diffusion profile the bssrdf method uses for one material (coefficients\n"
           "per millimetre; lengths printed in mm), reports r_max and the total diffuse\n"
           "reflectance three ways: closed form, Simpson of 2 pi r R(r) over [0, inf), and the\n"
           "table as the renderer reads it. With --mc N, also a brute-force random walk of N\n"
           "paths in the same slab (pencil beam, isotropic scattering with sigma_s', Fresnel\n"
           "faces), with the rel-L2 of the profile against it.\n"
           "\n"
           "options:\n"
           "  --preset NAME       a Jensen et al. 2001 material (see --list)\n"
           "  --sigma-s R,G,B     reduced scattering per mm (instead of a preset)\n"
           "  --sigma-a R,G,B     absorption per mm\n"
           "  --eta E             relative index of refraction (default: the preset's, else 1.3)\n"
           "  --model M           dipole, multipole, burley or pbd (default dipole)\n"
           "  --thickness MM      multipole: slab thickness (default: 64 mean free paths, as the table's end)\n"
           "  --table-size N      entries along r (default 512)\n"
           "  --epsilon E         r_max criterion (default 0.01)\n"
           "  --mc N              random-walk paths (e.g. 1000000)\n"
           "  --bins N            Monte Carlo radial bins over [0, r_max] (default 64)\n"
           "  --seed S            Monte Carlo seed (default 1)\n"
           "  --csv FILE          write r, model and Monte Carlo profiles per channel\n"
           "  --all               one line per preset: r_max and totals (dipole), with --mc the walk too\n"
           "  --list              list the presets\n");
}

static bool parse3(const char *s, double v[3]) {
    char tail;
    int n = sscanf(s, "%lf,%lf,%lf%c", &v[0], &v[1], &v[2], &tail);
    if (n == 1) {
        v[1] = v[2] = v[0];
        return true;
    }
    return n == 3;
}

typedef struct opts {
    lu_bssrdf_profile_desc desc;
    double thickness;   /* mm, multipole */
    long long mc;
    int bins;
    unsigned long long seed;
    const char *csv;
} opts;

/* Model profile averaged over the annulus [r0, r1] (area-weighted). */
static double annulus_mean(const lu_k_diffusion *k, const opts *o, int ch, double r0, double r1, int transmit,
                           float burley_a, float burley_h, const lu_bssrdf_profile *prof) {
    enum { N = 32 };
    double sum = 0.0, h = (r1 - r0) / N;
    for (int i = 0; i <= N; i++) {
        double r = r0 + i * h, w = (i == 0 || i == N) ? 1.0 : (i & 1 ? 4.0 : 2.0);
        double f;
        float s = lu_v3_get(k->sigma_tr, ch), a = lu_v3_get(k->alpha_p, ch), l = lu_v3_get(k->l, ch);
        float zb0 = lu_v3_get(k->zb_top, ch), zbd = lu_v3_get(k->zb_bottom, ch);
        if (o->desc.model == LU_BSSRDF_MULTIPOLE)
            f = lu_k_multipole1((float)r, (float)o->thickness, o->desc.pairs, transmit, s, a, l, zb0, zbd);
        else if (o->desc.model == LU_BSSRDF_BURLEY)
            f = r > 0.0 ? lu_k_burley1((float)r, burley_a, burley_h) : 0.0;
        else if (o->desc.model == LU_BSSRDF_PBD) /* tabulated: the table the renderer reads */
            f = transmit ? 0.0 : lu_v3_get(lu_bssrdf_profile_eval(prof, (float)r, 0.0f, 0), ch);
        else
            f = transmit ? 0.0 : lu_k_dipole1((float)r, s, a, l, zb0);
        sum += w * 2.0 * M_PI * r * f;
    }
    sum *= h / 3.0;
    return sum / (M_PI * (r1 * r1 - r0 * r0));
}

typedef struct mc_summary {
    double total[3], stderr_[3], t_total[3], multiple[3], unreflected[3];
    double rel_l2_ms[3];       /* model vs multiply scattered light only */
    double rel_l2[3];          /* model vs walk over [0, r_max], area-weighted */
    double mean_rel[3];        /* energy-weighted mean |model - walk| / walk over the bins: sum |M - W| / sum W of bin powers */
    /* Reflected power model / walk (multiply scattered) within bands of the
     * channel's mean free path l: r < l, l <= r < 10 l, r >= 10 l (to r_max). */
    double band[3][3];
} mc_summary;

static int run_one(const char *name, lu_vec3 ss, lu_vec3 sa, float eta, opts *o, bool verbose, mc_summary *ms,
                   lu_bssrdf_profile *prof_out) {
    lu_error err = {0};
    lu_bssrdf_layer layer = {ss, sa, eta, 0.0f};
    lu_bssrdf_profile prof;
    lu_bssrdf_profile_desc desc = o->desc;
    if (lu_bssrdf_profile_build(&layer, 1, &desc, &prof, &err) != LU_OK) return lu_cli_error("profile", &err);
    if (o->desc.model == LU_BSSRDF_MULTIPOLE && !(o->thickness > 0.0)) o->thickness = prof.d_hi;
    lu_k_diffusion k = lu_k_diffusion_make(ss, sa, eta, eta);
    if (verbose) {
        printf("material %s: sigma_s' = %g %g %g /mm, sigma_a = %g %g %g /mm, eta %g\n", name, ss.x, ss.y, ss.z, sa.x,
               sa.y, sa.z, eta);
        printf("  mean free path 1/sigma_t'   %10.5g %10.5g %10.5g mm\n", k.l.x, k.l.y, k.l.z);
        printf("  sigma_tr                    %10.5g %10.5g %10.5g /mm\n", k.sigma_tr.x, k.sigma_tr.y, k.sigma_tr.z);
        printf("  reduced albedo              %10.5g %10.5g %10.5g\n", k.alpha_p.x, k.alpha_p.y, k.alpha_p.z);
        printf("  A (F_dr %.4f)               %10.5g\n", lu_k_fdr(eta), lu_k_diffusion_a(eta));
        printf("  model %s, %d entries, r_max %.5g mm (eps %g)\n",
               o->desc.model == LU_BSSRDF_MULTIPOLE ? "multipole" : o->desc.model == LU_BSSRDF_BURLEY ? "burley"
               : o->desc.model == LU_BSSRDF_PBD       ? "pbd"
                                                      : "dipole",
               prof.nr, prof.r_max, o->desc.epsilon);
        if (o->desc.model == LU_BSSRDF_MULTIPOLE) {
            printf("  thickness d %.5g mm (table rows %.4g..%.4g mm)\n", o->thickness, prof.d_lo, prof.d_hi);
            double R[3], T[3];
            for (int c = 0; c < 3; c++)
                lu_bssrdf_slab_totals(lu_v3_get(ss, c), lu_v3_get(sa, c), eta, eta, o->thickness, &R[c], &T[c]);
            printf("  slab of thickness d, closed form (1D Green's function)\n");
            printf("    reflectance               %10.6f %10.6f %10.6f\n", R[0], R[1], R[2]);
            printf("    transmittance             %10.6f %10.6f %10.6f\n", T[0], T[1], T[2]);
        }
        const char *lbl = o->desc.model == LU_BSSRDF_MULTIPOLE ? "(R at the table's thickest row)" : "";
        printf("  total reflectance %s\n", lbl);
        printf("    closed form               %10.6f %10.6f %10.6f\n", prof.total_closed[0], prof.total_closed[1],
               prof.total_closed[2]);
        printf("    Simpson, [0, inf)         %10.6f %10.6f %10.6f\n", prof.total_numeric[0], prof.total_numeric[1],
               prof.total_numeric[2]);
        printf("    table, [0, r_max]         %10.6f %10.6f %10.6f\n", prof.total_table[0], prof.total_table[1],
               prof.total_table[2]);
    }
    memset(ms, 0, sizeof *ms);
    double *mc_r[3] = {0}, *mc_t[3] = {0}, *mc_m[3] = {0};
    int rc = LU_EXIT_OK;
    float burley_a[3], burley_h[3];
    for (int c = 0; c < 3; c++) {
        float s = lu_v3_get(k.sigma_tr, c), l = lu_v3_get(k.l, c);
        burley_a[c] = lu_k_dipole_total1(s, lu_v3_get(k.alpha_p, c), l, lu_v3_get(k.zb_top, c));
        burley_h[c] = lu_k_burley_h(burley_a[c], l);
    }
    double dr = prof.r_max / o->bins;
    if (o->mc > 0) {
        double thick = o->desc.model == LU_BSSRDF_MULTIPOLE ? o->thickness : INFINITY;
        for (int c = 0; c < 3 && rc == LU_EXIT_OK; c++) {
            lu_bssrdf_mc_result res;
            if (lu_bssrdf_mc_slab(lu_v3_get(ss, c), lu_v3_get(sa, c), eta, thick, o->mc, o->seed + (unsigned)c, o->bins + 1,
                                  dr, &res, &err) != LU_OK) {
                rc = lu_cli_error("profile", &err);
                break;
            }
            ms->total[c] = res.r_total;
            ms->stderr_[c] = res.r_stderr;
            ms->t_total[c] = res.t_total;
            ms->multiple[c] = res.r_multiple_total;
            ms->unreflected[c] = res.r_multiple_unreflected_total;
            mc_r[c] = res.r_profile;
            mc_t[c] = res.t_profile;
            mc_m[c] = res.r_multiple;
            double num = 0.0, den = 0.0, num_m = 0.0, den_m = 0.0, bm[3] = {0}, bw[3] = {0}, num_e = 0.0, den_e = 0.0;
            double lch = lu_v3_get(k.l, c);
            for (int b = 0; b < o->bins; b++) {
                double model = annulus_mean(&k, o, c, b * dr, (b + 1) * dr, 0, burley_a[c], burley_h[c], &prof);
                double area = M_PI * dr * dr * ((b + 1.0) * (b + 1.0) - (double)b * b);
                num += area * (model - mc_r[c][b]) * (model - mc_r[c][b]);
                den += area * mc_r[c][b] * mc_r[c][b];
                num_e += area * fabs(model - mc_r[c][b]);
                den_e += area * mc_r[c][b];
                num_m += area * (model - mc_m[c][b]) * (model - mc_m[c][b]);
                den_m += area * mc_m[c][b] * mc_m[c][b];
                double rcen = (b + 0.5) * dr;
                int band = rcen < lch ? 0 : (rcen < 10.0 * lch ? 1 : 2);
                bm[band] += area * model;
                bw[band] += area * mc_m[c][b];
            }
            ms->rel_l2[c] = den > 0.0 ? sqrt(num / den) : 0.0;
            ms->mean_rel[c] = den_e > 0.0 ? num_e / den_e : 0.0;
            ms->rel_l2_ms[c] = den_m > 0.0 ? sqrt(num_m / den_m) : 0.0;
            for (int q = 0; q < 3; q++) ms->band[q][c] = bw[q] > 0.0 ? bm[q] / bw[q] : NAN;
        }
        if (verbose && rc == LU_EXIT_OK) {
            printf("  random walk, %lld paths per channel%s\n", o->mc,
                   isfinite(thick) ? "" : " (semi-infinite)");
            printf("    total reflectance         %10.6f %10.6f %10.6f  (+- %.1e %.1e %.1e)\n", ms->total[0],
                   ms->total[1], ms->total[2], ms->stderr_[0], ms->stderr_[1], ms->stderr_[2]);
            if (isfinite(thick))
                printf("    total transmittance       %10.6f %10.6f %10.6f\n", ms->t_total[0], ms->t_total[1],
                       ms->t_total[2]);
            printf("    multiple scattering only  %10.6f %10.6f %10.6f\n", ms->multiple[0], ms->multiple[1],
                   ms->multiple[2]);
            /* the part a path tracer joining vertices to the light's beams by
             * straight segments reaches (docs/bssrdf.md) */
            printf("    multiple, no 1-2 reflection %8.6f %10.6f %10.6f\n", ms->unreflected[0], ms->unreflected[1],
                   ms->unreflected[2]);
            printf("    model rel-L2 on [0, r_max] %9.4f %10.4f %10.4f  (all light)\n", ms->rel_l2[0], ms->rel_l2[1],
                   ms->rel_l2[2]);
            printf("    model mean rel. error      %9.4f %10.4f %10.4f  (energy-weighted over the bins, all light)\n",
                   ms->mean_rel[0], ms->mean_rel[1], ms->mean_rel[2]);
            printf("    model rel-L2 on [0, r_max] %9.4f %10.4f %10.4f  (multiple scattering only)\n", ms->rel_l2_ms[0],
                   ms->rel_l2_ms[1], ms->rel_l2_ms[2]);
            static const char *const names[3] = {"r < 1 mfp", "1-10 mfp", "10 mfp-r_max"};
            for (int q = 0; q < 3; q++)
                printf("    power model/walk %-12s %7.4f %10.4f %10.4f  (multiple scattering)\n", names[q], ms->band[q][0],
                       ms->band[q][1], ms->band[q][2]);
        }
    }
    if (rc == LU_EXIT_OK && o->csv) {
        FILE *f = fopen(o->csv, "w");
        if (!f) {
            fprintf(stderr, "lucent profile: error: cannot write %s\n", o->csv);
            rc = LU_EXIT_FAIL;
        } else {
            fprintf(f, "r_mm,model_r,model_g,model_b,mc_r,mc_g,mc_b,mc_ms_r,mc_ms_g,mc_ms_b,model_t_r,model_t_g,model_t_b,"
                       "mc_t_r,mc_t_g,mc_t_b\n");
            for (int b = 0; b < o->bins; b++) {
                double rm = (b + 0.5) * dr;
                fprintf(f, "%.6g", rm);
                for (int c = 0; c < 3; c++)
                    fprintf(f, ",%.6g", annulus_mean(&k, o, c, b * dr, (b + 1) * dr, 0, burley_a[c], burley_h[c], &prof));
                for (int c = 0; c < 3; c++) fprintf(f, ",%.6g", mc_r[c] ? mc_r[c][b] : 0.0);
                for (int c = 0; c < 3; c++) fprintf(f, ",%.6g", mc_m[c] ? mc_m[c][b] : 0.0);
                for (int c = 0; c < 3; c++)
                    fprintf(f, ",%.6g", annulus_mean(&k, o, c, b * dr, (b + 1) * dr, 1, burley_a[c], burley_h[c], &prof));
                for (int c = 0; c < 3; c++) fprintf(f, ",%.6g", mc_t[c] ? mc_t[c][b] : 0.0);
                fprintf(f, "\n");
            }
            fclose(f);
        }
    }
    for (int c = 0; c < 3; c++) {
        lu_bssrdf_mc_result tmp = {0};
        tmp.r_profile = mc_r[c];
        tmp.t_profile = mc_t[c];
        tmp.r_multiple = mc_m[c];
        lu_bssrdf_mc_destroy(&tmp);
    }
    if (prof_out) *prof_out = prof;
    else lu_bssrdf_profile_destroy(&prof);
    return rc;
}

int lu_cmd_profile(int argc, char **argv) {
    opts o;
    memset(&o, 0, sizeof o);
    lu_bssrdf_profile_desc_default(&o.desc);
    o.bins = 64;
    o.seed = 1;
    const char *preset = NULL;
    double ss[3], sa[3];
    bool has_ss = false, has_sa = false, all = false;
    double eta = -1.0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool nx = i + 1 < argc;
        if (lu_cli_is_help(a)) {
            usage();
            return LU_EXIT_OK;
        } else if (strcmp(a, "--list") == 0) {
            int n;
            const lu_material_preset *p = lu_material_presets(&n);
            for (int k = 0; k < n; k++)
                printf("%-12s sigma_s' %6g %6g %6g  sigma_a %7g %7g %7g  eta %g\n", p[k].name, p[k].sigma_s_prime[0],
                       p[k].sigma_s_prime[1], p[k].sigma_s_prime[2], p[k].sigma_a[0], p[k].sigma_a[1], p[k].sigma_a[2],
                       p[k].eta);
            return LU_EXIT_OK;
        } else if (strcmp(a, "--preset") == 0 && nx) {
            preset = argv[++i];
        } else if (strcmp(a, "--sigma-s") == 0 && nx) {
            if (!parse3(argv[++i], ss)) return lu_cli_usage("profile", "--sigma-s takes R,G,B");
            has_ss = true;
        } else if (strcmp(a, "--sigma-a") == 0 && nx) {
            if (!parse3(argv[++i], sa)) return lu_cli_usage("profile", "--sigma-a takes R,G,B");
            has_sa = true;
        } else if (strcmp(a, "--eta") == 0 && nx) {
            eta = atof(argv[++i]);
            if (!(eta >= 1.0 && eta <= 4.0)) return lu_cli_usage("profile", "--eta must be in [1, 4]");
        } else if (strcmp(a, "--model") == 0 && nx) {
            const char *m = argv[++i];
            if (strcmp(m, "dipole") == 0) o.desc.model = LU_BSSRDF_DIPOLE;
            else if (strcmp(m, "multipole") == 0) o.desc.model = LU_BSSRDF_MULTIPOLE;
            else if (strcmp(m, "burley") == 0) o.desc.model = LU_BSSRDF_BURLEY;
            else if (strcmp(m, "pbd") == 0) o.desc.model = LU_BSSRDF_PBD;
            else return lu_cli_usage("profile", "--model takes dipole, multipole, burley or pbd");
        } else if (strcmp(a, "--thickness") == 0 && nx) {
            o.thickness = atof(argv[++i]);
            if (!(o.thickness > 0.0)) return lu_cli_usage("profile", "--thickness must be > 0");
        } else if (strcmp(a, "--table-size") == 0 && nx) {
            o.desc.table_size = atoi(argv[++i]);
            if (o.desc.table_size < 4 || o.desc.table_size > 65536)
                return lu_cli_usage("profile", "--table-size must be in [4, 65536]");
        } else if (strcmp(a, "--epsilon") == 0 && nx) {
            o.desc.epsilon = atof(argv[++i]);
            if (!(o.desc.epsilon > 0.0 && o.desc.epsilon < 1.0)) return lu_cli_usage("profile", "--epsilon in (0, 1)");
        } else if (strcmp(a, "--mc") == 0 && nx) {
            o.mc = atoll(argv[++i]);
            if (o.mc < 1) return lu_cli_usage("profile", "--mc takes a path count >= 1");
        } else if (strcmp(a, "--bins") == 0 && nx) {
            o.bins = atoi(argv[++i]);
            if (o.bins < 2 || o.bins > 100000) return lu_cli_usage("profile", "--bins in [2, 100000]");
        } else if (strcmp(a, "--seed") == 0 && nx) {
            o.seed = strtoull(argv[++i], NULL, 10);
        } else if (strcmp(a, "--csv") == 0 && nx) {
            o.csv = argv[++i];
        } else if (strcmp(a, "--all") == 0) {
            all = true;
        } else {
            return lu_cli_usage("profile", "unexpected argument \"%s\"", a);
        }
    }
    if (all) {
        int n;
        const lu_material_preset *p = lu_material_presets(&n);
        printf("preset,channel,r_max_mm,closed,simpson,table,simpson_rel,table_rel%s\n",
               o.mc > 0 ? ",mc,mc_stderr,mc_rel,mc_multiple,profile_rel_l2,profile_rel_l2_multiple,band_lt1,band_1_10,band_gt10" : "");
        for (int k = 0; k < n; k++) {
            mc_summary ms;
            lu_bssrdf_profile prof;
            const char *saved = o.csv;
            o.csv = NULL;
            int rc = run_one(p[k].name, lu_v3(p[k].sigma_s_prime[0], p[k].sigma_s_prime[1], p[k].sigma_s_prime[2]),
                             lu_v3(p[k].sigma_a[0], p[k].sigma_a[1], p[k].sigma_a[2]), eta > 0 ? (float)eta : p[k].eta,
                             &o, false, &ms, &prof);
            o.csv = saved;
            if (rc != LU_EXIT_OK) return rc;
            for (int c = 0; c < 3; c++) {
                printf("%s,%c,%.5g,%.6f,%.6f,%.6f,%.2e,%.2e", p[k].name, "RGB"[c], prof.r_max, prof.total_closed[c],
                       prof.total_numeric[c], prof.total_table[c],
                       (prof.total_numeric[c] - prof.total_closed[c]) / prof.total_closed[c],
                       (prof.total_table[c] - prof.total_closed[c]) / prof.total_closed[c]);
                if (o.mc > 0)
                    printf(",%.6f,%.1e,%.4f,%.6f,%.4f,%.4f,%.4f,%.4f,%.4f", ms.total[c], ms.stderr_[c],
                           (prof.total_closed[c] - ms.total[c]) / ms.total[c], ms.multiple[c], ms.rel_l2[c],
                           ms.rel_l2_ms[c], ms.band[0][c], ms.band[1][c], ms.band[2][c]);
                printf("\n");
            }
            lu_bssrdf_profile_destroy(&prof);
        }
        return LU_EXIT_OK;
    }
    lu_vec3 vss, vsa;
    float veta = eta > 0 ? (float)eta : 1.3f;
    const char *name = "custom";
    if (preset) {
        const lu_material_preset *p = lu_material_preset_find(preset);
        if (!p) return lu_cli_usage("profile", "unknown preset \"%s\" (see --list)", preset);
        vss = lu_v3(p->sigma_s_prime[0], p->sigma_s_prime[1], p->sigma_s_prime[2]);
        vsa = lu_v3(p->sigma_a[0], p->sigma_a[1], p->sigma_a[2]);
        if (eta < 0) veta = p->eta;
        name = p->name;
    }
    if (has_ss) vss = lu_v3((float)ss[0], (float)ss[1], (float)ss[2]);
    if (has_sa) vsa = lu_v3((float)sa[0], (float)sa[1], (float)sa[2]);
    if (!preset && !(has_ss && has_sa)) return lu_cli_usage("profile", "give --preset or both --sigma-s and --sigma-a");
    mc_summary ms;
    return run_one(name, vss, vsa, veta, &o, true, &ms, NULL);
}
