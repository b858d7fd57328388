/* Triangle adjacency across edges, vertices welded by position (see
 * mesh_adjacency.h). */
#include "methods/common/mesh_adjacency.h"

#include <stdlib.h>

typedef struct edge_rec {
    uint64_t key;
    uint32_t tri;
    uint8_t edge;
} edge_rec;

static int cmp_edge(const void *a, const void *b) {
    const edge_rec *x = a, *y = b;
    return x->key < y->key ? -1 : x->key > y->key;
}

typedef struct vkey {
    lu_vec3 p;
    uint32_t index;
} vkey;

static int cmp_vkey(const void *a, const void *b) {
    const vkey *x = a, *y = b;
    if (x->p.x != y->p.x) return x->p.x < y->p.x ? -1 : 1;
    if (x->p.y != y->p.y) return x->p.y < y->p.y ? -1 : 1;
    if (x->p.z != y->p.z) return x->p.z < y->p.z ? -1 : 1;
    return 0;
}

lu_result lu_mesh_edge_neighbours(const lu_mesh *m, uint32_t **out, lu_error *err) {
    uint32_t nt = m->triangle_count, nv = m->vertex_count;
    uint32_t *weld = lu_malloc((size_t)nv * sizeof *weld);
    vkey *vk = lu_malloc((size_t)nv * sizeof *vk);
    edge_rec *e = lu_malloc((size_t)3 * nt * sizeof *e);
    uint32_t *nb = lu_malloc((size_t)3 * nt * sizeof *nb);
    if (!weld || !vk || !e || !nb) {
        lu_free(weld);
        lu_free(vk);
        lu_free(e);
        lu_free(nb);
        return lu_fail(err, LU_ERR_NOMEM, "out of memory for mesh adjacency");
    }
    for (uint32_t i = 0; i < nv; i++) vk[i] = (vkey){m->positions[i], i};
    qsort(vk, nv, sizeof *vk, cmp_vkey);
    for (uint32_t i = 0; i < nv; i++)
        weld[vk[i].index] = i > 0 && cmp_vkey(&vk[i], &vk[i - 1]) == 0 ? weld[vk[i - 1].index] : vk[i].index;
    for (uint32_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            uint64_t a = weld[m->indices[3u * t + k]], b = weld[m->indices[3u * t + (k + 1) % 3]];
            e[3u * t + k] = (edge_rec){a < b ? (a << 32) | b : (b << 32) | a, t, (uint8_t)k};
            nb[3u * t + k] = UINT32_MAX;
        }
    qsort(e, (size_t)3 * nt, sizeof *e, cmp_edge);
    for (size_t i = 0; i < (size_t)3 * nt;) {
        size_t j = i;
        while (j < (size_t)3 * nt && e[j].key == e[i].key) j++;
        if (j - i == 2) {
            nb[3u * e[i].tri + e[i].edge] = e[i + 1].tri;
            nb[3u * e[i + 1].tri + e[i + 1].edge] = e[i].tri;
        }
        i = j;
    }
    lu_free(weld);
    lu_free(vk);
    lu_free(e);
    *out = nb;
    return LU_OK;
}

