!> Harness, not part of the engine (bench/RESULTS.md 42.1): the bed's dipole list pass alone
!> (pair_forces_list, the kernel the engine picks) on the grid's lattice, positions fixed.
!>   B=/tmp/bld   # meson setup $B . -Dnative=true && ninja -C $B partsim
!>   gfortran -O3 -march=native -fno-trapping-math -I$B/libpsengine.a.p \
!>       bench/prototypes/list_pass.f90 $B/libpsengine.a -fopenmp -o /tmp/lp
!>   OMP_NUM_THREADS=1 /tmp/lp N R_CUT PASSES [JITTER [PRUNE]]   # e.g. /tmp/lp 100000 3 300
!> JITTER [D1]: each disk uniform in a square of that side around its site (0.1: the grid's
!> lattice; 1.6: disordered); PRUNE [D1]: the pruned list's margin (0: none). Prints ns per
!> particle and pass, pruned pairs per row and sum |fx| (equal for engines of the same bits).


program harness
  use kinds, only: dp
  use state, only: state_t, state_allocate
  use neighbours
  use pair_forces
  implicit none
  type(state_t) :: s
  type(nlist_t) :: nl
  integer :: n, m, i, k, passes, side, p
  real(dp) :: rc, w, r2min, t0, t1, u(2), jit, pr
  character(len=32) :: arg
  call get_command_argument(1, arg); read(arg, *) n
  call get_command_argument(2, arg); read(arg, *) rc
  call get_command_argument(3, arg); read(arg, *) passes
  jit = 0.1_dp
  if (command_argument_count() >= 4) then
    call get_command_argument(4, arg); read(arg, *) jit
  end if
  pr = 0.25_dp
  if (command_argument_count() >= 5) then
    call get_command_argument(5, arg); read(arg, *) pr
  end if
  side = int(sqrt(real(n, dp)))
  n = side*side
  w = 1.6_dp*side
  include 'grid_lattice.inc'
  s%mu = 1; s%wsin = 1
  nl%with_owner = .true.; nl%with_ranges = .true.
  call nlist_setup(nl, nb_verlet, rc, 1.0_dp, w, w, n)
  nl%prune = pr
  call nlist_refresh(nl, s, pr > 0)
  call cpu_time(t0)
  do p = 1, passes
    s%fx = 0; s%fy = 0; s%s3 = 0
    call pair_forces_list(n, s%x, s%y, s%mu, s%wsin, 1.0_dp, rc**2, 0.0_dp, nl%check, .false., &
         nl%start, nl%nbr, s%fx, s%fy, s%s3, r2min, own=nl%own, rstart=nl%rstart, rlo=nl%rlo, &
         rhi=nl%rhi, mu_one=.true., pstart=nl%pstart, pnbr=nl%pnbr, pown=nl%pown, rowmax=nl%rowmax)
  end do
  call cpu_time(t1)
  print '(a,i0,a,f4.1,a,f8.2,a,f8.3,a,es22.15)', 'N ', n, ' r_c ', rc, ' ns/particle/pass ', &
       1e9_dp*(t1 - t0)/(real(n, dp)*passes), ' pruned pairs/row ', real(merge(nl%pstart(n+1),nl%start(n+1),pr>0)-1,dp)/n, &
       ' sum|fx| ', sum(abs(s%fx))
end program harness
