/* xoshiro256** (Blackman & Vigna), seeded through splitmix64 so any 64-bit seed is usable. */
#include "rths/core.h"

#include <math.h>

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) {
    return (x << k) | (x >> (64 - k));
}

void rths_rng_seed(rths_rng *rng, uint64_t seed) {
    uint64_t x = seed;
    for (int i = 0; i < 4; i++)
        rng->s[i] = splitmix64(&x);
}

/* one step of the generator on its state s[4] (rths_rng_normals runs it on a local copy) */
static inline uint64_t xoshiro_next(uint64_t *s) {
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

uint64_t rths_rng_next(rths_rng *rng) {
    return xoshiro_next(rng->s);
}

double rths_rng_uniform(rths_rng *rng) {
    return (double)(rths_rng_next(rng) >> 11) * 0x1.0p-53;
}

/* Standard normal by the ziggurat method (Marsaglia & Tsang, J. Stat. Softw. 5(8), 2000) in
 * Doornik's form (2005): 128 layers of equal area, the layer index and the uniform taken from
 * disjoint bits of one 64-bit draw (the index's bits are not reused by the uniform, which is what
 * made the original correlate). About 98.8 % of draws cost one generator step and one compare, no
 * log or sqrt: the virtual rig draws several sensor noises per sample (docs/architecture.md, the
 * per-sample rule), and the polar method's log and division were most of the plant's time. */
enum { ZIGGURAT_LAYERS = 128 };
static const double ZIGGURAT_R = 3.442619855899;      /* start of the tail */
static const double ZIGGURAT_V = 9.91256303526217e-3; /* area of every layer */
static double zig_x[ZIGGURAT_LAYERS + 1], zig_ratio[ZIGGURAT_LAYERS];
static double zig_f[ZIGGURAT_LAYERS + 1]; /* the density exp(-x^2 / 2) at each zig_x */
/* at load time, so every generator (seeded or not) finds the tables and no draw ever waits */
__attribute__((constructor)) static void ziggurat_tables(void) {
    double f = exp(-0.5 * ZIGGURAT_R * ZIGGURAT_R);
    zig_x[0] = ZIGGURAT_V / f; /* the base layer: rectangle plus tail, as a wider rectangle */
    zig_x[1] = ZIGGURAT_R;
    zig_x[ZIGGURAT_LAYERS] = 0;
    for (int i = 2; i < ZIGGURAT_LAYERS; i++) {
        zig_x[i] = sqrt(-2 * log(ZIGGURAT_V / zig_x[i - 1] + f));
        f = exp(-0.5 * zig_x[i] * zig_x[i]);
    }
    for (int i = 0; i < ZIGGURAT_LAYERS; i++)
        zig_ratio[i] = zig_x[i + 1] / zig_x[i];
    for (int i = 0; i <= ZIGGURAT_LAYERS; i++)
        zig_f[i] = exp(-0.5 * zig_x[i] * zig_x[i]);
}

/* (0, 1]: safe under log */
static double uniform_open0(rths_rng *rng) {
    return (double)((rths_rng_next(rng) >> 11) + 1) * 0x1.0p-53;
}

/* Marsaglia's tail beyond ZIGGURAT_R (1964) */
static double normal_tail(rths_rng *rng, int negative) {
    double x, y;
    do {
        x = log(uniform_open0(rng)) / ZIGGURAT_R;
        y = log(uniform_open0(rng));
    } while (-2 * y < x * x);
    return negative ? x - ZIGGURAT_R : ZIGGURAT_R - x;
}

/* One generator output as the ziggurat reads it: the layer from the low bits, the uniform in
 * [-1, 1) from the top 53 (disjoint). */
static inline unsigned normal_layer(uint64_t bits, double *u) {
    *u = 2.0 * ((double)(bits >> 11) * 0x1.0p-53) - 1.0;
    return (unsigned)(bits & (ZIGGURAT_LAYERS - 1));
}

/* The ziggurat's first try from one generator output: the value, or NAN when the draw falls
 * outside its layer's rectangle (about 1.2 % of draws). */
static inline double normal_try(uint64_t bits) {
    double u;
    unsigned layer = normal_layer(bits, &u);
    return fabs(u) < zig_ratio[layer] ? u * zig_x[layer] : NAN;
}

/* The rest of a draw whose try (bits) missed its rectangle: the tail, the wedge, or new tries. */
static double normal_rest(rths_rng *rng, uint64_t bits) {
    for (;;) {
        double u;
        unsigned layer = normal_layer(bits, &u);
        if (layer == 0) return normal_tail(rng, u < 0);
        /* the wedge between this layer's rectangle and the density */
        double x = u * zig_x[layer];
        double f_lo = zig_f[layer], f_hi = zig_f[layer + 1]; /* the layer's edges, tabulated */
        if (f_hi + rths_rng_uniform(rng) * (f_lo - f_hi) < exp(-0.5 * x * x)) return x;
        bits = rths_rng_next(rng);
        double again = normal_try(bits);
        if (again == again) return again;
    }
}

double rths_rng_normal(rths_rng *rng) {
    uint64_t bits = rths_rng_next(rng);
    double x = normal_try(bits);
    return x == x ? x : normal_rest(rng, bits);
}

/* The same draws as rths_rng_normal, the generator's state held in registers over the block
 * (stored only around the rare rest of a draw): a call per draw cost as much as the draw. */
void rths_rng_normals(rths_rng *rng, double *out, int n) {
    rths_rng local = *rng;
    for (int i = 0; i < n; i++) {
        uint64_t bits = xoshiro_next(local.s);
        double x = normal_try(bits);
        if (x != x) {
            *rng = local;
            x = normal_rest(rng, bits);
            local = *rng;
        }
        out[i] = x;
    }
    *rng = local;
}
