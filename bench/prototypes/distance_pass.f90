!> Prototype, not part of the engine (bench/RESULTS.md 42.2): rows_kept's first pass alone over
!> the pruned list of the grid's lattice (N 1e5, r_c 3, skin 1, prune 0.25), in seven forms:
!> 1 the compressing loop (js, r2 stored at the next free slot), 2 r^2 stored by position,
!> 3 the same vectorised (gathers), 4 by position then a compressing loop, 5 a branch per pair,
!> 6 by position plus a compressed index (GCC drops that store: never read), 7 as 6 then a
!> gather of the kept pairs, 8 j and i compressed (prune_rows), 9 only the index compressed.
!> Built against an engine build's static library (its module files):
!>   B=/tmp/bld   # meson setup $B . -Dnative=true && ninja -C $B partsim
!>   gfortran -O3 -march=native -fno-trapping-math -I$B/libpsengine.a.p \
!>       bench/prototypes/distance_pass.f90 $B/libpsengine.a -fopenmp -o /tmp/dp
!>   OMP_NUM_THREADS=1 /tmp/dp 100000 3 300     # N, r_c, passes: ns per pruned pair
module mic
  use kinds, only: dp
  implicit none
contains
  subroutine dist_flat(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j
    real(dp) :: dx, dy, r2
    nc = 0
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      r2 = dx*dx + dy*dy
      low = min(low, r2)
      js(nc + 1) = j
      r2s(nc + 1) = r2
      nc = nc + merge(1, 0, r2 < rk)
    end do
  end subroutine
  subroutine dist_nocomp(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j
    real(dp) :: dx, dy, r2
    nc = nk
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      r2 = dx*dx + dy*dy
      low = min(low, r2)
      r2s(k) = r2
    end do
  end subroutine
  subroutine dist_vec(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k
    nc = nk
    do k = 1, nk
      r2s(k) = (x(own(k)) - x(nbr(k)))**2 + (y(own(k)) - y(nbr(k)))**2
    end do
    low = min(low, minval(r2s(1:nk)))
  end subroutine
  subroutine dist_two(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j
    real(dp) :: dx, dy, r2, t(256)
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      t(k) = dx*dx + dy*dy
      low = min(low, t(k))
    end do
    nc = 0
    do k = 1, nk
      js(nc + 1) = nbr(k)
      r2s(nc + 1) = t(k)
      nc = nc + merge(1, 0, t(k) < rk)
    end do
  end subroutine
  subroutine dist_branch(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j
    real(dp) :: dx, dy, r2
    nc = 0
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      r2 = dx*dx + dy*dy
      low = min(low, r2)
      if (r2 < rk) then
        nc = nc + 1
        js(nc) = j
        r2s(nc) = r2
      end if
    end do
  end subroutine
  subroutine dist_idx(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j
    real(dp) :: dx, dy, r2
    integer :: ix(256)
    nc = 0
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      r2 = dx*dx + dy*dy
      low = min(low, r2)
      r2s(k) = r2
      ix(nc + 1) = k
      nc = nc + merge(1, 0, r2 < rk)
    end do
  end subroutine
  subroutine dist_idx2(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j, m
    real(dp) :: dx, dy, r2, t(256)
    integer :: ix(256)
    nc = 0
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      r2 = dx*dx + dy*dy
      low = min(low, r2)
      t(k) = r2
      ix(nc + 1) = k
      nc = nc + merge(1, 0, r2 < rk)
    end do
    !GCC$ novector
    do m = 1, nc
      k = ix(m)
      js(m) = nbr(k)
      r2s(m) = t(k)
    end do
  end subroutine
  subroutine dist_prune(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j
    real(dp) :: dx, dy
    integer :: ow(256)
    nc = 0
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      js(nc + 1) = j
      ow(nc + 1) = i
      nc = nc + merge(1, 0, dx*dx + dy*dy < rk)
    end do
    r2s(1) = ow(1)
  end subroutine
  subroutine dist_prune2(nk, own, nbr, x, y, rk, js, r2s, nc, low)
    integer, intent(in) :: nk, own(nk), nbr(nk)
    real(dp), intent(in) :: x(*), y(*), rk
    integer, intent(out) :: js(nk), nc
    real(dp), intent(out) :: r2s(nk)
    real(dp), intent(inout) :: low
    integer :: k, i, j
    real(dp) :: dx, dy
    integer :: ix(256)
    nc = 0
    !GCC$ novector
    do k = 1, nk
      i = own(k); j = nbr(k)
      dx = x(i) - x(j); dy = y(i) - y(j)
      ix(nc + 1) = k
      nc = nc + merge(1, 0, dx*dx + dy*dy < rk)
    end do
    r2s(1) = ix(1)
    js(1) = ix(nc)
  end subroutine
end module
program micro
  use kinds, only: dp
  use state, only: state_t, state_allocate
  use neighbours
  use mic
  implicit none
  type(state_t) :: s
  type(nlist_t) :: nl
  integer :: n, m, i, k, passes, side, p, v, k0, nk, nc, js(256), tot
  real(dp) :: rc, w, t0, t1, u(2), low, r2s(256), jit
  character(len=32) :: arg
  call get_command_argument(1, arg); read(arg, *) n
  call get_command_argument(2, arg); read(arg, *) rc
  call get_command_argument(3, arg); read(arg, *) passes
  side = int(sqrt(real(n, dp))); n = side*side; w = 1.6_dp*side
  jit = 0.1_dp
  include 'grid_lattice.inc'
  nl%with_owner = .true.; nl%with_ranges = .true.
  call nlist_setup(nl, nb_verlet, rc, 1.0_dp, w, w, n)
  nl%prune = 0.25_dp
  call nlist_refresh(nl, s, .true.)
  do v = 1, 9
    call cpu_time(t0)
    tot = 0; low = huge(1.0_dp)
    do p = 1, passes
      do k0 = 1, nl%pstart(n+1) - 1, 256
        nk = min(256, nl%pstart(n+1) - k0)
        select case (v)
        case (1); call dist_flat(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (2); call dist_nocomp(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (3); call dist_vec(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (4); call dist_two(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (5); call dist_branch(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (6); call dist_idx(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (7); call dist_idx2(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (8); call dist_prune(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        case (9); call dist_prune2(nk, nl%pown(k0:), nl%pnbr(k0:), s%x, s%y, rc**2, js, r2s, nc, low)
        end select
        tot = tot + nc + int(r2s(1))
      end do
    end do
    call cpu_time(t1)
    print '(a,i0,a,f8.3,a,i0)', 'variant ', v, ' ns/pair ', 1e9_dp*(t1-t0)/(real(nl%pstart(n+1)-1,dp)*passes), ' ', tot
  end do
end program
