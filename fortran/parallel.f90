!> OpenMP thread count policy. Without OMP_NUM_THREADS in the environment the
!> engine runs on one thread: the force passes only gain at large N, and
!> oversubscribed OpenMP threads (other jobs on the same cores) can be many
!> times slower than one. Set OMP_NUM_THREADS to use more cores.
module parallel
  implicit none
  private

  public :: init_threads, choose_threads

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
