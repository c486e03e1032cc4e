/* Software prefetch for the DSMC pair kernel (fortran/dsmc/dsmc_collisions.f90; gfortran has
   no prefetch intrinsic). The pair draw and the gathers read samples at random: asking for the
   next block's cache lines while the current block computes keeps many misses in flight.
   dsmc_prefetch(m, idx, base, stride): the lines holding base + (idx[i] - 1) * stride bytes,
   i = 0..m-1 (1-based Fortran indices), for reading and writing. */
#include <stdint.h>

void dsmc_prefetch(int64_t m, const int64_t *restrict idx, const char *base, int64_t stride) {
    for (int64_t i = 0; i < m; i++) __builtin_prefetch(base + (idx[i] - 1) * stride, 1, 3);
}
