!> Diagnostics computed only at their output cadence.
module observables
  use kinds, only: dp, pi
  implicit none
  private

  public :: mean_distance, packing_fraction, kinetic_energy

contains

  !> Mean inter-particle distance D_hat [D1] in the convention of the thesis'
  !> tables: (1/(N(N-1))) sum_{i<j} |r_i - r_j|, i.e. HALF the mean pair
  !> distance. Eq. 2.1 as typeset sums over all ordered pairs i /= j, which is
  !> twice this; Table 3.1's values (D_min = 10.90 D1 at N = 368, 60 D1 wide
  !> cell) are the half. O(N^2): rows on the threads
  !> (from 320 particles, ~5e4 pairs), row sums added in order afterwards, so
  !> the result has the same bits for any thread count.
  function mean_distance(n, x, y) result(d)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    real(dp) :: d, acc, rows(n)
    integer :: i, j
    d = 0
    if (n < 2) return
    !$omp parallel do if (n >= 320) schedule(dynamic, 16) private(i, j, acc)
    do i = 1, n - 1
      acc = 0
      do j = i + 1, n
        acc = acc + sqrt((x(i) - x(j))**2 + (y(i) - y(j))**2)
      end do
      rows(i) = acc
    end do
    !$omp end parallel do
    do i = 1, n - 1
      d = d + rows(i)
    end do
    d = d/(real(n, dp)*real(n - 1, dp))
  end function mean_distance

  !> Packing fraction (eq. 2.2): particle area / (W H).
  pure real(dp) function packing_fraction(area, width, h)
    real(dp), intent(in) :: area, width, h
    packing_fraction = area/(width*h)
  end function packing_fraction

  !> Kinetic energy sum m_i v_i^2/2 [m1 g D1].
  pure real(dp) function kinetic_energy(n, mass, vx, vy)
    integer, intent(in) :: n
    real(dp), intent(in) :: mass(n), vx(n), vy(n)
    kinetic_energy = 0.5_dp*sum(mass*(vx*vx + vy*vy))
  end function kinetic_energy

end module observables
