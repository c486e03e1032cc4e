!> Magnetic repulsion of the cell walls and the piston on every particle
!> (computed exactly, never truncated). Laws, per unit relative moment mu_i:
!>   experimental (eq. 2.8):  k w^-3.5,  k = F/2
!>   infinite wall (eq. 3.3): k w^-3,    k = F
!>   finite slab (eq. 3.17):  k l^-3 [g(A) + g(B)], k = 3F/4,
!>       g(a) = (3a^2+2)/((3a^2+3) sqrt(a^2+1)), A = l/(fL), B = l/((1-f)L)
!> Walls: left x = 0, right x = W, bottom y = 0 (length W), piston y = H
!> (length W); side walls have the cell height as length.
module walls
  use kinds, only: dp, i8
  use model, only: wall_experimental, wall_infinite, wall_slab
  implicit none
  private

  public :: wall_block, wall_energy, wall_chunk

  integer, parameter :: wall_chunk = 256   !< largest block of wall_block

contains

  !> The law, for a block of m particles and nw walls: f(i, w) is the push
  !> of wall w at distance l(i, w) (slab law: particle at along(i, w) on a
  !> wall of length length(w)). The select is outside the loops, so each law
  !> is one vectorised array expression.
  pure subroutine push_block(law, k, m, l, along, length, f)
    integer, intent(in) :: law, m
    real(dp), intent(in), contiguous :: l(:, :), along(:, :)
    real(dp), intent(in) :: k, length(:)
    real(dp), intent(out), contiguous :: f(:, :)
    integer :: w, i
    real(dp) :: q, r1, r2, t3, t4
    select case (law)
    case (wall_experimental)
      ! k w^-3.5, four walls (wall_block passes the piston column always). The side walls
      ! (1, 2) as k r^3 sqrt(r), r = 1/w, the facing pair sharing one division (1/w1 =
      ! w2/(w1 w2)); bottom and piston (3, 4) as k t^7, t = inv_sqrt(w): multiplies and adds
      ! only. In one loop the square-root/division unit and the FMA units work side by side.
      ! The law alone (micro-benchmark): 1.95x faster than all four walls through sqrt (4 sqrt
      ! + 2 divisions) with -march=native, as fast in a generic SSE2 build, where all four
      ! through inv_sqrt are 1.5x slower; in the step, all four through inv_sqrt would be 2 %
      ! faster natively and 2.6 % slower generic (bench/RESULTS.md section 24)
      do i = 1, m
        q = 1.0_dp/(l(i, 1)*l(i, 2))
        r1 = l(i, 2)*q
        r2 = l(i, 1)*q
        f(i, 1) = k*(r1*r1*r1)*sqrt(r1)
        f(i, 2) = k*(r2*r2*r2)*sqrt(r2)
        t3 = inv_sqrt(l(i, 3))
        t4 = inv_sqrt(l(i, 4))
        f(i, 3) = k*t3*(t3*t3)**3
        f(i, 4) = k*t4*(t4*t4)**3
      end do
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

  !> w^-1/2 for a positive normal w, to round-off: a 5-bit first guess from the bits of w (the
  !> exponent halved and negated), then 4 Newton steps t <- t (3/2 - (w/2) t^2), each squaring
  !> the relative error (3.4e-2, 1.8e-3, 4.6e-6, 3.2e-11, round-off). Measured against quad
  !> precision on 2e6 random w in 1e-2 .. 2e2: 2.7e-16 (the law k t^7: 2.3e-15, the former
  !> k r^3 sqrt(r) with r = 1/w: 1.2e-15; the two differ by <= 2.9e-15; bench/RESULTS.md
  !> section 24). Multiplies and adds only: it vectorises at the FMA rate (a vector square
  !> root or division takes ~10 cycles per 4 lanes here). Garbage for w <= 0 or NaN (the
  !> engine stops on a particle outside the cell before using its wall force).
  pure elemental real(dp) function inv_sqrt(w) result(t)
    real(dp), intent(in) :: w
    integer(i8), parameter :: magic = int(z'5FE6EB50C7B537A9', i8)
    real(dp) :: hw
    integer :: k
    hw = 0.5_dp*w
    t = transfer(magic - shiftr(transfer(w, 1_i8), 1), 1.0_dp)
    do k = 1, 4
      t = t*(1.5_dp - hw*t*t)
    end do
  end function inv_sqrt

  !> Edge factor of the finite slab law (eq. 3.17): g(q) = (3q^2+2)/((3q^2+3) sqrt(q^2+1)).
  pure elemental real(dp) function slab_edge(q) result(g)
    real(dp), intent(in) :: q
    g = (3*q*q + 2)/((3*q*q + 3)*sqrt(q*q + 1))
  end function slab_edge

  !> Add wall forces to fx, fy of a block of m <= wall_chunk particles; return the block's
  !> force on the piston (positive = pushing it up) and the first particle of the block found
  !> outside the cell (or with a non-finite coordinate), 0 if none. Distances to the walls,
  !> the law (push_block), then the sums. Serial: the engine runs the blocks on the threads
  !> and sums the blocks' piston forces in block order (the same bits for any thread count).
  subroutine wall_block(m, x, y, mu, law, k, width, height, h, with_piston, fx, fy, &
       f_piston, outside)
    integer, intent(in) :: m
    real(dp), intent(in) :: x(m), y(m), mu(m)
    integer, intent(in) :: law
    real(dp), intent(in) :: k, width, height   !< law prefactor, cell size [D1]
    real(dp), intent(in) :: h                  !< piston height [D1]
    logical, intent(in) :: with_piston
    real(dp), intent(inout) :: fx(m), fy(m)
    real(dp), intent(out) :: f_piston
    integer, intent(out) :: outside
    integer :: i, nw
    real(dp) :: out, top, l(wall_chunk, 4), along(wall_chunk, 4), f(wall_chunk, 4), lengths(4)
    top = height
    if (with_piston) top = h
    nw = merge(4, 3, with_piston)   ! left, right, bottom (+ piston)
    lengths = [height, height, width, width]
    ! written so that NaN fails the test too; the forces of an outside particle are garbage,
    ! but the engine stops on `outside` before using them. Flagged first (a loop that
    ! vectorises), the first such particle searched only when there is one.
    out = 0
    do i = 1, m       ! 1 if any test fails (no .and., no integers: GCC would branch or not vectorise)
      out = max(out, merge(0.0_dp, 1.0_dp, x(i) > 0), merge(0.0_dp, 1.0_dp, x(i) < width), &
           merge(0.0_dp, 1.0_dp, y(i) > 0), merge(0.0_dp, 1.0_dp, y(i) < top))
    end do
    outside = 0
    if (out > 0) then
      do i = m, 1, -1
        if (.not. (x(i) > 0 .and. x(i) < width .and. y(i) > 0 .and. y(i) < top)) outside = i
      end do
    end if
    f_piston = 0
    if (law == 0) return
    l(1:m, 1) = x
    l(1:m, 2) = width - x
    l(1:m, 3) = y
    l(1:m, 4) = h - y
    if (.not. with_piston) l(1:m, 4) = 1   ! a finite dummy for the experimental loop
    if (law == wall_slab) then     ! the positions along the walls: the slab law only
      along(1:m, 1) = y
      along(1:m, 2) = y
      along(1:m, 3) = x
      along(1:m, 4) = x
    end if
    if (law == wall_experimental) nw = 4    ! its loop takes the piston column (zeroed below)
    call push_block(law, k, m, l(:, 1:nw), along(:, 1:nw), lengths(1:nw), f(:, 1:nw))
    if (.not. with_piston) f(1:m, 4) = 0
    do i = 1, m
      fx(i) = fx(i) + mu(i)*(f(i, 1) - f(i, 2))
      f(i, 4) = mu(i)*f(i, 4)
      fy(i) = fy(i) + mu(i)*f(i, 3) - f(i, 4)
    end do
    f_piston = lane_sum(m, f(:, 4))
  end subroutine wall_block

  !> sum(a(1:m)) in a fixed order that vectorises (Fortran's sum adds in sequence: a chain of
  !> m dependent additions): 8 partial sums (element i to lane mod(i - 1, 8)), then the
  !> lanes pairwise. The order depends on m only: the same bits for any thread count.
  pure real(dp) function lane_sum(m, a) result(s)
    integer, intent(in) :: m
    real(dp), intent(in) :: a(:)
    real(dp) :: p(8)
    integer :: i, m8
    p = 0
    m8 = m - mod(m, 8)
    do i = 1, m8, 8
      p = p + a(i:i + 7)
    end do
    do i = m8 + 1, m
      p(i - m8) = p(i - m8) + a(i)
    end do
    s = ((p(1) + p(2)) + (p(3) + p(4))) + ((p(5) + p(6)) + (p(7) + p(8)))
  end function lane_sum

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
