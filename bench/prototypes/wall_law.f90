!> Prototype, not part of the engine (bench/RESULTS.md 44.2): the bed's wall pass (module walls,
!> wall_block: the experimental law k w^-3.5 on four walls, blocks of wall_chunk particles)
!> against the same block with the law's arithmetic in single precision (one single square root
!> and division per wall from the double distance; the sums double), on N particles spread
!> uniformly over the grid's square cell (509.2 D1, piston on top). Prints ns per particle and
!> pass for each, the single form's largest relative error against the engine's forces, and
!> whether the engine's form is the same bits when called twice (a sanity check of the harness).
!> Built against an engine build's static library (its module files):
!>   B=/tmp/bld   # meson setup $B . -Dnative=true && ninja -C $B partsim
!>   gfortran -O3 -march=native -fno-trapping-math -I$B/libpsengine.a.p -J /tmp \
!>       bench/prototypes/wall_law.f90 $B/libpsengine.a -fopenmp -o /tmp/wl
!>   /tmp/wl 100000 300     # N, passes
module wl
  use kinds, only: dp
  use walls, only: wall_chunk
  implicit none
  integer, parameter :: sp = kind(1.0e0)
contains
  !> wall_block's experimental case with the law in single precision (no outside check: the
  !> harness places every particle inside).
  subroutine wall_block_sp(m, x, y, mu, k, width, h, fx, fy, f_piston)
    integer, intent(in) :: m
    real(dp), intent(in) :: x(m), y(m), mu(m), k, width, h
    real(dp), intent(inout) :: fx(m), fy(m)
    real(dp), intent(out) :: f_piston
    real(dp) :: l(wall_chunk, 4), f(wall_chunk, 4)
    real(sp) :: a
    integer :: i, w
    l(1:m, 1) = x
    l(1:m, 2) = width - x
    l(1:m, 3) = y
    l(1:m, 4) = h - y
    do w = 1, 4
      do i = 1, m
        a = real(l(i, w), sp)
        f(i, w) = k*real(1.0_sp/(a*a*a*sqrt(a)), dp)
      end do
    end do
    do i = 1, m
      fx(i) = fx(i) + mu(i)*(f(i, 1) - f(i, 2))
      f(i, 4) = mu(i)*f(i, 4)
      fy(i) = fy(i) + mu(i)*f(i, 3) - f(i, 4)
    end do
    f_piston = sum(f(1:m, 4))
  end subroutine wall_block_sp
end module wl

program wall_law
  use kinds, only: dp
  use model, only: wall_experimental
  use walls, only: wall_block, wall_chunk
  use wl, only: wall_block_sp, sp
  implicit none
  integer :: n, passes, v, r, b, lo, hi, out, nb, i
  character(len=32) :: arg
  real(dp), allocatable :: x(:), y(:), mu(:), fx(:), fy(:)
  real(dp) :: width, fp, t0, t1, err, w
  real(sp) :: a
  call get_command_argument(1, arg); read(arg, *) n
  call get_command_argument(2, arg); read(arg, *) passes
  allocate(x(n), y(n), mu(n), fx(n), fy(n))
  call random_number(x); call random_number(y)
  width = 509.2_dp
  x = 0.5_dp + x*(width - 1); y = 0.5_dp + y*(width - 1); mu = 1
  nb = (n + wall_chunk - 1)/wall_chunk
  do v = 1, 3      ! 1, 3: the engine's block (timed before and after the single form), 2: single
    fx = 0; fy = 0
    call cpu_time(t0)
    do r = 1, passes
      do b = 1, nb
        lo = 1 + (b - 1)*wall_chunk; hi = min(n, b*wall_chunk)
        if (v == 2) then
          call wall_block_sp(hi - lo + 1, x(lo:hi), y(lo:hi), mu(lo:hi), 0.5_dp, width, width, &
               fx(lo:hi), fy(lo:hi), fp)
        else
          call wall_block(hi - lo + 1, x(lo:hi), y(lo:hi), mu(lo:hi), wall_experimental, &
               0.5_dp, width, width, width, .true., fx(lo:hi), fy(lo:hi), fp, out)
        end if
      end do
    end do
    call cpu_time(t1)
    print '(a, a, f8.3, es12.4)', merge('engine (exact)   ', 'single precision ', v /= 2), &
         ' ns per particle and pass:', (t1 - t0)/passes/n*1e9, sum(fx) + sum(fy)
  end do
  err = 0      ! the single law against the double one, w uniform in log over [0.5, width]
  do i = 0, 100000
    w = 0.5_dp*(2*width)**(real(i, dp)/100000)
    a = real(w, sp)
    err = max(err, abs(real(1.0_sp/(a*a*a*sqrt(a)), dp)*(w*w*w*sqrt(w)) - 1))
  end do
  print '(a, es10.3)', 'single law: largest relative error over w in [0.5, 509.2] D1: ', err
end program wall_law
