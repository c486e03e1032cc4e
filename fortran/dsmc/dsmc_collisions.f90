!> Binary collision law of rods of vanishing girth in the plane (seed 001,
!> "An example: nematic liquid crystals") and the Nanbu-Babovsky pair draw.
!>
!> A sample is (v in R^2, theta, omega): centre velocity, axis angle (axis
!> e = (cos theta, sin theta), normal e_perp = (-sin theta, cos theta)) and
!> angular velocity. Mass m, moment of inertia I about the centre, length L
!> (scene &rods; I = m L^2/12 for a thin rod, or given: the slides use
!> m = I = L = 1).
!>
!> Collision law (the slide's, 2D): with the contact arms r, r_* (centre to
!> contact point) and the unit contact normal n,
!>   v'  = v  - (1 + e_v) J/m n,           v*' = v* + (1 + e_v) J/m n,
!>   w'  = w  - (1 + e_w) J/I (r x n),     w*' = w* + (1 + e_w) J/I (r* x n),
!>   J   = - V.n / (2/m + [I^-1 (r x n) x r + I*^-1 (r* x n) x r*].n),
!> theta, theta* unchanged. In 2D r x n = r_x n_y - r_y n_x =: a is a scalar
!> (the z component) and ((a z) x r).n = a (z x r).n = a^2, so the bracket
!> is K = 2/m + a^2/I + a*^2/I. V is the velocity of the partner's contact
!> point relative to ours: V = (v* + w* z x r*) - (v + w z x r), and
!> (z x r).n = a, so V.n = (v* - v).n + w* a* - w a =: g_t + g_r.
!>
!> Geometry (derivation; the slide leaves it implicit). Two segments of zero
!> girth touch, generically, tip on side: one end of one rod (the striker)
!> meets the side of the other (the struck rod); tip-on-tip and side-on-side
!> contacts have measure zero. The contact normal is then the struck rod's
!> normal, n = +-e_perp(theta_struck); the struck rod's arm is s e(theta_struck)
!> with s in [-L/2, L/2] the contact abscissa, the striker's arm is
!> sigma (L/2) e(theta_striker), sigma = +-1 the tip. With Maxwellian molecules
!> (the slides' collision operator: a rate 1/tau independent of the
!> pre-collision state) the impact parameters are drawn from their uniform
!> law: the struck rod is either of the pair with probability 1/2, s uniform on
!> [-L/2, L/2], sigma = +-1 with probability 1/2. The striker's arm projects
!> on the normal through a* = sigma (L/2) cos(theta_striker - theta_struck)
!> (x the struck one's arm a = s), so a grazing striker (parallel rods) gives a
!> purely translational kick and a perpendicular one the largest spin.
!> Orientation of n: the post-collision state depends on n only through
!> J n and J (r x n), both even in n (J is odd), so the sign of n is free,
!> and so is it for dE below (J g_t, J g_r and J^2 are even): the kernel
!> leaves n as drawn (J of either sign, no branch); orienting n so that
!> V.n <= 0 would give J >= 0 and the same bits of every result.
!>
!> Checks (tests/test_rods.py, via the engine's collision audit):
!> * elastic (e_v = e_w = 1): total momentum is unchanged (equal and opposite
!>   impulses) and the energy change
!>     dE = (1+e_v) J g_t + (1+e_v)^2 J^2/m + (1+e_w) J g_r + (1+e_w)^2 J^2 A/2,
!>   A = a^2/I + a*^2/I, vanishes: with g_t + g_r = -J K it is
!>     dE = -(1 - e^2)/2 J^2 K = -(1 - e^2) (V.n)^2 / (2 K)   for e_v = e_w = e,
!>   zero at e = 1 and the energy loss formula for e < 1. With e_v /= e_w dE
!>   is not sign-definite (e.g. g_t = 0, e_v = 1, e_w = 0 gives
!>   dE = 2J^2/m - J^2 A/2): the scene allows it, the audit reports it.
!> * for fixed impact parameters the elastic map is the reflection
!>   z -> z - 2 (b.z) b/|b|^2 of the mass-weighted pair state z, which keeps
!>   the measure and the energy: the product of Maxwellians in v and w with
!>   one temperature (equipartition over 2 + 1 degrees of freedom) is a
!>   stationary state of the collision step for every theta distribution.
!> * translation-rotation exchange: averaging dE_rot = 2 J g_r + 2 J^2 A over
!>   uncorrelated velocities and spins gives (4A/(m K^2)) (T_t - T_r) per
!>   collision, so T_t - T_r decays at the rate (3/2) E_geometry[4A/(m K^2)]/tau
!>   (pyorch.rods.exchange_coefficient; measured in tests/test_rods.py).
!> Point particles (rotation off): arms and spins play no part, K = 2/m and n
!> is uniform on the circle (Maxwell molecules in 2D: the BKW solution).
!>
!> Kernel (collide_pairs): the pairs in blocks of `block`; per block the samples are
!> gathered into contiguous buffers, the law runs branch-free on them (the struck rod and the
!> tip chosen by merge; cos and sin in their own loops, which GCC vectorises through glibc's
!> libmvec), and the results are scattered back. A block's impact uniforms come from the
!> counter-based stream of dsmc_rng.c at counters fixed by (step, pair): the numbers, hence
!> the samples, do not depend on the thread count or on the order the blocks are run in.
!
! glibc's vector cos/sin (libmvec, linked through libm's AS_NEEDED; at most 4 ulp): GCC calls
! them for the loops below (8 lanes with -march=native, 2 without). x86_64 glibc only.
!GCC$ builtin (cos) attributes simd (notinbranch) if('x86_64')
!GCC$ builtin (sin) attributes simd (notinbranch) if('x86_64')
module dsmc_collisions
  use, intrinsic :: iso_c_binding, only: c_int64_t, c_double, c_loc, c_ptr
  use kinds, only: dp, i8, pi
  use parallel, only: par_min_loop
  implicit none
  private

  public :: collision_t, pair_count, draw_pairs, collide_pairs, stream_key, uniforms, &
       numbers_per_pair

  integer, parameter :: block = 256              !< pairs per block (its buffers fit in L1)
  integer(i8), parameter :: numbers_per_pair = 5  !< uniforms per pair and step: 2 draw + 3 impact
  !> A collided pair with |v_x| + |v_y| of a sample at or above this is a runaway (v^4 summed
  !> over 2e8 samples, M4, stays finite below it).
  real(dp), parameter :: v_bound = 1.0e60_dp

  !> Parameters of the collision law.
  type :: collision_t
    real(dp) :: m = 1.0_dp          !< mass [m]
    real(dp) :: inertia = 1.0_dp    !< moment of inertia about the centre [m L^2]
    real(dp) :: length = 1.0_dp     !< rod length [L]
    real(dp) :: e_v = 1.0_dp        !< translational restitution [1]
    real(dp) :: e_w = 1.0_dp        !< rotational restitution [1]
    logical :: rotation = .true.    !< rods (.true.) or point particles
  end type collision_t

  interface
    function dsmc_stream_key(seed) result(key) bind(C, name='dsmc_stream_key')
      import :: c_int64_t
      integer(c_int64_t), value :: seed
      integer(c_int64_t) :: key
    end function dsmc_stream_key
    subroutine dsmc_uniforms(key, step, per_step, offset, n, u) bind(C, name='dsmc_uniforms')
      import :: c_int64_t, c_double
      integer(c_int64_t), value :: key, step, per_step, offset, n
      real(c_double), intent(out) :: u(*)
    end subroutine dsmc_uniforms
    subroutine dsmc_prefetch(m, idx, base, stride) bind(C, name='dsmc_prefetch')
      import :: c_int64_t, c_ptr
      integer(c_int64_t), value :: m, stride
      integer(c_int64_t), intent(in) :: idx(*)
      type(c_ptr), value :: base
    end subroutine dsmc_prefetch
  end interface

contains

  !> Babovsky's pair count per step, floor(N dt / (2 tau)) (dt <= tau: at most N/2).
  pure function pair_count(n, dt, tau) result(nc)
    integer(i8), intent(in) :: n
    real(dp), intent(in) :: dt, tau
    integer(i8) :: nc
    nc = min(int(real(n, dp)*dt/(2.0_dp*tau), i8), n/2)
  end function pair_count

  !> Key of the counter-based stream of a scene seed (dsmc_rng.c).
  function stream_key(seed) result(key)
    integer(i8), intent(in) :: seed
    integer(i8) :: key
    key = dsmc_stream_key(seed)
  end function stream_key

  !> u(i) = uniform on [0, 1) number step*per_step + offset + i of the stream `key`.
  subroutine uniforms(key, step, per_step, offset, u)
    integer(i8), intent(in) :: key, step, per_step, offset
    real(dp), intent(out) :: u(:)
    call dsmc_uniforms(key, step, per_step, offset, size(u, kind=i8), u)
  end subroutine uniforms

  !> 2 nc distinct indices of 1..N without replacement: the first 2 nc entries
  !> of `perm` after a partial Fisher-Yates shuffle driven by the uniforms u(1:2nc).
  !> `perm` stays a permutation of 1..N (it is part of the checkpointed state).
  subroutine draw_pairs(perm, u, nc)
    integer(i8), contiguous, target, intent(inout) :: perm(:)
    real(dp), contiguous, intent(in) :: u(:)
    integer(i8), intent(in) :: nc
    integer, parameter :: ahead = 64        !< swaps whose targets are prefetched together
    integer(i8) :: jc(ahead), jn(ahead), k, k0, kn, j, n, tmp
    integer :: a, mc, mn
    n = size(perm, kind=i8)
    mn = 0
    call targets(1_i8, jn, mn)
    do k0 = 1, 2*nc, ahead
      jc(1:mn) = jn(1:mn)
      mc = mn
      kn = k0 + ahead
      call targets(kn, jn, mn)               ! the next chunk's targets, in flight meanwhile
      if (mn > 0) call dsmc_prefetch(int(mn, i8), jn, c_loc(perm(1)), 8_i8)
      do a = 1, mc
        k = k0 + a - 1
        j = jc(a)
        tmp = perm(k); perm(k) = perm(j); perm(j) = tmp
      end do
    end do
  contains
    !> j(1:mm) of the swaps k0.. (at most `ahead`, up to 2 nc): k + floor(u(k) (n - k + 1)).
    subroutine targets(k0, j, mm)
      integer(i8), intent(in) :: k0
      integer(i8), intent(out) :: j(ahead)
      integer, intent(out) :: mm
      integer :: b
      integer(i8) :: k
      mm = int(max(0_i8, min(int(ahead, i8), 2*nc - k0 + 1)))
      do b = 1, mm
        k = k0 + b - 1
        j(b) = k + min(int(u(k)*real(n - k + 1, dp), i8), n - k)
      end do
    end subroutine targets
  end subroutine draw_pairs

  !> The rod law on the nc = size(de) pairs (pidx(2p-1), pidx(2p)) of step `step`; the block
  !> of pairs p0..p0+m-1 takes the step's stream numbers 2 nc + 3 (p0 - 1) + 1..3m (the first
  !> 2 nc drive the pair draw) as m struck-rod choices, m abscissae, m tips (law_rods). de(p) = the formula's energy change of pair p [m L^2/t0^2];
  !> bad = some collided sample left with |v_x| + |v_y| >= v_bound or not finite;
  !> ade, adp = the audit's maxima (relative energy and momentum errors; 0 unless audit).
  subroutine collide_pairs(c, pidx, key, step, audit, v, theta, omega, de, bad, ade, adp)
    type(collision_t), intent(in) :: c
    integer(i8), contiguous, intent(in) :: pidx(:)
    integer(i8), intent(in) :: key, step
    logical, intent(in) :: audit
    real(dp), contiguous, target, intent(inout) :: v(:, :), omega(:)
    real(dp), contiguous, target, intent(in) :: theta(:)
    real(dp), intent(out) :: de(:)
    logical, intent(out) :: bad
    real(dp), intent(out) :: ade, adp
    integer(i8) :: nc, nb, b, p0, m, q0, q1
    nc = size(de, kind=i8)
    nb = (nc + block - 1)/block
    bad = .false.
    ade = 0.0_dp
    adp = 0.0_dp
    !$omp parallel do schedule(static) if(nc >= par_min_loop) default(shared) &
    !$omp private(p0, m, q0, q1) reduction(.or.: bad) reduction(max: ade, adp)
    do b = 1, nb
      p0 = (b - 1)*block + 1
      m = min(int(block, i8), nc - p0 + 1)
      if (b < nb) then       ! the next block's samples, in flight while this one computes
        q0 = 2*(p0 + m) - 1
        q1 = min(2*nc, q0 + 2*block - 1)
        call dsmc_prefetch(q1 - q0 + 1, pidx(q0:q1), c_loc(v(1, 1)), 16_i8)
        call dsmc_prefetch(q1 - q0 + 1, pidx(q0:q1), c_loc(theta(1)), 8_i8)
        call dsmc_prefetch(q1 - q0 + 1, pidx(q0:q1), c_loc(omega(1)), 8_i8)
      end if
      call collide_block(c, pidx(2*p0 - 1:2*(p0 + m - 1)), key, step, &
           numbers_per_pair*nc, 2*nc + 3*(p0 - 1), audit, v, theta, omega, de(p0:p0 + m - 1), &
           bad, ade, adp)
    end do
    !$omp end parallel do
  end subroutine collide_pairs

  !> One block of m <= block pairs: gather, the law, scatter (and the audit); bad, ade, adp
  !> are updated (or, max, max).
  subroutine collide_block(c, idx, key, step, per_step, offset, audit, v, theta, omega, de, &
       bad, ade, adp)
    type(collision_t), intent(in) :: c
    integer(i8), contiguous, intent(in) :: idx(:)
    integer(i8), intent(in) :: key, step, per_step, offset
    logical, intent(in) :: audit
    real(dp), contiguous, intent(inout) :: v(:, :), omega(:)
    real(dp), contiguous, intent(in) :: theta(:)
    real(dp), intent(out) :: de(:)
    logical, intent(inout) :: bad
    real(dp), intent(inout) :: ade, adp
    integer(i8) :: i1(block), i2(block)
    real(dp) :: x1(block), y1(block), w1(block), t1(block), x2(block), y2(block), w2(block), &
         t2(block), u(3*block), e0(block), px(block), py(block), sc(block), q
    integer :: b, m
    m = size(de)
    call uniforms(key, step, per_step, offset, u(1:3*m))
    do b = 1, m
      i1(b) = idx(2*b - 1)
      i2(b) = idx(2*b)
    end do
    do b = 1, m
      x1(b) = v(1, i1(b)); y1(b) = v(2, i1(b)); w1(b) = omega(i1(b)); t1(b) = theta(i1(b))
      x2(b) = v(1, i2(b)); y2(b) = v(2, i2(b)); w2(b) = omega(i2(b)); t2(b) = theta(i2(b))
    end do
    if (audit) then
      e0(1:m) = pair_energy(c, x1(1:m), y1(1:m), w1(1:m), x2(1:m), y2(1:m), w2(1:m))
      px(1:m) = x1(1:m) + x2(1:m)
      py(1:m) = y1(1:m) + y2(1:m)
      sc(1:m) = sqrt(x1(1:m)**2 + y1(1:m)**2) + sqrt(x2(1:m)**2 + y2(1:m)**2)
    end if
    if (c%rotation) then
      call law_rods(c, m, u, t1, t2, x1, y1, w1, x2, y2, w2, de)
    else
      call law_points(c, m, u, x1, y1, x2, y2, de)
    end if
    !$omp simd reduction(.or.: bad)
    do b = 1, m
      q = abs(x1(b)) + abs(y1(b)) + abs(x2(b)) + abs(y2(b))
      bad = bad .or. .not. (q < v_bound)
    end do
    do b = 1, m
      v(1, i1(b)) = x1(b); v(2, i1(b)) = y1(b); omega(i1(b)) = w1(b)
      v(1, i2(b)) = x2(b); v(2, i2(b)) = y2(b); omega(i2(b)) = w2(b)
    end do
    if (audit) then
      ade = max(ade, maxval(abs(pair_energy(c, x1(1:m), y1(1:m), w1(1:m), x2(1:m), y2(1:m), &
           w2(1:m)) - e0(1:m) - de(1:m))/max(e0(1:m), tiny(1.0_dp))))
      adp = max(adp, maxval(sqrt((x1(1:m) + x2(1:m) - px(1:m))**2 + &
           (y1(1:m) + y2(1:m) - py(1:m))**2)/max(sc(1:m), tiny(1.0_dp))))
    end if
  end subroutine collide_block

  !> The rod law (header) on m gathered pairs, branch-free. u(1:m) picks the struck rod (rod 1
  !> if < 1/2), u(m+1:2m) the contact abscissa s = (u - 1/2) L on it, u(2m+1:3m) the striker's
  !> tip sigma = +-L/2. Struck rod k: n = e_perp(theta_k), its arm's moment a_k = s, the
  !> striker's a = sigma cos(theta_1 - theta_2); K = 2/m + (a_1^2 + a_2^2)/I, J = -V.n/K.
  pure subroutine law_rods(c, m, u, t1, t2, x1, y1, w1, x2, y2, w2, de)
    type(collision_t), intent(in) :: c
    integer, intent(in) :: m
    real(dp), intent(in) :: u(:), t1(:), t2(:)
    real(dp), intent(inout) :: x1(:), y1(:), w1(:), x2(:), y2(:), w2(:)
    real(dp), intent(out) :: de(:)
    real(dp) :: c1(block), s1(block), c2(block), s2(block)
    real(dp) :: nx, ny, s, sig, cd, a1, a2, gt, gr, ak, jimp, pv, pw, fv, fw
    logical :: first
    integer :: b
    do b = 1, m       ! one function per loop: GCC fuses cos and sin of one argument into a
      c1(b) = cos(t1(b))      ! scalar sincos call, which has no vector variant
    end do
    do b = 1, m
      s1(b) = sin(t1(b))
    end do
    do b = 1, m
      c2(b) = cos(t2(b))
    end do
    do b = 1, m
      s2(b) = sin(t2(b))
    end do
    fv = 1.0_dp + c%e_v
    fw = 1.0_dp + c%e_w
    do b = 1, m
      first = u(b) < 0.5_dp
      s = (u(m + b) - 0.5_dp)*c%length
      sig = merge(0.5_dp, -0.5_dp, u(2*m + b) < 0.5_dp)*c%length
      cd = c1(b)*c2(b) + s1(b)*s2(b)
      nx = merge(-s1(b), -s2(b), first)
      ny = merge(c1(b), c2(b), first)
      a1 = merge(s, sig*cd, first)
      a2 = merge(sig*cd, s, first)
      gt = (x2(b) - x1(b))*nx + (y2(b) - y1(b))*ny
      gr = w2(b)*a2 - w1(b)*a1
      ak = (a1*a1 + a2*a2)/c%inertia
      jimp = -(gt + gr)/(2.0_dp/c%m + ak)
      pv = fv*jimp/c%m
      pw = fw*jimp/c%inertia
      x1(b) = x1(b) - pv*nx; y1(b) = y1(b) - pv*ny
      x2(b) = x2(b) + pv*nx; y2(b) = y2(b) + pv*ny
      w1(b) = w1(b) - pw*a1
      w2(b) = w2(b) + pw*a2
      de(b) = fv*jimp*gt + fv*fv*jimp*jimp/c%m + fw*jimp*gr + 0.5_dp*fw*fw*jimp*jimp*ak
    end do
  end subroutine law_rods

  !> Point particles: no arms, n = (cos 2 pi u, sin 2 pi u) with u = u(1:m), K = 2/m.
  pure subroutine law_points(c, m, u, x1, y1, x2, y2, de)
    type(collision_t), intent(in) :: c
    integer, intent(in) :: m
    real(dp), intent(in) :: u(:)
    real(dp), intent(inout) :: x1(:), y1(:), x2(:), y2(:)
    real(dp), intent(out) :: de(:)
    real(dp) :: nx(block), ny(block), gt, jimp, pv, fv
    integer :: b
    do b = 1, m
      nx(b) = cos(2.0_dp*pi*u(b))
    end do
    do b = 1, m
      ny(b) = sin(2.0_dp*pi*u(b))
    end do
    fv = 1.0_dp + c%e_v
    do b = 1, m
      gt = (x2(b) - x1(b))*nx(b) + (y2(b) - y1(b))*ny(b)
      jimp = -gt/(2.0_dp/c%m)
      pv = fv*jimp/c%m
      x1(b) = x1(b) - pv*nx(b); y1(b) = y1(b) - pv*ny(b)
      x2(b) = x2(b) + pv*nx(b); y2(b) = y2(b) + pv*ny(b)
      de(b) = fv*jimp*gt + fv*fv*jimp*jimp/c%m
    end do
  end subroutine law_points

  !> Kinetic energy of pairs [m L^2/t0^2].
  elemental function pair_energy(c, x1, y1, w1, x2, y2, w2) result(e)
    type(collision_t), intent(in) :: c
    real(dp), intent(in) :: x1, y1, w1, x2, y2, w2
    real(dp) :: e
    e = 0.5_dp*c%m*(x1*x1 + y1*y1 + x2*x2 + y2*y2)
    if (c%rotation) e = e + 0.5_dp*c%inertia*(w1*w1 + w2*w2)
  end function pair_energy

end module dsmc_collisions
