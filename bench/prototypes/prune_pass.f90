!> Prototype, not part of the engine (bench/RESULTS.md 42.3): prune_rows' loop alone over the
!> whole list (rows of ~10 pairs, r_c + 0.25 kept), as the engine has it (form 1: the pair stored
!> at the next free slot) and flags first, then the stores, row by row (form 2).
!>   B=/tmp/bld   # meson setup $B . -Dnative=true && ninja -C $B partsim
!>   gfortran -O3 -march=native -fno-trapping-math -I$B/libpsengine.a.p \
!>       bench/prototypes/prune_pass.f90 $B/libpsengine.a -fopenmp -o /tmp/pp
!>   OMP_NUM_THREADS=1 /tmp/pp 100000 3 100 0.1    # N, r_c, passes, jitter [D1]: ns per pair
program micro3
  use kinds, only: dp
  use state, only: state_t, state_allocate
  use neighbours
  implicit none
  type(state_t) :: s
  type(nlist_t) :: nl
  integer :: n, m, i, k, passes, side, p, v, slot, j, k0, nk, m0, mk
  integer, parameter :: blk = 64
  integer :: keep(blk)
  integer, allocatable :: out(:), outo(:)
  real(dp) :: rc, w, t0, t1, u(2), rp2, xi, yi, dx, dy, jit
  character(len=32) :: arg
  call get_command_argument(1, arg); read(arg, *) n
  call get_command_argument(2, arg); read(arg, *) rc
  call get_command_argument(3, arg); read(arg, *) passes
  call get_command_argument(4, arg); read(arg, *) jit
  side = int(sqrt(real(n, dp))); n = side*side; w = 1.6_dp*side
  include 'grid_lattice.inc'
  nl%with_owner = .true.
  call nlist_setup(nl, nb_verlet, rc, 1.0_dp, w, w, n)
  call nlist_refresh(nl, s)
  allocate(out(nl%start(n+1)), outo(nl%start(n+1)))
  rp2 = (rc + 0.25_dp)**2
  do v = 1, 2
    call cpu_time(t0)
    do p = 1, passes
      slot = 1
      if (v == 1) then
        do i = 1, n
          xi = s%x(i); yi = s%y(i)
          do k = nl%start(i), nl%start(i + 1) - 1
            j = nl%nbr(k)
            dx = xi - s%x(j); dy = yi - s%y(j)
            out(slot) = j; outo(slot) = i
            slot = slot + merge(1, 0, dx*dx + dy*dy < rp2)
          end do
        end do
      else
        do i = 1, n
          xi = s%x(i); yi = s%y(i)
          k0 = nl%start(i); nk = nl%start(i + 1) - k0
          do m0 = 0, nk - 1, blk
            mk = min(blk, nk - m0)
            do m = 1, mk
              j = nl%nbr(k0 + m0 + m - 1)
              dx = xi - s%x(j); dy = yi - s%y(j)
              keep(m) = merge(1, 0, dx*dx + dy*dy < rp2)
            end do
            do m = 1, mk
              out(slot) = nl%nbr(k0 + m0 + m - 1); outo(slot) = i
              slot = slot + keep(m)
            end do
          end do
        end do
      end if
    end do
    call cpu_time(t1)
    print '(a,i0,a,f8.3,a,i0)', 'form ', v, ' ns/pair ', 1e9_dp*(t1-t0)/(real(nl%start(n+1)-1,dp)*passes), ' kept ', slot - 1
  end do
end program
