/* Software prefetch for the event-driven engine (fortran/edmd): gfortran has no prefetch
   intrinsic. edmd_prefetch(x) asks for the cache line holding x, for reading and writing. */
void edmd_prefetch(const void *x) { __builtin_prefetch(x, 1, 3); }
