/* Seeded gradient noise for the procedural density generators.
 *
 * lu_noise3 is Perlin-style gradient noise on the integer lattice: each
 * lattice point gets one of the 12 cube-edge gradients (1,1,0)-style, picked
 * by an integer hash of (x, y, z, seed) rather than a permutation table, so
 * it does not repeat every 256 units and the seed changes everything. The
 * eight corner contributions dot(gradient, offset) are blended with the
 * quintic fade 6t^5 - 15t^4 + 10t^3 (C2 continuous). Properties the tests
 * rely on: exactly 0 at lattice points, result clamped to [-1, 1], and
 * bitwise deterministic for a given (point, seed) on IEEE-754 machines.
 *
 * lu_fbm3 sums `octaves` of it, frequency doubling and amplitude scaling by
 * `gain` each octave, each octave with its own derived seed, normalised by
 * the sum of amplitudes so the result stays in [-1, 1]. */
#ifndef LU_VOLUME_NOISE_H
#define LU_VOLUME_NOISE_H

#include <stdint.h>

float lu_noise3(double x, double y, double z, uint32_t seed);
float lu_fbm3(double x, double y, double z, int octaves, double gain, uint32_t seed);

#endif
