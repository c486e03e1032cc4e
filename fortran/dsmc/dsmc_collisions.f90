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
!> J n and J (r x n), both even in n (J is odd), so the sign of n is free;
!> it is chosen so that V.n <= 0 (the contact approaches, J >= 0).
!>
!> Checks (tests/test_rods_collisions.py, via the engine's collision audit):
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
module dsmc_collisions
  use kinds, only: dp, i8, pi
  implicit none
  private

  public :: collision_t, pair_count, draw_pairs, rod_geometry, point_geometry, collide, &
       pair_energy, energy_change

  !> Parameters of the collision law.
  type :: collision_t
    real(dp) :: m = 1.0_dp          !< mass [m]
    real(dp) :: inertia = 1.0_dp    !< moment of inertia about the centre [m L^2]
    real(dp) :: length = 1.0_dp     !< rod length [L]
    real(dp) :: e_v = 1.0_dp        !< translational restitution [1]
    real(dp) :: e_w = 1.0_dp        !< rotational restitution [1]
    logical :: rotation = .true.    !< rods (.true.) or point particles
  end type collision_t

contains

  !> Babovsky's pair count per step, floor(N dt / (2 tau)) (dt <= tau: at most N/2).
  pure function pair_count(n, dt, tau) result(nc)
    integer(i8), intent(in) :: n
    real(dp), intent(in) :: dt, tau
    integer(i8) :: nc
    nc = min(int(real(n, dp)*dt/(2.0_dp*tau), i8), n/2)
  end function pair_count

  !> 2 nc distinct indices of 1..N without replacement: the first 2 nc entries
  !> of `perm` after a partial Fisher-Yates shuffle driven by the uniforms u(1:2nc).
  !> `perm` stays a permutation of 1..N (it is part of the checkpointed state).
  pure subroutine draw_pairs(perm, u, nc)
    integer(i8), intent(inout) :: perm(:)
    real(dp), intent(in) :: u(:)
    integer(i8), intent(in) :: nc
    integer(i8) :: k, j, n, tmp
    n = size(perm, kind=i8)
    do k = 1, 2*nc
      j = k + min(int(u(k)*real(n - k + 1, dp), i8), n - k)
      tmp = perm(k); perm(k) = perm(j); perm(j) = tmp
    end do
  end subroutine draw_pairs

  !> Impact parameters of a rod-rod contact from three uniforms (see header):
  !> arms r1, r2 [L] and the (unoriented) normal n of the struck rod.
  pure subroutine rod_geometry(th1, th2, length, u, r1, r2, n)
    real(dp), intent(in) :: th1, th2, length, u(3)
    real(dp), intent(out) :: r1(2), r2(2), n(2)
    real(dp) :: s, sig, e1(2), e2(2)
    e1 = [cos(th1), sin(th1)]
    e2 = [cos(th2), sin(th2)]
    s = (u(2) - 0.5_dp)*length
    sig = merge(0.5_dp, -0.5_dp, u(3) < 0.5_dp)*length
    if (u(1) < 0.5_dp) then        ! rod 1 struck on its side by a tip of rod 2
      n = [-e1(2), e1(1)]
      r1 = s*e1
      r2 = sig*e2
    else                           ! rod 2 struck by a tip of rod 1
      n = [-e2(2), e2(1)]
      r2 = s*e2
      r1 = sig*e1
    end if
  end subroutine rod_geometry

  !> Point particles: no arms, normal uniform on the circle.
  pure subroutine point_geometry(u, r1, r2, n)
    real(dp), intent(in) :: u
    real(dp), intent(out) :: r1(2), r2(2), n(2)
    r1 = 0.0_dp
    r2 = 0.0_dp
    n = [cos(2.0_dp*pi*u), sin(2.0_dp*pi*u)]
  end subroutine point_geometry

  !> The collision law on one pair; jimp = J >= 0 [m L/tau] (n oriented so that V.n <= 0),
  !> gt, gr = the translational and rotational parts of V.n before the collision.
  pure subroutine collide(c, v1, w1, v2, w2, r1, r2, n_in, jimp, gt, gr, kk)
    type(collision_t), intent(in) :: c
    real(dp), intent(inout) :: v1(2), w1, v2(2), w2
    real(dp), intent(in) :: r1(2), r2(2), n_in(2)
    real(dp), intent(out) :: jimp, gt, gr, kk
    real(dp) :: n(2), a1, a2, pv, pw
    n = n_in
    a1 = r1(1)*n(2) - r1(2)*n(1)
    a2 = r2(1)*n(2) - r2(2)*n(1)
    gt = (v2(1) - v1(1))*n(1) + (v2(2) - v1(2))*n(2)
    gr = 0.0_dp
    kk = 2.0_dp/c%m
    if (c%rotation) then
      gr = w2*a2 - w1*a1
      kk = kk + (a1*a1 + a2*a2)/c%inertia
    end if
    if (gt + gr > 0.0_dp) then     ! orient n for approach (the law is even in n)
      n = -n; a1 = -a1; a2 = -a2; gt = -gt; gr = -gr
    end if
    jimp = -(gt + gr)/kk
    pv = (1.0_dp + c%e_v)*jimp/c%m
    v1 = v1 - pv*n
    v2 = v2 + pv*n
    if (c%rotation) then
      pw = (1.0_dp + c%e_w)*jimp/c%inertia
      w1 = w1 - pw*a1
      w2 = w2 + pw*a2
    end if
  end subroutine collide

  !> Kinetic energy of a pair [m L^2/tau^2].
  pure function pair_energy(c, v1, w1, v2, w2) result(e)
    type(collision_t), intent(in) :: c
    real(dp), intent(in) :: v1(2), w1, v2(2), w2
    real(dp) :: e
    e = 0.5_dp*c%m*(sum(v1**2) + sum(v2**2))
    if (c%rotation) e = e + 0.5_dp*c%inertia*(w1*w1 + w2*w2)
  end function pair_energy

  !> The energy change of a collision from its pre-collision J, g_t, g_r, K
  !> (header): dE = (1+e_v) J g_t + (1+e_v)^2 J^2/m + (1+e_w) J g_r + (1+e_w)^2 J^2 A/2.
  pure function energy_change(c, jimp, gt, gr, kk) result(de)
    type(collision_t), intent(in) :: c
    real(dp), intent(in) :: jimp, gt, gr, kk
    real(dp) :: de, a
    a = kk - 2.0_dp/c%m
    de = (1.0_dp + c%e_v)*jimp*gt + (1.0_dp + c%e_v)**2*jimp**2/c%m
    if (c%rotation) de = de + (1.0_dp + c%e_w)*jimp*gr + 0.5_dp*(1.0_dp + c%e_w)**2*jimp**2*a
  end function energy_change

end module dsmc_collisions
