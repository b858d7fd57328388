/* gradient.comp — the gradient family (gradient, rbf, pervoxel) on the GPU:
 * methods/gradient/lu_gradient.h over the shared GPU scene, one invocation per item
 * of the pass selected by u_pass:
 *   0  sample evaluation: F, gradient, E_j, tau (u_count samples, in place);
 *   1  radiance grid: one voxel each (gather over the cell lists, or traced);
 *   2  view march: one pixel each (lu_view_march.h's march with the grid source);
 *   3  tau_v of the samples (u_count, into the odd floats of ErrTau). */
layout(local_size_x = 64) in;

#include "kernels/lu_scene_gpu.glsl"
#include "methods/common/lu_lightview.h"
#include "lu_gradient_params.h"

layout(std430, binding = LU_SCENE_BINDING_FREE) readonly buffer Hits { float gr_hits[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 1) readonly buffer Spans { float gr_spans[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 2) readonly buffer Views { vec4 gr_views[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 3) readonly buffer ViewTable { int gr_view_table[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 4) readonly buffer Shadow { float gr_shadow[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 5) writeonly buffer Out { float gr_out[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 6) buffer Samples { float gr_samples[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 7) readonly buffer Cells { int gr_cells[]; };  // begins, then items
layout(std430, binding = LU_SCENE_BINDING_FREE + 8) readonly buffer Surf { float gr_surf[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 9) buffer Field { float gr_field[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 10) readonly buffer Params { lu_k_gr_params gr_par; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 11) buffer ErrTau { float gr_et[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 12) readonly buffer BMap { float gr_bmap[]; };

uniform int u_pass;
uniform int u_count;
uniform int u_want_error;
uniform float u_step;
uniform float u_eps;
uniform float u_t_cut;
uniform vec3 u_background;

float lu_k_shadow_depth(LU_CTX_PARAM, int map, int i, int j) {
    return gr_shadow[(map * gr_par.map_res + j) * gr_par.map_res + i];
}
int lu_k_rm_view_first(LU_CTX_PARAM, int l) { return gr_view_table[2 * l]; }
int lu_k_rm_view_count(LU_CTX_PARAM, int l) { return gr_view_table[2 * l + 1]; }
lu_k_lightview lu_k_rm_view(LU_CTX_PARAM, int v) {
    lu_k_lightview w;
    w.origin = gr_views[4 * v].xyz;
    w.ortho = int(gr_views[4 * v].w);
    w.axis_u = gr_views[4 * v + 1].xyz;
    w.extent_u = gr_views[4 * v + 1].w;
    w.axis_v = gr_views[4 * v + 2].xyz;
    w.extent_v = gr_views[4 * v + 2].w;
    w.axis_w = gr_views[4 * v + 3].xyz;
    w.depth_far = gr_views[4 * v + 3].w;
    return w;
}
float lu_k_rm_hit_fetch(LU_CTX_PARAM, int pixel, int k) { return gr_hits[pixel * 16 + k]; }
float lu_k_rm_span(LU_CTX_PARAM, int pixel, int m, int end) {
    return gr_spans[(pixel * lu_scene_medium_count() + m) * 2 + end];
}
lu_k_gr_params lu_k_gr_get(LU_CTX_PARAM) { return gr_par; }
vec3 lu_k_gr_field(LU_CTX_PARAM, int i) { return vec3(gr_field[3 * i], gr_field[3 * i + 1], gr_field[3 * i + 2]); }
float lu_k_gr_bmap_at(LU_CTX_PARAM, int k) { return gr_bmap[k]; }
int lu_k_gr_cell_begin(LU_CTX_PARAM, int c) { return gr_cells[c]; }
int lu_k_gr_cell_end(LU_CTX_PARAM, int c) { return gr_cells[c + 1]; }
int lu_k_gr_cell_item(LU_CTX_PARAM, int k) { return gr_cells[gr_par.cx * gr_par.cy * gr_par.cz + 1 + k]; }
float lu_k_gr_surf(LU_CTX_PARAM, int k) { return gr_surf[k]; }
float lu_k_gr_sample_fetch(LU_CTX_PARAM, int j, int k) { return gr_samples[j * LU_K_GR_SAMPLE_FLOATS + k]; }

#include "lu_gradient.h"

void put3(int base, vec3 v) {
    gr_samples[base] = v.x;
    gr_samples[base + 1] = v.y;
    gr_samples[base + 2] = v.z;
}

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    lu_k_gr_params G = gr_par;
    if (u_pass == 0) {
        int b = i * LU_K_GR_SAMPLE_FLOATS;
        vec3 x = vec3(gr_samples[b], gr_samples[b + 1], gr_samples[b + 2]);
        vec3 F, gx, gy, gz;
        float E, tau;
        lu_k_gr_eval(0, G, x, gr_samples[b + 3], gr_et[2 * i + 1], u_want_error, F, gx, gy, gz, E, tau);
        put3(b + 8, F);
        put3(b + 12, gx);
        put3(b + 16, gy);
        put3(b + 20, gz);
        gr_et[2 * i] = E;
        gr_et[2 * i + 1] = tau;
    } else if (u_pass == 1) {
        vec3 v = lu_k_gr_voxel(0, G, i);
        gr_field[3 * i] = v.x;
        gr_field[3 * i + 1] = v.y;
        gr_field[3 * i + 2] = v.z;
    } else if (u_pass == 3) {
        int b = i * LU_K_GR_SAMPLE_FLOATS;
        gr_et[2 * i + 1] = lu_k_gr_view_tau(0, G, vec3(gr_samples[b], gr_samples[b + 1], gr_samples[b + 2]));
    } else {
        int w = lu_scene_width();
        int x = i % w, y = i / w;
        lu_k_rm_params P;
        P.background = u_background;
        P.step = u_step;
        P.eps = u_eps;
        P.jitter = 0;
        P.map_res = G.map_res;
        P.t_cut = u_t_cut;
        P.ms = G.ms; /* unused: the octaves are in the radiance grid */
        vec3 d = lu_k_camera_dir(lu_scene_camera(), float(x) + 0.5, float(y) + 0.5);
        vec3 L = lu_k_gr_radiance(0, P, i, lu_scene_camera_position(), d);
        gr_out[3 * i] = L.x;
        gr_out[3 * i + 1] = L.y;
        gr_out[3 * i + 2] = L.z;
    }
}
