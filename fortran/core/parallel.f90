!> OpenMP thread count policy. Without OMP_NUM_THREADS in the environment the
!> engine runs on one thread: the force passes only gain at large N, and
!> oversubscribed OpenMP threads (other jobs on the same cores) can be many
!> times slower than one. Set OMP_NUM_THREADS to use more cores.
module parallel
  implicit none
  private

  public :: init_threads, choose_threads, par_min_loop, my_share

  !> Particles from which the O(N) loops run on the threads (fork/join ~1.6 us
  !> here, measured). Even the light loops (zeroing, gravity, checks) stay
  !> parallel from there: with the same static schedule everywhere, each
  !> thread finds its share of the arrays in its own cache (measured: making
  !> them serial below 5e4 particles slowed 2-thread steps at N = 1e4 by 6 %).
  integer, parameter :: par_min_loop = 4000

  logical, save :: chosen = .false.   !< a thread count has been decided

contains

  subroutine init_threads()
    !$ use omp_lib, only: omp_set_num_threads
    integer :: stat
    if (chosen) return
    call get_environment_variable('OMP_NUM_THREADS', status=stat)
    !$ if (stat /= 0) call omp_set_num_threads(1)
    if (stat /= 0) continue
    chosen = .true.
  end subroutine init_threads

  !> Inside a parallel region: this thread's number t (1-based) among nt threads; 1, 1
  !> outside one. Thread t's share of 1..n is 1 + ((t - 1) n)/nt .. (t n)/nt. Loops that run
  !> serially below par_min_loop call their range kernel directly instead of entering an
  !> inactive region (`parallel if (.false.)` still costs ~0.3 us, several times a step).
  subroutine my_share(n, t, nt)
    !$ use omp_lib, only: omp_get_thread_num, omp_get_num_threads
    integer, intent(in) :: n
    integer, intent(out) :: t, nt
    t = 1; nt = 1
    !$ t = omp_get_thread_num() + 1
    !$ nt = omp_get_num_threads()
    if (n < 0) nt = 1
  end subroutine my_share

  subroutine choose_threads(n)
    !$ use omp_lib, only: omp_set_num_threads
    integer, intent(in) :: n
    !$ call omp_set_num_threads(max(1, n))
    if (n < 0) continue
    chosen = .true.
  end subroutine choose_threads

end module parallel
