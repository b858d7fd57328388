/* lucent.h — translucent materials and participating media in real time,
 * judged against a ground truth computed by the same library.
 *
 * Table of contents (one header per area):
 *   core.h      results and errors, settings (key=value), threads, progress, atomic files
 *   math.h      vectors, affine maps, boxes
 *   image.h     linear RGB images, PNG / EXR / PFM, error metrics
 *   mesh.h      triangle meshes: OBJ, PLY(.gz), procedural shapes
 *   grid.h      density grids: NanoVDB, raw, procedural
 *   geometry.h  ray queries (Embree), inside tests, voxelisation
 *   scene.h     the scene contract: camera, lights, media, objects
 *   method.h    the method table: prepare / render / destroy + parameters
 *
 * The data path reads as a straight line:
 *   lu_scene_load -> lu_renderer_create (prepare) -> lu_renderer_render -> lu_image_save */
#ifndef LUCENT_H
#define LUCENT_H

#include "core.h"
#include "math.h"
#include "image.h"
#include "mesh.h"
#include "grid.h"
#include "geometry.h"
#include "scene.h"
#include "method.h"

#endif
