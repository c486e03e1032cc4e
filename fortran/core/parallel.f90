!> OpenMP thread count policy. Without OMP_NUM_THREADS in the environment the
!> engine runs on one thread: the force passes only gain at large N, and
!> oversubscribed OpenMP threads (other jobs on the same cores) can be many
!> times slower than one. Set OMP_NUM_THREADS to use more cores.
module parallel
  implicit none
  private

  public :: init_threads, choose_threads, par_min_loop

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

  subroutine choose_threads(n)
    !$ use omp_lib, only: omp_set_num_threads
    integer, intent(in) :: n
    !$ call omp_set_num_threads(max(1, n))
    if (n < 0) continue
    chosen = .true.
  end subroutine choose_threads

end module parallel
