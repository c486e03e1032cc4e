!> Magnetic repulsion of the cell walls and the piston on every particle
!> (computed exactly, never truncated). Laws, per unit relative moment mu_i:
!>   experimental (eq. 2.8):  k w^-3.5,  k = F/2
!>   infinite wall (eq. 3.3): k w^-3,    k = F
!>   finite slab (eq. 3.17):  k l^-3 [g(A) + g(B)], k = 3F/4,
!>       g(a) = (3a^2+2)/((3a^2+3) sqrt(a^2+1)), A = l/(fL), B = l/((1-f)L)
!> Walls: left x = 0, right x = W, bottom y = 0 (length W), piston y = H
!> (length W); side walls have the cell height as length.
module walls
  use kinds, only: dp
  use model, only: wall_experimental, wall_infinite, wall_slab
  implicit none
  private

  public :: wall_forces, wall_push, wall_energy

  integer, parameter :: par_min = 4000    !< particles below which O(N) loops stay serial

contains

  !> Magnitude of the push of one wall at distance l, for a particle at
  !> `along` on a wall of length `length` (slab law only uses those two).
  pure function wall_push(law, k, l, along, length) result(f)
    integer, intent(in) :: law
    real(dp), intent(in) :: k, l, along, length
    real(dp) :: f, l3, a, b
    l3 = l*l*l
    select case (law)
    case (wall_experimental)
      f = k/(l3*sqrt(l))
    case (wall_infinite)
      f = k/l3
    case (wall_slab)
      a = l/max(along, tiny(1.0_dp))
      b = l/max(length - along, tiny(1.0_dp))
      f = k/l3*(g(a) + g(b))
    case default
      f = 0
    end select
  contains
    pure real(dp) function g(q)
      real(dp), intent(in) :: q
      g = (3*q*q + 2)/((3*q*q + 3)*sqrt(q*q + 1))
    end function g
  end function wall_push

  !> Add wall forces to fx, fy; return the total force of the particles on
  !> the piston (positive = pushing it up) and the first particle found
  !> outside the cell (or with a non-finite coordinate), 0 if none.
  subroutine wall_forces(n, x, y, mu, law, k, width, height, h, with_piston, &
       fx, fy, f_piston, outside)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), mu(n)
    integer, intent(in) :: law
    real(dp), intent(in) :: k, width, height   !< law prefactor, cell size [D1]
    real(dp), intent(in) :: h                  !< piston height [D1]
    logical, intent(in) :: with_piston
    real(dp), intent(inout) :: fx(n), fy(n)
    real(dp), intent(out) :: f_piston
    integer, intent(out) :: outside
    integer :: i, first_bad
    real(dp) :: top, xi, yi
    real(dp), allocatable :: fp(:)   !< push of the piston on each particle
    allocate(fp(n))
    top = height
    if (with_piston) top = h
    first_bad = huge(1)
    !$omp parallel do if (n >= par_min) schedule(static) default(shared) private(i, xi, yi) &
    !$omp reduction(min: first_bad)
    do i = 1, n
      xi = x(i); yi = y(i)
      fp(i) = 0
      ! written so that NaN fails the test too
      if (.not. (xi > 0 .and. xi < width .and. yi > 0 .and. yi < top)) then
        first_bad = min(first_bad, i)
        cycle
      end if
      if (law /= 0) then
        fx(i) = fx(i) + mu(i)*(wall_push(law, k, xi, yi, height) &
             - wall_push(law, k, width - xi, yi, height))
        fy(i) = fy(i) + mu(i)*wall_push(law, k, yi, xi, width)
        if (with_piston) then
          fp(i) = mu(i)*wall_push(law, k, h - yi, xi, width)
          fy(i) = fy(i) - fp(i)
        end if
      end if
    end do
    !$omp end parallel do
    outside = 0
    if (first_bad /= huge(1)) outside = first_bad
    f_piston = sum(fp)   ! serial sum: the same bits for any thread count
  end subroutine wall_forces

  !> Wall potential energy [m1 g D1] for the laws that have one
  !> (experimental: k w^-2.5/2.5, infinite: k w^-2/2).
  function wall_energy(n, x, y, mu, law, k, width, h, with_piston) result(e)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), mu(n), k, width, h
    integer, intent(in) :: law
    logical, intent(in) :: with_piston
    real(dp) :: e
    integer :: i
    e = 0
    do i = 1, n
      e = e + mu(i)*(u(x(i)) + u(width - x(i)) + u(y(i)))
      if (with_piston) e = e + mu(i)*u(h - y(i))
    end do
  contains
    pure real(dp) function u(w)
      real(dp), intent(in) :: w
      select case (law)
      case (wall_experimental); u = k/(2.5_dp*w*w*sqrt(w))
      case (wall_infinite);     u = k/(2.0_dp*w*w)
      case default;             u = 0
      end select
    end function u
  end function wall_energy

end module walls
