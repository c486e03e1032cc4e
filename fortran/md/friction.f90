!> Body forces other than magnetism: gravity, viscous drag (thesis eq. 4.4)
!> and regularised Coulomb friction against the glass (eq. 4.5) whose normal
!> force comes from the dipole torques (eqs. 2.15 / 3.2 / 4.11).
!> Serial kernels over the arrays given (the engine runs them per block of particles,
!> on the threads from par_min_loop particles).
module friction
  use kinds, only: dp
  implicit none
  private

  public :: gravity_force, viscous_friction, dry_friction

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

end module friction
