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
  use parallel, only: par_min_loop
  implicit none
  private

  public :: wall_forces, wall_energy

contains

  !> The law, for a block of m particles and nw walls: f(i, w) is the push
  !> of wall w at distance l(i, w) (slab law: particle at along(i, w) on a
  !> wall of length length(w)). The select is outside the loops, so each law
  !> is one vectorised array expression.
  pure subroutine push_block(law, k, m, l, along, length, f)
    integer, intent(in) :: law, m
    real(dp), intent(in) :: k, l(:, :), along(:, :), length(:)
    real(dp), intent(out) :: f(:, :)
    integer :: w
    select case (law)
    case (wall_experimental)
      f(1:m, :) = k/(l(1:m, :)**3*sqrt(l(1:m, :)))
    case (wall_infinite)
      f(1:m, :) = k/l(1:m, :)**3
    case (wall_slab)
      do w = 1, size(l, 2)
        f(1:m, w) = k/l(1:m, w)**3*(slab_edge(l(1:m, w)/max(along(1:m, w), tiny(1.0_dp))) &
             + slab_edge(l(1:m, w)/max(length(w) - along(1:m, w), tiny(1.0_dp))))
      end do
    case default
      f(1:m, :) = 0
    end select
  end subroutine push_block

  !> Edge factor of the finite slab law (eq. 3.17): g(q) = (3q^2+2)/((3q^2+3) sqrt(q^2+1)).
  pure elemental real(dp) function slab_edge(q) result(g)
    real(dp), intent(in) :: q
    g = (3*q*q + 2)/((3*q*q + 3)*sqrt(q*q + 1))
  end function slab_edge

  !> Add wall forces to fx, fy; return the total force of the particles on
  !> the piston (positive = pushing it up) and the first particle found
  !> outside the cell (or with a non-finite coordinate), 0 if none.
  !> Particles go by blocks of `chunk`: distances to the walls, the law
  !> (push_block), then the sums.
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
    integer, parameter :: chunk = 256
    integer :: i, i0, m, nw, first_bad
    real(dp) :: top, l(chunk, 4), along(chunk, 4), f(chunk, 4), lengths(4)
    real(dp) :: part((n + chunk - 1)/chunk)   !< push on the piston by each block
    top = height
    if (with_piston) top = h
    nw = merge(4, 3, with_piston)   ! left, right, bottom (+ piston)
    lengths = [height, height, width, width]
    first_bad = huge(1)
    !$omp parallel do if (n >= par_min_loop) schedule(static) default(shared) &
    !$omp private(i, i0, m, l, along, f) reduction(min: first_bad)
    do i0 = 1, n, chunk
      m = min(chunk, n - i0 + 1)
      do i = 1, m
        ! written so that NaN fails the test too; the forces of an outside particle
        ! are garbage, but the engine stops on `outside` before using them
        if (.not. (x(i0 + i - 1) > 0 .and. x(i0 + i - 1) < width .and. y(i0 + i - 1) > 0 &
             .and. y(i0 + i - 1) < top)) first_bad = min(first_bad, i0 + i - 1)
      end do
      if (law == 0) then
        part(1 + (i0 - 1)/chunk) = 0
        cycle
      end if
      l(1:m, 1) = x(i0:i0 + m - 1)
      l(1:m, 2) = width - x(i0:i0 + m - 1)
      l(1:m, 3) = y(i0:i0 + m - 1)
      l(1:m, 4) = h - y(i0:i0 + m - 1)
      along(1:m, 1) = y(i0:i0 + m - 1)
      along(1:m, 2) = y(i0:i0 + m - 1)
      along(1:m, 3) = x(i0:i0 + m - 1)
      along(1:m, 4) = x(i0:i0 + m - 1)
      call push_block(law, k, m, l(:, 1:nw), along(:, 1:nw), lengths(1:nw), f(:, 1:nw))
      if (.not. with_piston) f(1:m, 4) = 0
      do i = 1, m
        fx(i0 + i - 1) = fx(i0 + i - 1) + mu(i0 + i - 1)*(f(i, 1) - f(i, 2))
        f(i, 4) = mu(i0 + i - 1)*f(i, 4)
        fy(i0 + i - 1) = fy(i0 + i - 1) + mu(i0 + i - 1)*f(i, 3) - f(i, 4)
      end do
      part(1 + (i0 - 1)/chunk) = sum(f(1:m, 4))
    end do
    !$omp end parallel do
    outside = 0
    if (first_bad /= huge(1)) outside = first_bad
    f_piston = sum(part)   ! fixed blocks summed in order: the same bits for any thread count
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
