/* Counter-based uniforms for the DSMC (fortran/dsmc, module dsmc_collisions binds these).

   SplitMix64 (G. Steele, D. Lea, C. Flood, "Fast splittable pseudorandom number generators",
   OOPSLA 2014; the generator of java.util.SplittableRandom, the seeder recommended for
   xoshiro): its k-th output is mix(key + k gamma), a pure function of the counter k. Evaluated
   at the counters first, first + 1, ... the numbers are consecutive outputs of one SplitMix64
   stream (period 2^64; it passes BigCrush), but any block of them can be computed anywhere, in
   any order, in SIMD lanes or on any thread: the pair kernel draws a block's impact parameters
   where it needs them, and a run's numbers depend on (seed, step) only, not on the thread count
   or on a generator state (a checkpoint needs none).

   C, not Fortran, because the mix wraps unsigned 64-bit products: defined here, signed overflow
   (undefined behaviour) in Fortran. */
#include <stdint.h>

static const uint64_t gamma_ = 0x9e3779b97f4a7c15ULL;   /* 2^64 / golden ratio, odd */

static inline uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* The stream's key (its state before the first output) of a scene seed: one SplitMix64 output,
   so that neighbouring seeds start far apart on the 2^64 cycle. */
int64_t dsmc_stream_key(int64_t seed) {
    return (int64_t)mix64((uint64_t)seed * gamma_ + 0x2545f4914f6cdd1dULL);
}

/* u[i] = the stream's output number step*per_step + offset + i + 1 as a double in [0, 1)
   (its top 53 bits times 2^-53), i = 0..n-1. The counter wraps modulo 2^64. */
void dsmc_uniforms(int64_t key, int64_t step, int64_t per_step, int64_t offset, int64_t n,
                   double *restrict u) {
    const uint64_t first = (uint64_t)step * (uint64_t)per_step + (uint64_t)offset + 1u;
    const uint64_t k0 = (uint64_t)key;
    for (int64_t i = 0; i < n; i++) {
        uint64_t z = mix64(k0 + (first + (uint64_t)i) * gamma_);
        u[i] = (double)(z >> 11) * 0x1.0p-53;
    }
}
