!> Dipole-dipole repulsion between magnets with moments normal to the plane
!> (thesis eq. 2.7 / 4.3): F_ij = k_pair mu_i mu_j r_ij^-4 r_hat (k_pair = 3F/4).
!> One kernel; every neighbour strategy calls it. The same pass accumulates
!> the r^-3 sums that the dry-friction normal force needs (eq. 4.11).
module pair_forces
  use kinds, only: dp
  implicit none
  private

  public :: dipole_kernel, pair_forces_all, pair_energy_all

contains

  !> Kernel for one pair separated by (dx, dy) = r_i - r_j [D1]:
  !> s5 = r^-5 (so the force on i is k mu_i mu_j s5 (dx, dy)) and s3 = r^-3.
  !> No non-integer powers: one sqrt, one division.
  pure subroutine dipole_kernel(dx, dy, s5, s3)
    real(dp), intent(in) :: dx, dy
    real(dp), intent(out) :: s5, s3
    real(dp) :: r2inv, rinv
    r2inv = 1.0_dp/(dx*dx + dy*dy)
    rinv = sqrt(r2inv)
    s3 = r2inv*rinv
    s5 = s3*r2inv
  end subroutine dipole_kernel

  !> O(N^2) reference: every pair once, Newton's third law applied exactly.
  !> Adds to fx, fy (n) [m1 g]; if with_r3, adds to s3 (n).
  subroutine pair_forces_all(n, x, y, mu, wsin, k_pair, with_r3, fx, fy, s3)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)       !< positions [D1]
    real(dp), intent(in) :: mu(n)            !< relative moments mu_i/mu1
    real(dp), intent(in) :: wsin(n)          !< mu_i sin(theta_i), friction weights
    real(dp), intent(in) :: k_pair           !< (3/4) F
    logical, intent(in) :: with_r3           !< accumulate friction sums
    real(dp), intent(inout) :: fx(n), fy(n)  !< forces [m1 g]
    real(dp), intent(inout) :: s3(n)         !< sum_j wsin_j r_ij^-3
    integer :: i, j
    real(dp) :: xi, yi, ci, dx, dy, s5, r3, c, fxi, fyi, s3i, wi

    do i = 1, n - 1
      xi = x(i); yi = y(i)
      ci = k_pair*mu(i)
      wi = wsin(i)
      fxi = 0; fyi = 0; s3i = 0
      do j = i + 1, n
        dx = xi - x(j)
        dy = yi - y(j)
        call dipole_kernel(dx, dy, s5, r3)
        c = ci*mu(j)*s5
        fxi = fxi + c*dx
        fyi = fyi + c*dy
        fx(j) = fx(j) - c*dx
        fy(j) = fy(j) - c*dy
        if (with_r3) then
          s3i = s3i + wsin(j)*r3
          s3(j) = s3(j) + wi*r3
        end if
      end do
      fx(i) = fx(i) + fxi
      fy(i) = fy(i) + fyi
      if (with_r3) s3(i) = s3(i) + s3i
    end do
  end subroutine pair_forces_all

  !> Pair potential energy sum_{i<j} (k_pair/3) mu_i mu_j r^-3 [m1 g D1].
  function pair_energy_all(n, x, y, mu, k_pair) result(e)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), mu(n), k_pair
    real(dp) :: e, s5, r3
    integer :: i, j
    e = 0
    do i = 1, n - 1
      do j = i + 1, n
        call dipole_kernel(x(i) - x(j), y(i) - y(j), s5, r3)
        e = e + mu(i)*mu(j)*r3
      end do
    end do
    e = e*k_pair/3.0_dp
  end function pair_energy_all

end module pair_forces
