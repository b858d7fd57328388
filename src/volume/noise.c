/* Seeded gradient noise (see lu_noise.h for the definition). */
#include "lu_noise.h"

#include <math.h>

#include "kernels/lu_hash.h"

static uint32_t mix32(uint32_t h) { return lu_k_mix32(h); }

static uint32_t lattice_hash(int64_t x, int64_t y, int64_t z, uint32_t seed) {
    uint32_t h = mix32(seed + 0x9e3779b9U);
    h = mix32(h ^ (uint32_t)x);
    h = mix32(h ^ (uint32_t)y);
    return mix32(h ^ (uint32_t)z);
}

/* Perlin's 12 cube-edge gradients, four repeated to make 16 entries. */
static const signed char grad[16][3] = {
    {1, 1, 0}, {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0}, {1, 0, 1}, {-1, 0, 1}, {1, 0, -1}, {-1, 0, -1},
    {0, 1, 1}, {0, -1, 1}, {0, 1, -1}, {0, -1, -1}, {1, 1, 0}, {0, -1, 1}, {-1, 1, 0}, {0, -1, -1},
};

static double corner(int64_t x, int64_t y, int64_t z, uint32_t seed, double fx, double fy, double fz) {
    const signed char *g = grad[lattice_hash(x, y, z, seed) >> 28];
    return g[0] * fx + g[1] * fy + g[2] * fz;
}

static double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }
static double lerp(double a, double b, double t) { return a + t * (b - a); }

float lu_noise3(double x, double y, double z, uint32_t seed) {
    /* Keeps floor() within int64; the generators never come near this. */
    if (!(fabs(x) < 1e15 && fabs(y) < 1e15 && fabs(z) < 1e15)) return 0.0f;
    double fx0 = floor(x), fy0 = floor(y), fz0 = floor(z);
    int64_t ix = (int64_t)fx0, iy = (int64_t)fy0, iz = (int64_t)fz0;
    double fx = x - fx0, fy = y - fy0, fz = z - fz0;
    double u = fade(fx), v = fade(fy), w = fade(fz);
    double n000 = corner(ix, iy, iz, seed, fx, fy, fz);
    double n100 = corner(ix + 1, iy, iz, seed, fx - 1, fy, fz);
    double n010 = corner(ix, iy + 1, iz, seed, fx, fy - 1, fz);
    double n110 = corner(ix + 1, iy + 1, iz, seed, fx - 1, fy - 1, fz);
    double n001 = corner(ix, iy, iz + 1, seed, fx, fy, fz - 1);
    double n101 = corner(ix + 1, iy, iz + 1, seed, fx - 1, fy, fz - 1);
    double n011 = corner(ix, iy + 1, iz + 1, seed, fx, fy - 1, fz - 1);
    double n111 = corner(ix + 1, iy + 1, iz + 1, seed, fx - 1, fy - 1, fz - 1);
    double n = lerp(lerp(lerp(n000, n100, u), lerp(n010, n110, u), v), lerp(lerp(n001, n101, u), lerp(n011, n111, u), v),
                    w);
    return (float)(n > 1.0 ? 1.0 : (n < -1.0 ? -1.0 : n));
}

float lu_fbm3(double x, double y, double z, int octaves, double gain, uint32_t seed) {
    double sum = 0.0, norm = 0.0, amp = 1.0, freq = 1.0;
    for (int o = 0; o < octaves; o++) {
        /* Odd offsets keep octave lattices from lining up at the origin. */
        double off = 17.31 * o;
        sum += amp * lu_noise3(x * freq + off, y * freq - off, z * freq + 0.5 * off, mix32(seed + 0x85ebca6bU * (uint32_t)(o + 1)));
        norm += amp;
        amp *= gain;
        freq *= 2.0;
    }
    return norm > 0.0 ? (float)(sum / norm) : 0.0f;
}
