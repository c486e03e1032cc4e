!> Dipole-dipole repulsion between magnets with moments normal to the plane
!> (thesis eq. 2.7 / 4.3): F_ij = k_pair mu_i mu_j r_ij^-4 r_hat (k_pair = 3F/4).
!> One kernel; every neighbour strategy calls it. The same pass accumulates
!> the r^-3 sums that the dry-friction normal force needs (eq. 4.11).
!>
!> Longer than 600 lines because the pair passes (all pairs, lists by flat pairs, rows and
!> ranges of j, the far field, threaded with their reaction spill) and the law kernels they
!> inline are one compilation unit: gfortran inlines reliably only within a file (the build links with LTO since
!> RESULTS 32.2, but -Db_lto=false must stay as fast);
!> the load-time builders of the evaluations are module pair_eval.
!>
!> Truncated strategies may shift the force (shift4 = r_c^-4) so that it
!> vanishes continuously at r_c: f(r) = k (r^-4 - r_c^-4).
!>
!> The same passes (all pairs, half lists, threads) carry a second law, the
!> truncated Lennard-Jones of seed 000 (eqs. 3-5, kind 'lj_box'): selected by
!> the optional `law` argument (type lj_law_t); mu = 1, k_pair = 1, no r^-3 sums.
!>
!> Either law may be evaluated more cheaply (the optional `tab` argument, a pair_table_t, its
!> `eval`; module pair_table): from a table in r^2 (no square root, no division; built once at
!> load by dipole_table / lj_table to a requested relative error), in single precision (the
!> law's arithmetic from the double r^2; separations and sums stay double), or with r^-1 from
!> a bit-level guess and three Newton steps (rsqrt3: multiplies and adds only). Each is
!> measured at load against the exact kernels over the run's range (dipole_eval_build,
!> lj_eval_build). One loop structure for every evaluation: the loops compute the distances
!> and the sums and hand the law to dipole_eval or lj_chunk, which choose the evaluation
!> outside their loops; the lane loops of dipole_ranges (dipole_ranges.inc) are compiled once
!> per evaluation, each with its own lane kernel.
module pair_forces
  use, intrinsic :: iso_fortran_env, only: sp => real32
  use kinds, only: dp, i8
  use pair_table, only: pair_table_t, max_bits, eval_exact, eval_table, eval_single, eval_rsqrt
  implicit none
  private

  public :: dipole_kernel, pair_forces_all, pair_forces_list, pair_forces_far, pair_energy_all
  public :: list_takes_pruned, long_row_pairs
  public :: lj_law_t, lj_law, lj_kernel, lj_energy
  public :: split_t, split_of
  public :: pair_table_t, max_bits
  public :: dipole_eval, lj_chunk, rsqrt3
  !> for module pair_eval (which builds and measures the evaluations at load)
  public :: table_values, pair_chunk, kernel_lj6

  integer, parameter :: mode_all = 1, mode_list = 2
  !> Mean listed pairs per row from which dipole lists go row by row (rows_list) instead of as
  !> one flat pair sequence (rows_pairs), and from which they go by contiguous ranges of j
  !> (rows_ranges, when the list has ranges; never with pair_eval = 'single'). 10 on the
  !> AVX-512 Xeon of bench/RESULTS.md section 26; 48 on the AVX2 EPYC of section 35.6, where
  !> the rows measured 1.26-1.33x the ranges at 15 pairs per row, 1.05x at 35, 1.0x at 61
  !> (exact; single 1.3-1.8x at every length)
  !> Below kept_row_pairs (and from mid_row_pairs on) the rows go by rows_kept (flat chunks of
  !> the pruned list). With the pair arrays written by position (no compression of the pairs
  !> below r_c) it measured 1.05-1.20x the compressing rows_kept at 6-10 pruned pairs per row
  !> (r_c 3-4 + skin 1) and 1.01-1.09x rows_list at 16-33 (r_c 5-7) on Zen 3, so it takes the
  !> rows up to long_row_pairs (bench/RESULTS.md 42; before: 24, section 37).
  real(dp), parameter :: mid_row_pairs = 8, kept_row_pairs = 48, long_row_pairs = 48
  !> Lanes of the contiguous dipole loops (dipole_ranges): the sums on i are kept in this many
  !> fixed lanes (j = j0 + l - 1 goes to lane l), so the loop vectorises without reordering a
  !> floating-point sum; the order depends on the lane count only, never on the machine
  integer, parameter :: lanes = 4
  integer, parameter :: kernel_dipole = 1, kernel_lj6 = 2, kernel_lj = 3
  integer, parameter :: side_none = 0, side_near = 1, side_far = 2   !< split weights (dipole_ranges)
  integer, parameter :: pair_chunk = 256   !< pairs per chunk of the flat pair loop
  real(dp), parameter :: ones(pair_chunk) = 1   !< the per-pair factor ci of rows_pairs' law

  !> Seed 000's steric law between r_m and the cut-off R: U = 4 U0 ((2/r)^2p - (2/r)^p),
  !> continued linearly below r_m (constant force |U'(r_m)|). Lengths in a, energies
  !> in m g a. p is an integer (powers by multiplication; p = 6 has its own unrolled path).
  type :: lj_law_t
    integer :: kernel = kernel_lj
    integer :: p = 6            !< exponent [1]
    real(dp) :: u0 = 1          !< well depth U0 [m g a]
    real(dp) :: rm = 1.8_dp     !< lower cut-off r_m [a]
    real(dp) :: rm2 = 3.24_dp   !< r_m^2 [a^2]
    real(dp) :: c4p = 24        !< 4 p U0 [m g a]
    real(dp) :: fcore = 0       !< |U'(r_m)| [m g]
    real(dp) :: ucore = 0       !< U_LJ(r_m) [m g a]
    real(dp) :: rc2 = 25        !< R^2: zero beyond the cut-off R, for every strategy [a^2]
  end type lj_law_t

  !> Smooth hand-over between the near pairs (neighbour list, every step) and the far field
  !> (all pairs, every tail_every steps): weight S(r) on the near side, 1 - S(r) on the far
  !> side, S = 1 below r_in, 0 from r_c on, and the C2 smoothstep S = 1 - x^3 (10 - 15 x + 6 x^2)
  !> in x = (r^2 - r_in^2)/(r_c^2 - r_in^2) between (no square root). Off (on = .false.): the
  !> sharp split at r_c. A pair crossing r_c then moves its force from one side to the other
  !> continuously, so the far field stays smooth in time between its evaluations.
  type :: split_t
    logical :: on = .false.
    real(dp) :: ri2 = 0        !< r_in^2 [D1^2]
    real(dp) :: inv_w = 0      !< 1/(r_c^2 - r_in^2) [D1^-2]
  end type split_t

  !> Spill buffers of threaded_pass (n, 3, threads): reactions a thread puts on
  !> rows owned by later threads. Kept between passes and all zero between them.
  real(dp), allocatable :: spill(:, :, :)
  !> Per-row sums of dipole_ranges (3, n; each thread uses its own rows) and the all-pairs
  !> triangle as ranges (row i: the one range i+1..n). Kept between passes: no allocation per
  !> step; set up by threaded_pass outside its parallel region.
  real(dp), allocatable :: row_sums(:, :)
  !> rows_pairs' Lennard-Jones row sums (n; size 1 while only the dipole law ran): the running
  !> sum stored at every pair of a row (the last store holds the row's sum), added to the
  !> forces after the pass (each thread's rows its own)
  real(dp), allocatable :: lj_rx(:), lj_ry(:)
  integer, allocatable :: tri_start(:), tri_lo(:), tri_hi(:)

contains

  !> The hand-over over [r_c - width, r_c] [D1]; width <= 0: the sharp split at r_c.
  pure function split_of(r_cut, width) result(sp)
    real(dp), intent(in) :: r_cut, width
    type(split_t) :: sp
    sp%on = width > 0
    if (.not. sp%on) return
    sp%ri2 = (r_cut - width)**2
    sp%inv_w = 1.0_dp/(r_cut**2 - sp%ri2)
  end function split_of

  !> Near-side weight S at squared distance r2 [D1^2] (1 - S on the far side).
  pure elemental real(dp) function near_weight(sp, r2) result(w)
    type(split_t), intent(in) :: sp
    real(dp), intent(in) :: r2
    real(dp) :: x
    x = min(1.0_dp, max(0.0_dp, (r2 - sp%ri2)*sp%inv_w))
    w = 1.0_dp - x*x*x*(10.0_dp + x*(6.0_dp*x - 15.0_dp))
  end function near_weight

  !> Kernel for one pair at squared distance r2 [D1^2]: the force on i is
  !> k mu_i mu_j s5 (r_i - r_j), with s5 = r^-5 - shift4 r^-1, and s3 = r^-3.
  !> No non-integer powers: one sqrt, one division.
  pure elemental subroutine dipole_kernel(r2, shift4, s5, s3)
    real(dp), intent(in) :: r2, shift4
    real(dp), intent(out) :: s5, s3
    real(dp) :: r2inv, rinv
    r2inv = 1.0_dp/r2
    rinv = sqrt(r2inv)
    s3 = r2inv*rinv
    s5 = s3*r2inv - shift4*rinv
  end subroutine dipole_kernel

  !> dipole_kernel in single precision (pair_eval = 'single'): r2 rounded to single (and kept
  !> >= 1e-12 D1^2, so no lane overflows), one single division and square root; s5, s3 are
  !> returned in double for the double sums. Relative error a few 1e-7 (measured at load).
  pure elemental subroutine dipole_kernel_sp(r2, shift4, s5, s3)
    real(dp), intent(in) :: r2, shift4
    real(dp), intent(out) :: s5, s3
    real(sp) :: r2inv, rinv, c
    r2inv = 1.0_sp/real(max(r2, 1.0e-12_dp), sp)
    rinv = sqrt(r2inv)
    c = r2inv*rinv
    s3 = real(c, dp)
    s5 = real(c*r2inv - real(shift4, sp)*rinv, dp)
  end subroutine dipole_kernel_sp

  !> dipole_kernel with r^-1 from rsqrt3 (pair_eval = 'rsqrt'): no square root, no division.
  pure elemental subroutine dipole_kernel_rs(r2, shift4, s5, s3)
    real(dp), intent(in) :: r2, shift4
    real(dp), intent(out) :: s5, s3
    real(dp) :: rinv, r2inv
    rinv = rsqrt3(r2)
    r2inv = rinv*rinv
    s3 = r2inv*rinv
    s5 = s3*r2inv - shift4*rinv
  end subroutine dipole_kernel_rs

  !> 1/sqrt(u) for a normal u > 0 with multiplies and adds only: a guess from the bits of u
  !> (largest relative error 3.4e-2) refined by three Newton steps t <- t (3/2 - (u/2) t^2),
  !> each squaring the error (3.4e-2 -> 1.8e-3 -> 4.7e-6 -> 3.3e-11, always from below).
  pure elemental real(dp) function rsqrt3(u) result(t)
    real(dp), intent(in) :: u
    integer(i8), parameter :: magic = int(z'5FE6EB50C7B537A9', i8)
    real(dp) :: h
    t = transfer(magic - shiftr(transfer(u, 0_i8), 1), 1.0_dp)
    h = 0.5_dp*u
    t = t*(1.5_dp - h*t*t)
    t = t*(1.5_dp - h*t*t)
    t = t*(1.5_dp - h*t*t)
  end function rsqrt3

  !> The dipole law by evaluation ev (exact when absent or eval_exact) at nk squared distances
  !> r2s [D1^2], weighted: c(m) = S ci c(m) s5 with the force factor s5 = r^-5 - shift4 r^-1
  !> and r3(m) = S w3 r^-3, S the mask at rk2 or the split's near side (ci, w3 and c(m) on
  !> entry: the callers' factors); the loops of dipole_eval.inc, as the pair loops run them;
  !> nk <= pair_chunk.
  subroutine dipole_eval(nk, r2s, shift4, sp, rk2, ci, w3, c, r3, tab)
    integer, intent(in) :: nk
    real(dp), intent(in) :: r2s(nk), shift4, rk2, ci, w3
    type(split_t), intent(in) :: sp
    real(dp), intent(inout) :: c(nk), r3(nk)
    type(pair_table_t), intent(in), optional :: tab
    integer(i8) :: ks(pair_chunk), tn
    real(dp) :: ds(pair_chunk), e5, e3, keep, cis(pair_chunk)
    integer :: m, code
    code = eval_exact
    if (present(tab)) code = tab%eval
    cis(1:nk) = ci
    associate (ci => cis)
      include 'dipole_eval.inc'
    end associate
  end subroutine dipole_eval

  !> The dipole table's two pieces (row tc of c(8, n)) at offset d: force factor s5 and r^-3.
  pure subroutine table_piece(tc, d, s5, s3)
    real(dp), intent(in) :: tc(8), d
    real(dp), intent(out) :: s5, s3
    s5 = tc(1) + d*(tc(2) + d*(tc(3) + d*tc(4)))
    s3 = tc(5) + d*(tc(6) + d*(tc(7) + d*tc(8)))
  end subroutine table_piece

  !> The law with exponent p, depth u0 [m g a], lower cut-off rm [a] (rm > 0) and
  !> cut-off rc [a] (plain truncation, as eq. 3: force and energy jump at R).
  pure function lj_law(p, u0, rm, rc) result(l)
    integer, intent(in) :: p
    real(dp), intent(in) :: u0, rm, rc
    type(lj_law_t) :: l
    real(dp) :: q
    l%p = p
    l%kernel = merge(kernel_lj6, kernel_lj, p == 6)
    l%u0 = u0
    l%rm = rm
    l%rm2 = rm*rm
    l%c4p = 4.0_dp*real(p, dp)*u0
    q = (2.0_dp/rm)**p
    l%fcore = l%c4p/rm*(2*q*q - q)     ! -U'(r_m), eq. (9)
    l%ucore = 4.0_dp*u0*(q*q - q)
    l%rc2 = rc*rc
  end function lj_law

  !> Force factor s (force on i = s (r_i - r_j)) at squared distance r2 [a^2]:
  !> 4 p U0 r^-2 (2 q^2 - q), q = (2/r)^p, above r_m; |U'(r_m)|/r at and below r_m; 0 at
  !> and beyond R. No non-integer powers: q from w = 4/r^2 by multiplication (one sqrt for
  !> the core branch and odd p). lj6_kernel is the same for p = 6, unrolled (vectorises).
  pure elemental subroutine lj_kernel(l, r2, s)
    type(lj_law_t), intent(in) :: l
    real(dp), intent(in) :: r2
    real(dp), intent(out) :: s
    real(dp) :: r2inv, rinv, q
    real(dp) :: s_lj, s_core, r2c
    r2c = max(r2, l%rm2)            ! the power law where it applies (finite otherwise)
    r2inv = 1.0_dp/r2c
    q = (4.0_dp*r2inv)**(l%p/2)
    if (mod(l%p, 2) == 1) q = q*2.0_dp*sqrt(r2inv)
    s_lj = l%c4p*r2inv*(2*q*q - q)
    rinv = sqrt(1.0_dp/r2)
    s_core = l%fcore*rinv
    s = merge(s_lj, s_core, r2 > l%rm2)*merge(1.0_dp, 0.0_dp, r2 < l%rc2)
  end subroutine lj_kernel

  !> p = 6 above r_m (no sqrt, no branch: vectorises); r2 at or below r_m^2 is evaluated at
  !> r_m (lj_chunk fixes those pairs up with the core force).
  !> The cut-off's 0/1 factor is computed first, on its own line: written inside the product,
  !> GCC 12 makes a branch of it with AVX2 (no masks) and none of the loops calling these
  !> kernels vectorises ("control flow in loop"; the same numbers either way).
  pure elemental subroutine lj6_kernel(c4p, rm2, rc2, r2, s)
    real(dp), intent(in) :: c4p, rm2, rc2, r2
    real(dp), intent(out) :: s
    real(dp) :: w, q, on
    on = merge(1.0_dp, 0.0_dp, r2 < rc2)
    w = 4.0_dp/max(r2, rm2)
    q = w*w*w
    s = 0.25_dp*c4p*w*(2*q*q - q)*on
  end subroutine lj6_kernel

  !> lj6_kernel in single precision (pair_eval = 'single'; the factor returned in double).
  pure elemental subroutine lj6_kernel_sp(c4p, rm2, rc2, r2, s)
    real(dp), intent(in) :: c4p, rm2, rc2, r2
    real(dp), intent(out) :: s
    real(sp) :: w, q
    real(dp) :: on
    on = merge(1.0_dp, 0.0_dp, r2 < rc2)   ! first (see lj6_kernel)
    w = 4.0_sp/real(max(r2, rm2), sp)
    q = w*w*w
    s = real(0.25_sp*real(c4p, sp)*w*(2*q*q - q), dp)*on
  end subroutine lj6_kernel_sp

  !> lj6_kernel with 1/r^2 = rsqrt3(r^2)^2 (pair_eval = 'rsqrt'): no division.
  pure elemental subroutine lj6_kernel_rs(c4p, rm2, rc2, r2, s)
    real(dp), intent(in) :: c4p, rm2, rc2, r2
    real(dp), intent(out) :: s
    real(dp) :: w, q, on
    on = merge(1.0_dp, 0.0_dp, r2 < rc2)   ! first (see lj6_kernel)
    w = rsqrt3(max(r2, rm2))
    w = 4.0_dp*w*w
    q = w*w*w
    s = 0.25_dp*c4p*w*(2*q*q - q)*on
  end subroutine lj6_kernel_rs

  !> The Lennard-Jones force factor of the law (force on i = cs (r_i - r_j)) over a chunk of
  !> nk squared distances r2s [a^2], by the evaluation of tab (exact when absent; table for
  !> any p, single and rsqrt for p = 6): the loops of lj_eval.inc with unit separations.
  subroutine lj_chunk(l, nk, r2s, cs, tab)
    type(lj_law_t), intent(in) :: l
    integer, intent(in) :: nk
    real(dp), intent(in) :: r2s(nk)
    real(dp), intent(out) :: cs(nk)
    type(pair_table_t), intent(in), optional :: tab   !< the law's evaluation
    real(dp) :: c4p, rm2, lc2, lo2, hi2, dd, on, s, d, unused(nk)
    integer :: m, shift, code
    integer(i8) :: tn, base, kk
    code = eval_exact
    if (present(tab)) code = tab%eval
    ! (a loop, not minval, which GCC 12 does not vectorise)
    d = huge(1.0_dp)
    do m = 1, nk
      d = min(d, r2s(m))
    end do
    associate (d1 => ones, d2 => ones, g1 => cs, g2 => unused)   ! s*1 is s
      include 'lj_eval.inc'
    end associate
  end subroutine lj_chunk

  !> Potential energy of the law [m g a] (pairs within R): over the pairs of a half list
  !> (start, nbr) when given (its radius >= R), else every pair.
  function lj_energy(n, x, y, l, start, nbr) result(e)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    type(lj_law_t), intent(in) :: l
    integer, intent(in), optional :: start(:), nbr(:)
    real(dp) :: e
    integer :: i, j, k
    e = 0
    do i = 1, n - 1
      if (present(start)) then
        do k = start(i), start(i + 1) - 1
          e = e + u_pair(i, nbr(k))
        end do
      else
        do j = i + 1, n
          e = e + u_pair(i, j)
        end do
      end if
    end do
  contains
    real(dp) function u_pair(a, b) result(u)
      integer, intent(in) :: a, b
      real(dp) :: r2, r, q
      r2 = (x(a) - x(b))**2 + (y(a) - y(b))**2
      u = 0
      if (r2 >= l%rc2) return
      r = sqrt(r2)
      if (r2 > l%rm2) then
        q = (2.0_dp/r)**l%p
        u = 4.0_dp*l%u0*(q*q - q)
      else
        u = l%ucore - l%fcore*(r - l%rm)
      end if
    end function u_pair
  end function lj_energy

  !> The segment k of u = r^2 in a table (module pair_table) and the offset d = u - u_k into
  !> it: one clamp, one shift, no square root, no division. The loops then evaluate the
  !> piece c(q..q+3, k) as c1 + d (c2 + d (c3 + d c4)) themselves (inlined: a routine holding
  !> the cubic too was not inlined by GCC, and its loops did not vectorise).
  pure elemental subroutine table_seg(u, lo2, hi2, n, shift, base, k, d)
    real(dp), intent(in) :: u, lo2, hi2
    integer(i8), intent(in) :: n, base
    integer, intent(in) :: shift
    integer(i8), intent(out) :: k   ! 64-bit: with a default integer the loops do not vectorise
    real(dp), intent(out) :: d
    real(dp) :: uc
    uc = min(max(u, lo2), hi2)
    k = max(1_i8, min(n, ishft(transfer(uc, 0_i8), -shift) - base))
    d = uc - transfer(ishft(base + k, shift), 1.0_dp)
  end subroutine table_seg

  !> Every quantity of table t at u = r^2, through the routines the pair loops use.
  subroutine table_values(t, u, v)
    type(pair_table_t), intent(in) :: t
    real(dp), intent(in) :: u
    real(dp), intent(out) :: v(:)
    integer(i8) :: k
    integer :: q
    real(dp) :: d
    call table_seg(u, t%lo2, t%hi2, int(t%n, i8), t%shift, t%base, k, d)
    do q = 1, t%nq
      v(q) = t%c(4*q - 3, k) + d*(t%c(4*q - 2, k) + d*(t%c(4*q - 1, k) + d*t%c(4*q, k)))
    end do
  end subroutine table_values

  !> O(N^2) reference: every pair once, Newton's third law applied exactly.
  !> Adds to fx, fy (n) [m1 g]; if with_r3, adds to s3 (n).
  subroutine pair_forces_all(n, x, y, mu, wsin, k_pair, with_r3, fx, fy, s3, r2min, law, tab)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)       !< positions [D1]
    real(dp), intent(in) :: mu(n)            !< relative moments mu_i/mu1
    real(dp), intent(in) :: wsin(n)          !< mu_i sin(theta_i), friction weights
    real(dp), intent(in) :: k_pair           !< (3/4) F
    logical, intent(in) :: with_r3           !< accumulate friction sums
    real(dp), intent(inout) :: fx(n), fy(n)  !< forces [m1 g]
    real(dp), intent(inout) :: s3(n)         !< sum_j wsin_j r_ij^-3
    real(dp), intent(out) :: r2min           !< smallest squared pair distance [D1^2]
    type(lj_law_t), intent(in), optional :: law   !< Lennard-Jones instead of the dipole law
    type(pair_table_t), intent(in), optional :: tab   !< the law's table (used when on)
    integer :: dummy(1)
    call threaded_pass(mode_all, kernel_of(law), law_of(law), split_t(), n, x, y, mu, wsin, &
         k_pair, 0.0_dp, 0.0_dp, 0.0_dp, .false., with_r3, dummy, dummy, fx, fy, s3, r2min, &
         tab=tab)
  end subroutine pair_forces_all

  !> Half neighbour list (pairs i < j stored once, CSR: the neighbours of i
  !> are nbr(start(i) : start(i+1)-1), own(k) the row of pair k). Pairs at r >= r_c
  !> are skipped when check is set (the thesis variant r_c = r_v uses every listed pair);
  !> with a split (dipole), pairs are weighted by its near side S(r).
  subroutine pair_forces_list(n, x, y, mu, wsin, k_pair, rc2, shift4, check, with_r3, &
       start, nbr, fx, fy, s3, r2min, law, own, split, rstart, rlo, rhi, tab, mu_one, pstart, &
       pnbr, pown, rowmax)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair
    real(dp), intent(in) :: rc2       !< squared cut-off [D1^2]
    real(dp), intent(in) :: shift4    !< force shift r_c^-4 (0: plain truncation)
    logical, intent(in) :: check, with_r3
    integer, intent(in) :: start(n + 1)
    integer, intent(in), contiguous :: nbr(:)
    real(dp), intent(inout) :: fx(n), fy(n), s3(n)
    real(dp), intent(out) :: r2min    !< smallest squared distance among listed pairs
    type(lj_law_t), intent(in), optional :: law   !< Lennard-Jones instead of the dipole law
    integer, intent(in), contiguous :: own(:)   !< the row i of each listed pair (nlist_t own)
    type(split_t), intent(in), optional :: split  !< smooth near/far hand-over (far field on)
    !> the same list as contiguous ranges of j (nlist_t; dipole with check only): used when
    !> the rows are long
    integer, intent(in), optional, contiguous :: rstart(:), rlo(:), rhi(:)
    type(pair_table_t), intent(in), optional :: tab   !< the law's table (used when on)
    !> every mu(i) equals mu(1) (one species): rows_list (from 48 listed pairs per row, single) takes
    !> mu_j as mu_i instead of a gather per pair, rows_kept (8-48) fills the chunk's factors
    !> once instead of a load and a product per listed pair (the same values, the same bits;
    !> ~1.07x at r_c 7, 0.97-1.08x at r_c 3-4; in rows_pairs' sums it measured slower:
    !> bench/RESULTS.md 38.3, 38.7)
    logical, intent(in), optional :: mu_one
    !> the list pruned to r_c + prune (nlist_t; with check): taken instead of start, nbr, own
    !> where list_takes_pruned says so (the same terms in the same order: the same bits);
    !> the kernel choice and the threads' blocks still follow start
    integer, intent(in), optional, contiguous :: pstart(:), pnbr(:), pown(:)
    !> the largest j of each row (nlist_t rowmax): rows_kept's reactions then go by one branch
    !> per row (needed for the pruned list's bits on threads)
    integer, intent(in), optional, contiguous :: rowmax(:)
    type(split_t) :: sp
    logical :: one
    integer :: i, k, j
    one = .false.
    if (present(mu_one)) one = mu_one
    if (present(split)) sp = split
    if (present(rstart) .and. check .and. .not. present(law)) then
      call threaded_pass(mode_list, kernel_dipole, lj_law_t(), sp, n, x, y, mu, wsin, k_pair, &
           0.0_dp, rc2, shift4, check, with_r3, start, nbr, fx, fy, s3, r2min, own, rstart, rlo, &
           rhi, tab=tab, mu_one=one, pstart=pstart, pnbr=pnbr, pown=pown, rowmax=rowmax)
    else
      call threaded_pass(mode_list, kernel_of(law), law_of(law), sp, n, x, y, mu, wsin, k_pair, &
           0.0_dp, rc2, shift4, check, with_r3, start, nbr, fx, fy, s3, r2min, own, tab=tab, &
           mu_one=one, pstart=pstart, pnbr=pnbr, pown=pown, rowmax=rowmax)
    end if
    ! r2min over the pruned list is the list's when below r_c^2 (every pair left out is
    ! beyond r_c); otherwise the list's own, taken here (rare: no pair within r_c)
    if (present(pstart) .and. r2min >= rc2 .and. &
        list_takes_pruned(present(law), n, start(n + 1) - 1)) then
      do i = 1, n
        do k = start(i), start(i + 1) - 1
          j = nbr(k)
          r2min = min(r2min, (x(i) - x(j))**2 + (y(i) - y(j))**2)
        end do
      end do
    end if
  end subroutine pair_forces_list

  !> Whether pair_forces_list's kernel for a list of npairs over n rows takes a pruned list
  !> (rows_pairs, rows_kept: pairs beyond r_c dropped or zeroed one by one, the sums in the
  !> list's order; not rows_list, rows_ranges, whose sums go by lanes of the rows' positions).
  pure logical function list_takes_pruned(lj, n, npairs) result(yes)
    logical, intent(in) :: lj   !< the Lennard-Jones law (else the dipole law)
    integer, intent(in) :: n, npairs
    yes = lj .or. real(npairs, dp) < kept_row_pairs*real(max(1, n), dp)
  end function list_takes_pruned

  pure integer function kernel_of(law) result(k)
    type(lj_law_t), intent(in), optional :: law
    k = kernel_dipole
    if (present(law)) k = law%kernel
  end function kernel_of

  pure function law_of(law) result(l)
    type(lj_law_t), intent(in), optional :: law
    type(lj_law_t) :: l
    if (present(law)) l = law
  end function law_of

  !> The far field: every pair at r >= r_c, O(N^2), for the tail correction (recomputed
  !> every tail_every steps); with a split, every pair at r >= r_in weighted by 1 - S(r).
  !> Overwrites fx, fy, s3.
  subroutine pair_forces_far(n, x, y, mu, wsin, k_pair, rc2, with_r3, fx, fy, s3, split, tab)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair, rc2
    logical, intent(in) :: with_r3
    real(dp), intent(out) :: fx(n), fy(n), s3(n)
    type(split_t), intent(in) :: split
    type(pair_table_t), intent(in), optional :: tab   !< the dipole table (used when on)
    integer :: dummy(1)
    real(dp) :: r2min, r2_from
    fx = 0; fy = 0; s3 = 0
    r2_from = rc2
    if (split%on) r2_from = split%ri2
    call threaded_pass(mode_all, kernel_dipole, lj_law_t(), split, n, x, y, mu, wsin, k_pair, &
         r2_from, 0.0_dp, 0.0_dp, .false., with_r3, dummy, dummy, fx, fy, s3, r2min, tab=tab)
  end subroutine pair_forces_far

  !> Rows i_lo..i_hi of the all-pairs triangle; pairs with r^2 < r2_min are
  !> masked out (0 for the full sum, r_c^2 for the far field). Reactions on
  !> j <= hi_direct go to fx, fy, s3, those on j > hi_direct to the spill
  !> arrays sx, sy, ss (another thread owns those rows; see threaded_pass).
  subroutine rows_all(kernel, l, sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, &
       r2_min, with_r3, fx, fy, s3, sx, sy, ss, r2low, tab)
    integer, intent(in) :: kernel, i_lo, i_hi, hi_direct, n
    type(lj_law_t), intent(in) :: l
    type(split_t), intent(in) :: sp
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair, r2_min
    logical, intent(in) :: with_r3
    real(dp), intent(inout) :: fx(n), fy(n), s3(n)
    real(dp), intent(inout) :: sx(*), sy(*), ss(*)
    real(dp), intent(inout) :: r2low   !< running minimum of r^2
    type(pair_table_t), intent(in), optional :: tab
    integer :: i
    real(dp) :: fxi, fyi
    if (i_hi < i_lo) return
    if (kernel == kernel_dipole) then   ! row i is the one range i+1..n (tri_*)
      row_sums(:, i_lo:i_hi) = 0
      call dipole_ranges(sp, merge(side_far, side_none, sp%on), i_lo, i_hi, 1, min(n, hi_direct), &
           min(n, hi_direct), x, y, mu, wsin, k_pair, r2_min, huge(1.0_dp), 0.0_dp, with_r3, &
           tri_start, tri_lo, tri_hi, fx, fy, s3, row_sums(:, i_lo:i_hi), r2low, tab)
      if (hi_direct < n) call dipole_ranges(sp, merge(side_far, side_none, sp%on), i_lo, i_hi, &
           hi_direct + 1, n, n, x, y, mu, wsin, k_pair, r2_min, huge(1.0_dp), 0.0_dp, with_r3, &
           tri_start, tri_lo, tri_hi, sx, sy, ss, row_sums(:, i_lo:i_hi), r2low, tab)
      call add_row_sums(i_lo, i_hi, with_r3, row_sums(:, i_lo:i_hi), fx, fy, s3)
      return
    end if
    do i = i_lo, i_hi
      fxi = 0; fyi = 0
      call row_segment(l, i, i + 1, min(n, hi_direct), n, x, y, fx, fy, fxi, fyi, r2low, tab)
      if (hi_direct < n) call row_segment(l, i, max(i + 1, hi_direct + 1), n, n, x, y, sx, sy, &
           fxi, fyi, r2low, tab)
      fx(i) = fx(i) + fxi
      fy(i) = fy(i) + fyi
    end do
  end subroutine rows_all

  !> Lennard-Jones pairs (i, j), j = j_lo..j_hi, of the triangle (contiguous j: vectorised),
  !> in chunks: distances, the law's kernel, sums. The action on i is added to fxi, fyi, the
  !> reaction to ax, ay(j).
  subroutine row_segment(l, i, j_lo, j_hi, n, x, y, ax, ay, fxi, fyi, r2low, tab)
    integer, intent(in) :: i, j_lo, j_hi, n
    type(lj_law_t), intent(in) :: l
    real(dp), intent(in) :: x(n), y(n)
    real(dp), intent(inout) :: ax(*), ay(*)
    real(dp), intent(inout) :: fxi, fyi, r2low
    type(pair_table_t), intent(in), optional :: tab
    integer, parameter :: chunk = 256
    integer :: j, j0, m, nk
    real(dp) :: xi, yi, low, gx, gy
    real(dp) :: dxs(chunk), dys(chunk), r2s(chunk), cs(chunk)
    ! accumulate in locals: dummy arguments updated in the inner loop may
    ! alias the force arrays (no vectorisation) and false-share between threads
    low = r2low
    gx = 0; gy = 0
    xi = x(i); yi = y(i)
    do j0 = j_lo, j_hi, chunk
      nk = min(chunk, j_hi - j0 + 1)
      do m = 1, nk
        dxs(m) = xi - x(j0 + m - 1)
        dys(m) = yi - y(j0 + m - 1)
        r2s(m) = dxs(m)*dxs(m) + dys(m)*dys(m)
        low = min(low, r2s(m))
      end do
      call lj_chunk(l, nk, r2s, cs, tab)
      do m = 1, nk
        j = j0 + m - 1
        gx = gx + cs(m)*dxs(m)
        gy = gy + cs(m)*dys(m)
        ax(j) = ax(j) - cs(m)*dxs(m)
        ay(j) = ay(j) - cs(m)*dys(m)
      end do
    end do
    fxi = fxi + gx
    fyi = fyi + gy
    r2low = low
  end subroutine row_segment

  !> Dipole rows i_lo..i_hi of a half neighbour list (rows of mid_row_pairs .. kept_row_pairs,
  !> usually the list pruned to r_c + prune), the pairs in flat chunks of pair_chunk (whole rows
  !> and pieces of rows). Three passes per chunk, every array written by the pair's position
  !> in the chunk: the separations and r^2 (one flat loop, the row i = own(k) loaded per pair:
  !> no branch at the rows' ends); the law over the whole chunk (vectorised; a pair at r >= r_c
  !> gets the weight 0 exactly, so it adds only signed zeros below); then row by row the sums
  !> on i (carried over a chunk's end while the row lasts, added to fx(i) when it ends, every
  !> row in order, empty ones too) and the reactions on j (j > hi_direct to the spill arrays,
  !> as in rows_all). The same operations on every acting pair, in the same order, as one row
  !> at a time over every listed pair. Until bench/RESULTS.md 42 the first pass kept only the
  !> pairs below r_c, compressed: its stores at an index known only after the pair's r^2 made
  !> the distance loop 3-4x slower than writing by position (a micro-benchmark of the loop
  !> alone), more than the law on the 25-35 % of pruned pairs beyond r_c costs.
  subroutine rows_kept(sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, shift4, &
       check, with_r3, mu_one, start, nbr, own, fx, fy, s3, sx, sy, ss, r2low, tab, rowmax)
    type(split_t), intent(in) :: sp
    integer, intent(in) :: i_lo, i_hi, hi_direct, n
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair, rc2, shift4
    logical, intent(in) :: check, with_r3
    logical, intent(in) :: mu_one   !< every mu(j) = mu(1): no load of mu_j per pair
    integer, intent(in) :: start(n + 1), nbr(*)
    integer, intent(in) :: own(*)   !< the row of each listed pair
    real(dp), intent(inout) :: fx(n), fy(n), s3(n)
    real(dp), intent(inout) :: sx(*), sy(*), ss(*)
    real(dp), intent(inout) :: r2low   !< running minimum of r^2
    type(pair_table_t), intent(in), optional :: tab   !< the dipole law's evaluation
    !> the largest j of each row of the whole list (nlist_t): a row's reactions go by one
    !> branch whichever pairs of it a chunk holds (the branches' products may round
    !> differently), so the pruned list sums as the whole one; absent: by the chunk's j
    integer, intent(in), optional :: rowmax(n)
    integer, parameter :: chunk = pair_chunk
    integer :: i, j, m, m_lo, m_hi, k, k0, k_hi, nk, r_open
    logical :: direct, all_direct, by_row
    real(dp) :: wi, fxi, fyi, s3i, low, rk2, e5, e3, keep, d
    real(dp) :: cs(chunk), r3s(chunk), r2s(chunk), ds(chunk), cis(chunk), dxs(chunk), dys(chunk)
    integer(i8) :: ks(chunk), tn
    integer :: code
    code = eval_exact
    if (present(tab)) code = tab%eval
    rk2 = huge(1.0_dp)   ! pairs at r >= r_c skipped only with check
    if (check) rk2 = rc2
    low = r2low   ! local running minimum (see row_segment)
    if (i_hi < i_lo) return
    r_open = i_lo   ! the row whose sums fxi, fyi, s3i hold
    fxi = 0; fyi = 0; s3i = 0
    wi = wsin(i_lo)
    k_hi = start(i_hi + 1) - 1
    all_direct = hi_direct >= n
    by_row = present(rowmax) .and. .not. all_direct
    do k0 = start(i_lo), k_hi, chunk
      nk = min(chunk, k_hi - k0 + 1)
      d = huge(1.0_dp)
      !GCC$ novector
      do m = 1, nk
        k = k0 + m - 1
        i = own(k)
        j = nbr(k)
        dxs(m) = x(i) - x(j)
        dys(m) = y(i) - y(j)
        r2s(m) = dxs(m)*dxs(m) + dys(m)*dys(m)
        d = min(d, r2s(m))
        if (.not. mu_one) cs(m) = mu(j)*merge(1.0_dp, k_pair*mu(i), sp%on)
      end do
      low = min(low, d)
      if (mu_one) cs(1:nk) = mu(i_lo)*merge(1.0_dp, k_pair*mu(i_lo), sp%on)
      if (sp%on) then
        do m = 1, nk
          cis(m) = k_pair*mu(own(k0 + m - 1))
        end do
      else
        cis(1:nk) = 1
      end if
      associate (c => cs, r3 => r3s, ci => cis, w3 => 1.0_dp)
        include 'dipole_eval.inc'
      end associate
      direct = all_direct
      if (.not. (direct .or. by_row)) direct = maxval(nbr(k0:k0 + nk - 1)) <= hi_direct
      m_lo = 1
      do while (m_lo <= nk)
        i = own(k0 + m_lo - 1)
        if (i /= r_open) then   ! the open row ended: its sums, then the empty rows'
          call close_rows(r_open, i - 1, with_r3, fxi, fyi, s3i, fx, fy, s3)
          r_open = i
          wi = wsin(r_open)
        end if
        m_hi = min(nk, start(i + 1) - k0)
        if (by_row) direct = rowmax(r_open) <= hi_direct
        if (direct) then   ! the usual case: every j is ours
          do m = m_lo, m_hi
            j = nbr(k0 + m - 1)
            fxi = fxi + cs(m)*dxs(m)
            fyi = fyi + cs(m)*dys(m)
            fx(j) = fx(j) - cs(m)*dxs(m)
            fy(j) = fy(j) - cs(m)*dys(m)
          end do
          if (with_r3) then
            do m = m_lo, m_hi
              j = nbr(k0 + m - 1)
              s3i = s3i + wsin(j)*r3s(m)
              s3(j) = s3(j) + wi*r3s(m)
            end do
          end if
        else                          ! rows next to a later thread's block
          do m = m_lo, m_hi
            j = nbr(k0 + m - 1)
            fxi = fxi + cs(m)*dxs(m)
            fyi = fyi + cs(m)*dys(m)
            if (with_r3) s3i = s3i + wsin(j)*r3s(m)
            if (j <= hi_direct) then
              fx(j) = fx(j) - cs(m)*dxs(m)
              fy(j) = fy(j) - cs(m)*dys(m)
              if (with_r3) s3(j) = s3(j) + wi*r3s(m)
            else
              sx(j) = sx(j) - cs(m)*dxs(m)
              sy(j) = sy(j) - cs(m)*dys(m)
              if (with_r3) ss(j) = ss(j) + wi*r3s(m)
            end if
          end do
        end if
        m_lo = m_hi + 1
      end do
    end do
    call close_rows(r_open, i_hi, with_r3, fxi, fyi, s3i, fx, fy, s3)
    r2low = low
  end subroutine rows_kept

  !> rows_kept's end of a row: the open row r_open's sums fxi, fyi, s3i added to fx, fy, s3 (and
  !> zeroed), then zero sums for the empty rows after it up to r_last (as one row at a time).
  !> A module routine with explicit arguments (an internal one was not inlined: 6 % of the step,
  !> the sums then held in memory).
  pure subroutine close_rows(r_open, r_last, with_r3, fxi, fyi, s3i, fx, fy, s3)
    integer, intent(in) :: r_open, r_last
    logical, intent(in) :: with_r3
    real(dp), intent(inout) :: fxi, fyi, s3i, fx(*), fy(*), s3(*)
    integer :: r
    fx(r_open) = fx(r_open) + fxi
    fy(r_open) = fy(r_open) + fyi
    if (with_r3) s3(r_open) = s3(r_open) + s3i
    fxi = 0; fyi = 0; s3i = 0
    do r = r_open + 1, r_last
      fx(r) = fx(r) + fxi
      fy(r) = fy(r) + fyi
      if (with_r3) s3(r) = s3(r) + s3i
    end do
  end subroutine close_rows

  !> Dipole rows i_lo..i_hi of a half neighbour list, row by row, every listed pair (for rows
  !> of kept_row_pairs .. long_row_pairs, and longer with pair_eval = 'single': x_i, y_i, mu_i, wsin_i are scalars of the row, not
  !> gathered as in rows_pairs; shorter rows go by rows_kept). Two passes per
  !> chunk: gather and evaluate (vectorisable), then accumulate on i and scatter on j
  !> (reactions on j > hi_direct to the spill arrays, as in rows_all).
  subroutine rows_list(sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, shift4, &
       check, with_r3, mu_one, start, nbr, fx, fy, s3, sx, sy, ss, r2low, tab)
    type(split_t), intent(in) :: sp
    integer, intent(in) :: i_lo, i_hi, hi_direct, n
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair, rc2, shift4
    logical, intent(in) :: check, with_r3
    logical, intent(in) :: mu_one   !< every mu(j) = mu(1): no gather of mu_j
    integer, intent(in) :: start(n + 1), nbr(*)
    real(dp), intent(inout) :: fx(n), fy(n), s3(n)
    real(dp), intent(inout) :: sx(*), sy(*), ss(*)
    real(dp), intent(inout) :: r2low   !< running minimum of r^2
    integer, parameter :: chunk = 256
    integer :: i, j, m, k0, nk
    logical :: direct
    type(pair_table_t), intent(in), optional :: tab   !< the dipole law's evaluation
    real(dp) :: xi, yi, ci, wi, fxi, fyi, s3i, low, rk2, e5, e3, keep
    real(dp) :: dxs(chunk), dys(chunk), cs(chunk), r3s(chunk), r2s(chunk), ds(chunk), cis(chunk)
    integer(i8) :: ks(chunk), tn
    integer :: code
    code = eval_exact
    if (present(tab)) code = tab%eval
    rk2 = huge(1.0_dp)   ! pairs at r >= r_c skipped only with check
    if (check) rk2 = rc2
    low = r2low   ! local running minimum (see row_segment)
    do i = i_lo, i_hi
      xi = x(i); yi = y(i)
      ci = k_pair*mu(i)
      wi = wsin(i)
      fxi = 0; fyi = 0; s3i = 0
      do k0 = start(i), start(i + 1) - 1, chunk
        nk = min(chunk, start(i + 1) - k0)
        do m = 1, nk   ! distances and weights (gathers)
          j = nbr(k0 + m - 1)
          dxs(m) = xi - x(j)
          dys(m) = yi - y(j)
          r2s(m) = dxs(m)*dxs(m) + dys(m)*dys(m)
          low = min(low, r2s(m))
          if (.not. mu_one) cs(m) = mu(j)   ! (loop-invariant: unswitched)
        end do
        if (mu_one) cs(1:nk) = mu(i)
        cis(1:nk) = ci
        associate (c => cs, r3 => r3s, ci => cis, w3 => 1.0_dp)   ! the law
          include 'dipole_eval.inc'
        end associate
        direct = hi_direct >= n
        if (.not. direct) direct = maxval(nbr(k0:k0 + nk - 1)) <= hi_direct
        if (direct) then   ! the usual case: every j is ours
          do m = 1, nk
            j = nbr(k0 + m - 1)
            fxi = fxi + cs(m)*dxs(m)
            fyi = fyi + cs(m)*dys(m)
            fx(j) = fx(j) - cs(m)*dxs(m)
            fy(j) = fy(j) - cs(m)*dys(m)
          end do
          if (with_r3) then
            do m = 1, nk
              j = nbr(k0 + m - 1)
              s3i = s3i + wsin(j)*r3s(m)
              s3(j) = s3(j) + wi*r3s(m)
            end do
          end if
        else                          ! rows next to a later thread's block
          do m = 1, nk
            j = nbr(k0 + m - 1)
            fxi = fxi + cs(m)*dxs(m)
            fyi = fyi + cs(m)*dys(m)
            if (with_r3) s3i = s3i + wsin(j)*r3s(m)
            if (j <= hi_direct) then
              fx(j) = fx(j) - cs(m)*dxs(m)
              fy(j) = fy(j) - cs(m)*dys(m)
              if (with_r3) s3(j) = s3(j) + wi*r3s(m)
            else
              sx(j) = sx(j) - cs(m)*dxs(m)
              sy(j) = sy(j) - cs(m)*dys(m)
              if (with_r3) ss(j) = ss(j) + wi*r3s(m)
            end if
          end do
        end if
      end do
      fx(i) = fx(i) + fxi
      fy(i) = fy(i) + fyi
      if (with_r3) s3(i) = s3(i) + s3i
    end do
    r2low = low
  end subroutine rows_list

  !> Dipole rows i_lo..i_hi of a half Verlet list given as contiguous ranges of j (nlist_t
  !> rstart, rlo, rhi: the listed j of row i lie in rlo(r)..rhi(r), r = rstart(i)..rstart(i+1)-1,
  !> together with unlisted j that are beyond r_c and are masked out; exact for the Verlet rule,
  !> see neighbours). Reactions on j > hi_direct go to the spill arrays (see threaded_pass).
  subroutine rows_ranges(sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, shift4, &
       with_r3, rstart, rlo, rhi, fx, fy, s3, sx, sy, ss, r2low, tab)
    type(split_t), intent(in) :: sp
    integer, intent(in) :: i_lo, i_hi, hi_direct, n
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair, rc2, shift4
    logical, intent(in) :: with_r3
    integer, intent(in) :: rstart(n + 1), rlo(*), rhi(*)
    real(dp), intent(inout) :: fx(n), fy(n), s3(n)
    real(dp), intent(inout) :: sx(*), sy(*), ss(*)
    real(dp), intent(inout) :: r2low   !< running minimum of r^2
    type(pair_table_t), intent(in), optional :: tab
    integer :: side
    if (i_hi < i_lo) return
    row_sums(:, i_lo:i_hi) = 0
    side = merge(side_near, side_none, sp%on)
    call dipole_ranges(sp, side, i_lo, i_hi, 1, hi_direct, hi_direct, x, y, mu, wsin, k_pair, &
         0.0_dp, rc2, shift4, with_r3, rstart, rlo, rhi, fx, fy, s3, row_sums(:, i_lo:i_hi), r2low, &
         tab)
    if (hi_direct < n) call dipole_ranges(sp, side, i_lo, i_hi, hi_direct + 1, n, n, x, y, mu, &
         wsin, k_pair, 0.0_dp, rc2, shift4, with_r3, rstart, rlo, rhi, sx, sy, ss, &
         row_sums(:, i_lo:i_hi), r2low, tab)
    call add_row_sums(i_lo, i_hi, with_r3, row_sums(:, i_lo:i_hi), fx, fy, s3)
  end subroutine rows_ranges

  !> The dipole kernel over contiguous ranges of j: rows i = i_lo..i_hi, ranges
  !> r = rstart(i)..rstart(i+1)-1, pairs (i, j) for j in rlo(r)..rhi(r) clipped to
  !> j_min..j_max (i outside every range). Pairs are masked by r2_lo <= r^2 < r2_hi, or
  !> (side_near / side_far) weighted by the split's near side S(r) or far side 1 - S(r). Force
  !> on i: k mu_i mu_j (s5 - shift4 r^-1) (r_i - r_j), summed per row in fixed lanes (j = j0 +
  !> l - 1 of each block of lanes goes to lane l: the loop vectorises without reordering a
  !> floating-point sum, and the order depends on the lane count only) and added to rsum(:, i)
  !> (see add_row_sums); the reactions go to ax, ay, a3(j). Whole blocks of lanes run past the end of a
  !> range (masked: exact zeros) while they stay <= j_pad, the last entry of ax, ay, a3 this
  !> caller owns (<= n); the rest runs lane by lane. a3, s3 get exact zeros without with_r3.
  !> r2low: running minimum of r^2 over the ranges.
  subroutine dipole_ranges(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
       k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    type(split_t), intent(in) :: sp
    integer, intent(in) :: side, i_lo, i_hi, j_min, j_max, j_pad
    real(dp), intent(in) :: x(max(j_pad, i_hi)), y(max(j_pad, i_hi)), mu(max(j_pad, i_hi))
    real(dp), intent(in) :: wsin(max(j_pad, i_hi)), k_pair, r2_lo, r2_hi, shift4
    logical, intent(in) :: with_r3
    integer, intent(in) :: rstart(i_hi + 1), rlo(*), rhi(*)
    real(dp), intent(inout) :: ax(j_pad), ay(j_pad), a3(j_pad)
    real(dp), intent(inout) :: rsum(3, i_lo:i_hi)
    real(dp), intent(inout) :: r2low
    type(pair_table_t), intent(in), optional :: tab   !< the dipole law's evaluation
    integer :: code
    code = eval_exact
    if (present(tab)) code = tab%eval
    select case (code)   ! one loop nest (dipole_ranges.inc), compiled once per evaluation
    case (eval_table)
      call ranges_table(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
           k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    case (eval_single)
      call ranges_single(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
           k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    case (eval_rsqrt)
      call ranges_rsqrt(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
           k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    case default
      call ranges_exact(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
           k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    end select
  end subroutine dipole_ranges

  ! dipole_ranges by evaluation: the loop nest of dipole_ranges.inc compiled with the constant law
  subroutine ranges_exact(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
       k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    integer, parameter :: law = eval_exact
    include 'dipole_ranges.inc'
  end subroutine ranges_exact

  subroutine ranges_table(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
       k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    integer, parameter :: law = eval_table
    include 'dipole_ranges.inc'
  end subroutine ranges_table

  subroutine ranges_single(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
       k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    integer, parameter :: law = eval_single
    include 'dipole_ranges.inc'
  end subroutine ranges_single

  subroutine ranges_rsqrt(sp, side, i_lo, i_hi, j_min, j_max, j_pad, x, y, mu, wsin, &
       k_pair, r2_lo, r2_hi, shift4, with_r3, rstart, rlo, rhi, ax, ay, a3, rsum, r2low, tab)
    integer, parameter :: law = eval_rsqrt
    include 'dipole_ranges.inc'
  end subroutine ranges_rsqrt

  !> Add the row sums of dipole_ranges to the rows' own forces.
  subroutine add_row_sums(i_lo, i_hi, with_r3, rsum, fx, fy, s3)
    integer, intent(in) :: i_lo, i_hi
    logical, intent(in) :: with_r3
    real(dp), intent(in) :: rsum(3, i_lo:i_hi)
    real(dp), intent(inout) :: fx(*), fy(*), s3(*)
    integer :: i
    do i = i_lo, i_hi
      fx(i) = fx(i) + rsum(1, i)
      fy(i) = fy(i) + rsum(2, i)
      if (with_r3) s3(i) = s3(i) + rsum(3, i)
    end do
  end subroutine add_row_sums

  !> One lane of dipole_ranges at squared distance d2 = dx^2 + dy^2: r2 = d2 (huge(1.0) in a
  !> lane that is off, so that it leaves the running minimum alone) and the lane's weight
  !> keep (the kernel's factor): exactly 0 in a lane that is off or out of the mask r2_lo <=
  !> d2 < r2_hi, else wa + wb S(r): 1 (wa = 1, wb = 0), S (0, 1) or 1 - S (1, -1).
  pure elemental subroutine lane_weight(sp, wa, wb, lane, r2_lo, r2_hi, d2, r2, keep)
    type(split_t), intent(in) :: sp
    real(dp), intent(in) :: wa, wb, lane, r2_lo, r2_hi, d2
    real(dp), intent(out) :: r2, keep
    keep = merge(1.0_dp, 0.0_dp, d2 >= r2_lo)*merge(1.0_dp, 0.0_dp, d2 < r2_hi)*lane
    keep = keep*(wa + wb*near_weight(sp, d2))
    r2 = d2 + (1.0_dp - lane)*huge(1.0_dp)
  end subroutine lane_weight

  !> Rows i_lo..i_hi of a half list taken as one flat sequence of pairs (own(k) = the row i of
  !> pair k): chunks of 256 pairs whatever the row lengths (a row holds ~5 pairs at the
  !> production cut-offs, too few to vectorise row by row). Per chunk, one vectorised loop of
  !> the law (distances gathered, the kernel branch-free), then chunk_sums. The law is chosen
  !> once per chunk, outside the loops. Dipole: pairs at r >= r_c are skipped when check is
  !> set, and the r^-3 friction sums (with_r3) go along. Reactions on j > hi_direct go to the
  !> spill arrays sx, sy, ss (see threaded_pass).
  subroutine rows_pairs(kernel, l, sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, &
       shift4, check, with_r3, start, nbr, own, fx, fy, s3, sx, sy, ss, r2low, tab)
    integer, intent(in) :: kernel, i_lo, i_hi, hi_direct, n
    type(lj_law_t), intent(in) :: l
    type(split_t), intent(in) :: sp
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair, rc2, shift4
    logical, intent(in) :: check, with_r3
    integer, intent(in) :: start(n + 1), nbr(*), own(*)   ! contiguous (stride-1 index loads)
    real(dp), intent(inout) :: fx(n), fy(n), s3(n), sx(*), sy(*), ss(*)
    real(dp), intent(inout) :: r2low
    integer, parameter :: chunk = pair_chunk
    integer :: i, j, m, k, k0, nk, k_hi, code, ic, shift
    real(dp) :: low, rk2, keep3, e5, e3, keep, ax, ay, a3, d
    real(dp) :: s, on, c4p, rm2, lc2, lo2, hi2, dd   ! (lj_eval.inc)
    integer(i8) :: base, kk
    ! per pair: x_i - x_j, y_i - y_j, then the dipole's force factor and r^-3, or the
    ! Lennard-Jones force on i (x, y)
    real(dp) :: r2s(chunk), pw(chunk, 4)
    type(pair_table_t), intent(in), optional :: tab   !< the law's evaluation
    integer(i8) :: ks(pair_chunk), tn
    real(dp) :: ds(pair_chunk)
    code = eval_exact
    if (present(tab)) code = tab%eval
    low = r2low
    keep3 = merge(1.0_dp, 0.0_dp, with_r3)
    rk2 = huge(1.0_dp)
    if (check) rk2 = rc2
    k_hi = start(i_hi + 1) - 1
    ax = 0; ay = 0; a3 = 0
    if (k_hi >= start(i_lo)) ic = own(start(i_lo))   ! the first open row
    do k0 = start(i_lo), k_hi, chunk
      nk = min(chunk, k_hi - k0 + 1)
      ! scalar loads, not vector gathers: with AVX-512 GCC 12 gathers 8 doubles per
      ! vgatherdpd, which on Zen 4 cost 1.5x the scalar loop (bench/RESULTS.md 35.10)
      ! (r^2 and the chunk's least in this scalar loop too, not in a vector pass of their own:
      ! the same bits, 1.02x the LJ step, bench/RESULTS.md 41.5)
      d = huge(1.0_dp)
      !GCC$ novector
      do m = 1, nk                  ! distances, shared by the laws
        k = k0 + m - 1
        i = own(k)
        j = nbr(k)
        pw(m, 1) = x(i) - x(j)
        pw(m, 2) = y(i) - y(j)
        r2s(m) = pw(m, 1)*pw(m, 1) + pw(m, 2)*pw(m, 2)
        d = min(d, r2s(m))
      end do
      low = min(low, d)
      if (kernel == kernel_dipole) then
        pw(1:nk, 3) = 1             ! (the law's input factor)
        ! force factor times k mu_i mu_j in chunk_sums (no gathers of mu, wsin here); r^-3
        ! times 0 without the friction sums (s3 then gets + 0)
        associate (c => pw(:, 3), r3 => pw(:, 4), ci => ones, w3 => keep3)
          include 'dipole_eval.inc'
        end associate
      else
        ! the forces on i into columns 3, 4 from the law's loop itself (chunk_sums adds these
        ! rounded products: a product inside the sums would be contracted, other bits)
        associate (d1 => pw(:, 1), d2 => pw(:, 2), g1 => pw(:, 3), g2 => pw(:, 4))
          include 'lj_eval.inc'
        end associate
      end if
      call chunk_sums(nk, own(k0:k0 + nk - 1), nbr(k0:k0 + nk - 1), hi_direct, &
           kernel == kernel_dipole, pw, fx, fy, s3, sx, sy, ss, mu, wsin, k_pair, hi_direct >= n, &
           ic, ax, ay, a3, lj_rx, lj_ry)
    end do
    if (kernel /= kernel_dipole) then
      ! the rows' sums after their reactions (every j > i: all of row i's reactions came
      ! before it, so fx(i) gets the same additions in the same order as at the row's end)
      do i = i_lo, i_hi
        if (start(i + 1) > start(i)) then
          fx(i) = fx(i) + lj_rx(i)
          fy(i) = fy(i) + lj_ry(i)
        end if
      end do
    else if (k_hi >= start(i_lo)) then   ! the dipole's last open row
      fx(ic) = fx(ic) + ax
      fy(ic) = fy(ic) + ay
      s3(ic) = s3(ic) + a3
    end if
    r2low = low
  end subroutine rows_pairs

  !> The sums of one chunk of pairs (i = own(m), j = nbr(m)) with force factors cs and
  !> separations dxs, dys: the action on the open row ic summed in registers while its row
  !> lasts (pairs come in row order: no store-to-load chain through fx(i) from one pair to the
  !> next), also across chunks (ic, ax, ay, a3 carried: the sums do not depend on where the
  !> chunks end, so a list with pairs left out beyond r_c sums the same terms the same way;
  !> the caller adds the last open row), the reaction on j directly (j <= hi_direct) or to the
  !> spill arrays. Dipole (scaled): the force factor is k mu_i mu_j cs, and s3(i) += wsin_j r3s,
  !> s3(j) += wsin_i r3s (mu_i and wsin_i loaded once per row; r3s = 0 without the friction
  !> sums). Otherwise (Lennard-Jones) columns 3, 4 hold the pair's force on i itself (the
  !> law's loop in rows_pairs multiplies it out, vectorised: here a product inside the sums
  !> would be contracted into two fused multiply-adds, other bits), a row's sums go without a
  !> branch at the row's end into rx, ry (the caller adds them; see the loop), and serially
  !> (all_direct) the reactions go without the test on hi_direct.
  subroutine chunk_sums(nk, own, nbr, hi_direct, scaled, pw, fx, fy, s3, sx, sy, ss, mu, &
       wsin, k_pair, all_direct, ic, ax, ay, a3, rx, ry)
    integer, intent(in) :: nk, own(nk), nbr(nk), hi_direct
    logical, intent(in) :: scaled
    logical, intent(in) :: all_direct   !< hi_direct >= n: every reaction direct
    !> per pair m: separations dx, dy (columns 1, 2), then the dipole's force factor cs (3)
    !> and r^-3 r3s (4), or the Lennard-Jones force on i, x (3) and y (4); one array (one base
    !> register in the scalar loop, which otherwise reloads four from the stack)
    real(dp), intent(in) :: pw(pair_chunk, 4)
    real(dp), intent(in) :: mu(*), wsin(*), k_pair
    real(dp), intent(inout) :: fx(*), fy(*), s3(*), sx(*), sy(*), ss(*)
    integer, intent(inout) :: ic             !< the open row
    real(dp), intent(inout) :: ax, ay, a3    !< its sums so far
    !> Lennard-Jones: the running sums of each row, stored at each of its pairs (unused by
    !> the dipole)
    real(dp), intent(inout) :: rx(*), ry(*)
    integer :: m, i, j, jc
    real(dp) :: gx, gy, c, ci, wi, bx, by
    if (scaled) then
      ci = k_pair*mu(ic)
      wi = wsin(ic)
      do m = 1, nk
        i = own(m)
        j = nbr(m)
        if (i /= ic) then
          fx(ic) = fx(ic) + ax
          fy(ic) = fy(ic) + ay
          s3(ic) = s3(ic) + a3
          ic = i
          ci = k_pair*mu(i)
          wi = wsin(i)
          ax = 0; ay = 0; a3 = 0
        end if
        c = ci*mu(j)*pw(m, 3)   ! (mu_j from a register with mu_one: 0.95-0.97x, RESULTS 38.3)
        gx = c*pw(m, 1)
        gy = c*pw(m, 2)
        ax = ax + gx
        ay = ay + gy
        a3 = a3 + wsin(j)*pw(m, 4)
        if (j <= hi_direct) then
          fx(j) = fx(j) - gx
          fy(j) = fy(j) - gy
          s3(j) = s3(j) + wi*pw(m, 4)
        else
          sx(j) = sx(j) - gx
          sy(j) = sy(j) - gy
          ss(j) = ss(j) + wi*pw(m, 4)
        end if
      end do
    else
      ! No branch at the row ends (one unpredictable branch per row of ~5 pairs cost ~25 % of
      ! the step, bench/RESULTS.md 40.1): the running sum is multiplied by keep = 1 within a
      ! row and 0 at its first pair (from the row ids by integer arithmetic: GCC makes a
      ! branch of a merge or a comparison here), as a fused multiply-add: b*1 + g is b + g
      ! rounded once, b*0 + g is g (up to the sign of a zero), so a row's sum is the same
      ! additions as before. It is stored at every pair (the last store is the row's sum)
      ! and rows_pairs adds it after the pass. The reactions go in pair order, directly
      ! (serially always: all_direct) or to the spill beyond hi_direct.
      bx = ax
      by = ay
      jc = ic
      if (all_direct) then   ! (serially: no test per pair; with it, 0.96x at N 2e3 and 1e4)
        do m = 1, nk
          j = nbr(m)
          call row_step(own(m), pw(m, 3), pw(m, 4), jc, bx, by, rx, ry)
          fx(j) = fx(j) - pw(m, 3)
          fy(j) = fy(j) - pw(m, 4)
        end do
      else
        do m = 1, nk
          j = nbr(m)
          call row_step(own(m), pw(m, 3), pw(m, 4), jc, bx, by, rx, ry)
          if (j <= hi_direct) then
            fx(j) = fx(j) - pw(m, 3)
            fy(j) = fy(j) - pw(m, 4)
          else
            sx(j) = sx(j) - pw(m, 3)
            sy(j) = sy(j) - pw(m, 4)
          end if
        end do
      end if
      ax = bx
      ay = by
      ic = jc
    end if
  end subroutine chunk_sums

  !> One pair (row i, force gx, gy on i) of chunk_sums' Lennard-Jones row sums: the running
  !> sums bx, by of row jc continued, or restarted when i begins a new row, and stored as
  !> row i's; jc becomes i. The restart by keep = 1 or 0 from integer arithmetic (no
  !> comparison for GCC to turn into a branch) and b*keep + g (a fused multiply-add).
  pure subroutine row_step(i, gx, gy, jc, bx, by, rx, ry)
    integer, intent(in) :: i
    real(dp), intent(in) :: gx, gy
    integer, intent(inout) :: jc
    real(dp), intent(inout) :: bx, by, rx(*), ry(*)
    integer :: d
    real(dp) :: keep
    d = ieor(i, jc)
    keep = real(1 + shifta(ior(d, -d), 31), dp)   ! 1 if i == jc, else 0
    bx = bx*keep + gx
    by = by*keep + gy
    rx(i) = bx
    ry(i) = by
    jc = i
  end subroutine row_step

  !> rows_pairs' Lennard-Jones row sums for n particles (allocated when too small).
  subroutine lj_row_buffers(n)
    integer, intent(in) :: n
    if (allocated(lj_rx)) then
      if (size(lj_rx) < n) deallocate(lj_rx, lj_ry)
    end if
    if (.not. allocated(lj_rx)) allocate(lj_rx(n), lj_ry(n))
  end subroutine lj_row_buffers

  !> The buffers of the contiguous dipole passes for n particles (allocated when n changes).
  subroutine range_buffers(n)
    integer, intent(in) :: n
    integer :: i
    if (allocated(row_sums)) then
      if (size(row_sums, 2) /= n) deallocate(row_sums, tri_start, tri_lo, tri_hi)
    end if
    if (allocated(row_sums)) return
    allocate(row_sums(3, n), tri_start(n + 1), tri_lo(n), tri_hi(n))
    tri_start = [(i, i = 1, n + 1)]
    tri_lo = [(i + 1, i = 1, n)]
    tri_hi = n
  end subroutine range_buffers

  !> Run the rows on the OpenMP threads, deterministically and without
  !> per-step buffers. Thread t takes a fixed block of rows lo_t..hi_t
  !> holding ~1/nt of the pairs. Since every pair (i, j) has j > i, only
  !> thread t touches the force entries of its own block: it adds to them
  !> directly, and puts its reactions on rows j > hi_t (the band next to the
  !> following blocks) into a persistent spill buffer. After a barrier the
  !> spills are added in thread order and reset to zero. The result does not
  !> depend on scheduling, and on the thread count only through round-off.
  subroutine threaded_pass(mode, kernel, l, sp, n, x, y, mu, wsin, k_pair, r2_min, rc2, &
       shift4, check, with_r3, start, nbr, fx, fy, s3, r2low, own, rstart, rlo, rhi, tab, mu_one, &
       pstart, pnbr, pown, rowmax)
    !$ use omp_lib, only: omp_get_max_threads, omp_get_thread_num
    integer, intent(in) :: mode, kernel, n
    type(lj_law_t), intent(in) :: l
    type(split_t), intent(in) :: sp
    real(dp), intent(in) :: x(n), y(n), mu(n), wsin(n), k_pair, r2_min, rc2, shift4
    logical, intent(in) :: check, with_r3
    integer, intent(in), contiguous :: start(:), nbr(:)
    real(dp), intent(inout) :: fx(n), fy(n), s3(n)
    real(dp), intent(out) :: r2low
    integer, intent(in), optional, contiguous :: own(:)   !< row of each listed pair (lists only)
    integer, intent(in), optional, contiguous :: rstart(:), rlo(:), rhi(:)   !< the list's ranges
    type(pair_table_t), intent(in), optional :: tab   !< the law's table (used when on)
    logical, intent(in), optional :: mu_one   !< every mu(i) equals mu(1) (pair_forces_list)
    !> the pruned list for rows_kept and rows_pairs (pair_forces_list)
    integer, intent(in), optional, contiguous :: pstart(:), pnbr(:), pown(:)
    integer, intent(in), optional, contiguous :: rowmax(:)   !< (pair_forces_list)
    real(dp) :: low(64)
    logical :: use_p
    logical :: one
    integer :: nt, t, lo, hi, i, u
    integer :: bound(0:64)
    real(dp) :: work, dummy(1, 3)
    logical :: mid_rows, kept_rows, long_rows
    one = .false.
    if (present(mu_one)) one = mu_one
    nt = 1
    ! threads only pay off with enough pairs per step (fork/join costs ~ microseconds)
    if (mode == mode_all) then
      work = 0.5_dp*real(n, dp)**2
    else
      work = real(start(n + 1) - 1, dp)
    end if
    ! dipole lists: the flat pair sequence when rows are short, the kept pairs in flat chunks
    ! (rows_kept) and row by row in between, by ranges when they are long (bench/RESULTS.md sections 26, 35.6); single precision row by
    ! row (its 8-lane range loop measured 0.6-0.8x the rows on the AVX2 EPYC)
    mid_rows = work >= mid_row_pairs*real(max(1, n), dp)
    kept_rows = work < kept_row_pairs*real(max(1, n), dp)
    long_rows = work >= long_row_pairs*real(max(1, n), dp) .and. present(rstart)
    if (present(tab)) long_rows = long_rows .and. tab%eval /= eval_single
    use_p = present(pstart) .and. present(pnbr) .and. present(pown)
    if (use_p) use_p = list_takes_pruned(kernel /= kernel_dipole, n, start(n + 1) - 1)
    !$ if (work >= 5.0e4_dp) nt = min(omp_get_max_threads(), 64)
    r2low = huge(1.0_dp)
    if (kernel == kernel_dipole .and. (mode == mode_all .or. long_rows)) call range_buffers(n)
    ! (the dipole's rows_pairs passes it without using it: one element)
    if (mode /= mode_all) call lj_row_buffers(merge(n, 1, kernel /= kernel_dipole))
    if (nt == 1) then
      dummy = 0
      call rows(1, n, n, fx, fy, s3, dummy(:, 1), dummy(:, 2), dummy(:, 3), r2low)
      return
    end if
    if (allocated(spill)) then
      if (size(spill, 1) /= n .or. size(spill, 3) < nt) deallocate(spill)
    end if
    if (.not. allocated(spill)) then
      allocate(spill(n, 3, nt))
      spill = 0
    end if
    do t = 0, nt
      bound(t) = first_row(t)
    end do
    !$omp parallel num_threads(nt) default(shared) private(t, lo, hi, u)
    t = 1
    !$ t = omp_get_thread_num() + 1
    low(t) = huge(1.0_dp)
    lo = bound(t - 1) + 1
    hi = bound(t)
    call rows(lo, hi, hi, fx, fy, s3, spill(:, 1, t), spill(:, 2, t), spill(:, 3, t), low(t))
    !$omp barrier
    ! rows above the first block may hold spills of earlier threads
    !$omp do schedule(static)
    do i = bound(1) + 1, n
      do u = 1, nt - 1
        if (i <= bound(u)) exit      ! threads u and later own row i or spill nothing on it
        fx(i) = fx(i) + spill(i, 1, u)
        fy(i) = fy(i) + spill(i, 2, u)
        spill(i, 1, u) = 0
        spill(i, 2, u) = 0
        if (with_r3) then
          s3(i) = s3(i) + spill(i, 3, u)
          spill(i, 3, u) = 0
        end if
      end do
    end do
    !$omp end do
    !$omp end parallel
    r2low = minval(low(1:nt))
  contains
    subroutine rows(i_lo, i_hi, hi_direct, ax, ay, a3, bx, by, b3, lw)
      integer, intent(in) :: i_lo, i_hi, hi_direct
      real(dp), intent(inout) :: ax(n), ay(n), a3(n), bx(*), by(*), b3(*), lw
      if (mode == mode_all) then
        call rows_all(kernel, l, sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, r2_min, &
             with_r3, ax, ay, a3, bx, by, b3, lw, tab)
      else if (kernel == kernel_dipole .and. long_rows) then
        call rows_ranges(sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, shift4, &
             with_r3, rstart, rlo, rhi, ax, ay, a3, bx, by, b3, lw, tab)
      else if (kernel == kernel_dipole .and. mid_rows .and. kept_rows .and. use_p) then
        call rows_kept(sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, &
             shift4, check, with_r3, one, pstart, pnbr, pown, ax, ay, a3, bx, by, b3, lw, tab, &
             rowmax)
      else if (kernel == kernel_dipole .and. mid_rows .and. kept_rows) then
        call rows_kept(sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, &
             shift4, check, with_r3, one, start, nbr, own, ax, ay, a3, bx, by, b3, lw, tab, rowmax)
      else if (kernel == kernel_dipole .and. mid_rows) then
        call rows_list(sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, &
             shift4, check, with_r3, one, start, nbr, ax, ay, a3, bx, by, b3, lw, tab)
      else if (use_p) then
        call rows_pairs(kernel, l, sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, &
             shift4, check, with_r3, pstart, pnbr, pown, ax, ay, a3, bx, by, b3, lw, tab)
      else
        call rows_pairs(kernel, l, sp, i_lo, i_hi, hi_direct, n, x, y, mu, wsin, k_pair, rc2, &
             shift4, check, with_r3, start, nbr, own, ax, ay, a3, bx, by, b3, lw, tab)
      end if
    end subroutine rows
    !> Last row of the first k shares (0 for k = 0, n for k = nt).
    integer function first_row(k) result(r)
      integer, intent(in) :: k
      real(dp) :: target, total
      integer :: lo_r, hi_r, mid
      if (k <= 0) then
        r = 0
        return
      end if
      if (k >= nt) then
        r = n
        return
      end if
      if (mode == mode_all) then
        ! pairs in rows 1..r: r n - r (r+1)/2; solve for the share k/nt
        total = 0.5_dp*real(n, dp)*real(n - 1, dp)
        target = total*real(k, dp)/real(nt, dp)
        r = int((real(n, dp) - 0.5_dp) - sqrt((real(n, dp) - 0.5_dp)**2 - 2*target))
      else
        total = real(start(n + 1) - 1, dp)
        target = total*real(k, dp)/real(nt, dp)
        ! smallest r with start(r + 1) - 1 >= target (start is monotonic): bisection
        lo_r = 0
        hi_r = n
        do while (lo_r < hi_r)
          mid = (lo_r + hi_r)/2
          if (real(start(mid + 1) - 1, dp) < target) then
            lo_r = mid + 1
          else
            hi_r = mid
          end if
        end do
        r = lo_r
      end if
      r = max(0, min(n, r))
    end function first_row
  end subroutine threaded_pass

  !> Pair potential energy sum_{i<j} (k_pair/3) mu_i mu_j r^-3 [m1 g D1] (untruncated).
  function pair_energy_all(n, x, y, mu, k_pair) result(e)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), mu(n), k_pair
    real(dp) :: e, s5, r3
    integer :: i, j
    e = 0
    do i = 1, n - 1
      do j = i + 1, n
        call dipole_kernel((x(i) - x(j))**2 + (y(i) - y(j))**2, 0.0_dp, s5, r3)
        e = e + mu(i)*mu(j)*r3
      end do
    end do
    e = e*k_pair/3.0_dp
  end function pair_energy_all

end module pair_forces
