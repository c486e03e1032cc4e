/* Memory hints for the event-driven engine (fortran/edmd): gfortran has no prefetch intrinsic
   and no madvise. edmd_prefetch(x) asks for the cache line holding x, for reading and writing.
   edmd_huge_pages(x, bytes) asks Linux for transparent huge pages (2 MiB) on the aligned
   interior of [x, x + bytes) and collapses the pages already touched into them (MADV_COLLAPSE,
   Linux >= 6.1): the disk records, calendar entries and bucket heads are read at random
   places, and at N >= 1e5 their 4 KiB pages overflow the TLB (bench/RESULTS.md s. 18, 32).
   A hint only: failures are ignored, and elsewhere (no MADV_HUGEPAGE) it does nothing. */
#include <stdint.h>
#include <sys/mman.h>

void edmd_prefetch(const void *x) { __builtin_prefetch(x, 1, 3); }

void edmd_huge_pages(const void *x, const int64_t *bytes)
{
#ifdef MADV_HUGEPAGE
  const uintptr_t h = (uintptr_t)2 << 20;
  uintptr_t a = ((uintptr_t)x + h - 1) & ~(h - 1);
  uintptr_t b = ((uintptr_t)x + (uintptr_t)*bytes) & ~(h - 1);
  if (*bytes <= 0 || b <= a) return;
  if (madvise((void *)a, b - a, MADV_HUGEPAGE) != 0) return;
#ifndef MADV_COLLAPSE
#define MADV_COLLAPSE 25
#endif
  (void)madvise((void *)a, b - a, MADV_COLLAPSE);
#else
  (void)x; (void)bytes;
#endif
}
