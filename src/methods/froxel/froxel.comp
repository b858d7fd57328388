/* froxel.comp — the froxel method on the GPU: the three passes of
 * lu_froxel.h (u_pass 0: light each cell, 1: integrate each column,
 * 2: composite each pixel) over the shared GPU scene and the frame buffers
 * the CPU built (camera hits, spans, light views, shadow maps, surface
 * visibility, column spans). The grids are the records of
 * lu_froxel_grid.h, set as uniform structs. */
layout(local_size_x = 8, local_size_y = 8) in;

#include "kernels/lu_scene_gpu.glsl"
#include "methods/common/lu_lightview.h"

#include "methods/common/lu_view_march_gpu.glsl"
#include "methods/froxel/lu_froxel_grid.h"

layout(std430, binding = LU_RM_BINDING_NEXT) writeonly buffer Out { float fx_out[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 1) readonly buffer FxSurfaceVis { float fx_surface_vis[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 2) readonly buffer FxColumnSpans { float fx_cspans[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 3) buffer FxLit { float fx_lit[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 4) readonly buffer FxHist { float fx_hist[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 5) buffer FxInt { float fx_int[]; };

uniform float u_eps;
uniform float u_t_cut;
uniform vec3 u_background;
uniform int u_pass;
uniform lu_k_fx_grid u_g;    /* this frame's grid */
uniform lu_k_fx_grid u_p;    /* the previous frame's */
uniform int u_history;
uniform float u_blend;
uniform int u_cull;

float lu_k_rm_surface_vis(LU_CTX_PARAM, int pixel, int l) { return fx_surface_vis[pixel * lu_scene_light_count() + l]; }
#define LU_K_RM_SURFACE_VIS(l, pixel, x, n) lu_k_rm_surface_vis(LU_CTX, pixel, l)

/* FxColumnSpans: each column's reach, then its spans (froxel.c). */
float lu_k_fx_reach(LU_CTX_PARAM, int column) { return fx_cspans[column]; }
float lu_k_fx_span(LU_CTX_PARAM, int column, int m, int end) {
    return fx_cspans[u_g.nx * u_g.ny + (column * lu_scene_medium_count() + m) * 2 + end];
}
float lu_k_fx_hist_valid(LU_CTX_PARAM, int cell) { return fx_hist[cell * LU_K_FX_CELL_FLOATS + 3]; }
vec3 lu_k_fx_lit(LU_CTX_PARAM, int cell, int part) {
    int b = cell * LU_K_FX_CELL_FLOATS + 4 * part;
    return vec3(fx_lit[b], fx_lit[b + 1], fx_lit[b + 2]);
}
vec3 lu_k_fx_hist(LU_CTX_PARAM, int cell, int part) {
    int b = cell * LU_K_FX_CELL_FLOATS + 4 * part;
    return vec3(fx_hist[b], fx_hist[b + 1], fx_hist[b + 2]);
}
vec3 lu_k_fx_int(LU_CTX_PARAM, int node, int part) {
    int b = node * LU_K_FX_CELL_FLOATS + 4 * part;
    return vec3(fx_int[b], fx_int[b + 1], fx_int[b + 2]);
}
void lu_k_fx_int_store(LU_CTX_PARAM, int node, vec3 L, vec3 tau) {
    int b = node * LU_K_FX_CELL_FLOATS;
    fx_int[b] = L.x;
    fx_int[b + 1] = L.y;
    fx_int[b + 2] = L.z;
    fx_int[b + 3] = 0.0;
    fx_int[b + 4] = tau.x;
    fx_int[b + 5] = tau.y;
    fx_int[b + 6] = tau.z;
    fx_int[b + 7] = 0.0;
}

#include "methods/froxel/lu_froxel.h"

void main() {
    int x = int(gl_GlobalInvocationID.x), y = int(gl_GlobalInvocationID.y), k = int(gl_GlobalInvocationID.z);
    lu_k_rm_params P;
    P.background = u_background;
    P.step = 1.0;
    P.eps = u_eps;
    P.jitter = 0;
    P.map_res = u_map_res;
    P.t_cut = u_t_cut;
    P.ms = lu_rm_ms_uniform();
    lu_k_fx_grid G = u_g;
    if (u_pass == 2) {
        if (x >= G.width || y >= G.height) return;
        vec3 L = lu_k_fx_pixel(0, P, G, x, y);
        int px = y * G.width + x;
        fx_out[3 * px] = L.x;
        fx_out[3 * px + 1] = L.y;
        fx_out[3 * px + 2] = L.z;
        return;
    }
    if (x >= G.nx || y >= G.ny) return;
    if (u_pass == 1) {
        lu_k_fx_integrate(0, G, x, y);
        return;
    }
    vec3 S = vec3(0.0), sig = vec3(0.0);
    float lit = lu_k_fx_light(0, P, G, x, y, k, u_history, u_p, u_blend, u_cull, S, sig);
    int b = lu_k_fx_cell(G, x, y, k) * LU_K_FX_CELL_FLOATS;
    fx_lit[b] = S.x;
    fx_lit[b + 1] = S.y;
    fx_lit[b + 2] = S.z;
    fx_lit[b + 3] = lit;
    fx_lit[b + 4] = sig.x;
    fx_lit[b + 5] = sig.y;
    fx_lit[b + 6] = sig.z;
    fx_lit[b + 7] = 0.0;
}
