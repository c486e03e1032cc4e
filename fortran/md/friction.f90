!> Body forces other than magnetism: gravity, viscous drag (thesis eq. 4.4)
!> and regularised Coulomb friction against the glass (eq. 4.5) whose normal
!> force comes from the dipole torques (eqs. 2.15 / 3.2 / 4.11).
!> Serial kernels over the arrays given (the engine runs them per block of particles,
!> on the threads from par_min_loop particles).
module friction
  use kinds, only: dp
  implicit none
  private

  public :: gravity_force, viscous_friction, dry_friction, friction_at_vn

contains

  !> Weight: fy -= G m_i.
  subroutine gravity_force(n, mass, big_g, fy)
    integer, intent(in) :: n
    real(dp), intent(in) :: mass(n), big_g
    real(dp), intent(inout) :: fy(n)
    integer :: i
    do i = 1, n
      fy(i) = fy(i) - big_g*mass(i)
    end do
  end subroutine gravity_force

  !> Viscous drag -gamma m_i v_i (thesis eq. 4.4 with D_i = alpha gamma T/m1).
  subroutine viscous_friction(n, mass, gamma, vx, vy, fx, fy)
    integer, intent(in) :: n
    real(dp), intent(in) :: mass(n), gamma, vx(n), vy(n)
    real(dp), intent(inout) :: fx(n), fy(n)
    fx = fx - gamma*mass*vx
    fy = fy - gamma*mass*vy
  end subroutine viscous_friction

  !> Regularised Coulomb friction. On entry fx, fy hold F_T = F_M + F_g
  !> (eq. 4.6). Static: |F_T| <= mu_s N and |v| < v_t -> the particle holds
  !> (friction = -F_T). Dynamic: -mu_d N v/(|v| + v_t).
  !> N_i = nfac_i * s3_i, with s3_i = sum_j mu_j sin(theta_j) r_ij^-3.
  subroutine dry_friction(n, nfac, s3, mu_s, mu_d, v_t, vx, vy, fx, fy)
    integer, intent(in) :: n
    real(dp), intent(in) :: nfac(n), s3(n), mu_s, mu_d, v_t, vx(n), vy(n)
    real(dp), intent(inout) :: fx(n), fy(n)
    integer :: i
    real(dp) :: fn, fs, ft2, v, c, hold
    ! branch-free (the hold test as a 0/1 factor): the loop vectorises (also in a generic
    ! SSE2 build: written so, GCC does not branch). |F_T| <= mu_s N is tested on squares,
    ! |F_T|^2 <= mu_s N |mu_s N| (false for mu_s N < 0, as before): one square root per
    ! particle, |v|, which the dynamic law needs anyway
    do i = 1, n
      fn = nfac(i)*s3(i)
      fs = mu_s*fn
      ft2 = fx(i)**2 + fy(i)**2
      v = sqrt(vx(i)**2 + vy(i)**2)
      hold = merge(0.0_dp, 1.0_dp, ft2 <= fs*abs(fs) .and. v < v_t)
      c = mu_d*fn/(v + v_t)
      fx(i) = hold*(fx(i) - c*vx(i))
      fy(i) = hold*(fy(i) - c*vy(i))
    end do
  end subroutine dry_friction

  !> Both frictions at the velocity v_n the Verlet scheme itself reports at this step
  !> (&integration friction_velocity = 'implicit'), instead of the lagged estimate. On entry
  !> vx, vy hold u = v_{n-1/2} and fx, fy hold F_T (every other force at step n).
  !> Stick (dry friction, static law at the velocity level): when a friction force within
  !> mu_s N can stop the particle over this step, |F_T + m u/h| <= mu_s N, it does: the total
  !> force is -m u/h, so v_{n+1/2} = 0 (a particle at rest, u = 0, holds while |F_T| <= mu_s N,
  !> the thesis' static rule). Slip: v_n = u + (h/2m)(F_T + F_f(v_n)) with
  !> F_f(v) = -mu_d N v/(|v| + v_t) - gamma m v, solved in closed form: v_n is parallel to
  !> w = u + (h/2m) F_T and |v_n| = x is the positive root of
  !> b x^2 + (b v_t + a - |w|) x - |w| v_t = 0 (a = h mu_d N/(2m), b = 1 + h gamma/2), taken
  !> in its cancellation-free form. The lagged estimate instead lets a slowly sliding particle's
  !> friction flip sign from step to step, by an amount that grows with h. On exit vx, vy hold
  !> v_n and fx, fy the total force. dry: dry friction on; gamma = 0: no viscous drag.
  subroutine friction_at_vn(n, mass, nfac, s3, dry, mu_s, mu_d, v_t, gamma, h, vx, vy, fx, fy)
    integer, intent(in) :: n
    real(dp), intent(in) :: mass(n), nfac(n), s3(n), mu_s, mu_d, v_t, gamma, h
    logical, intent(in) :: dry
    real(dp), intent(inout) :: vx(n), vy(n), fx(n), fy(n)
    integer :: i
    real(dp) :: fn, wx, wy, w, a, b, ib, bb, c, q, vn, d, half, on, stopx, stopy, stick, rh
    on = merge(1.0_dp, 0.0_dp, dry)
    b = 1.0_dp + 0.5_dp*h*gamma
    ib = 1.0_dp/b
    rh = 1.0_dp/h
    ! branch-free (the loop vectorises, given -fno-trapping-math: meson.build): the positive
    ! root of b x^2 + bb x - c = 0 is
    ! max(q/b, -c/q) with q = -(bb + sign(r, bb))/2, r = sqrt(bb^2 + 4 b c): the form without
    ! cancellation for either sign of bb (the other expression is the negative root)
    do i = 1, n
      half = 0.5_dp*h/mass(i)
      fn = on*nfac(i)*s3(i)
      stopx = -mass(i)*vx(i)*rh                ! the total force that stops it: v_{n+1/2} = 0
      stopy = -mass(i)*vy(i)*rh
      stick = on*merge(1.0_dp, 0.0_dp, (fx(i) - stopx)**2 + (fy(i) - stopy)**2 <= mu_s*fn*abs(mu_s*fn))
      wx = vx(i) + half*fx(i)
      wy = vy(i) + half*fy(i)
      w = sqrt(wx**2 + wy**2)
      a = half*mu_d*fn
      bb = b*v_t + a - w
      c = w*v_t
      q = -0.5_dp*(bb + sign(sqrt(bb*bb + 4.0_dp*b*c), bb))
      vn = max(q*ib, -c/(q - tiny(1.0_dp)))     ! slip: |v_n|
      w = max(w, 1.0e-280_dp)                   ! w = 0 gives v_n = 0 (v_t >= 1e-15: d finite)
      d = 1.0_dp/(w*(vn + v_t))
      q = vn*(vn + v_t)*d                       ! v_n = q w_vec
      c = mu_d*fn*w*d + gamma*mass(i)           ! F_f = -c v_n
      fx(i) = stick*stopx + (1 - stick)*(fx(i) - c*q*wx)
      fy(i) = stick*stopy + (1 - stick)*(fy(i) - c*q*wy)
      vx(i) = stick*0.5_dp*vx(i) + (1 - stick)*q*wx
      vy(i) = stick*0.5_dp*vy(i) + (1 - stick)*q*wy
    end do
  end subroutine friction_at_vn

end module friction
