!> Seeding of the intrinsic random_number generator from a scene's seed (the time-stepped
!> systems' initial conditions): the same seed, the same stream, on both doors.
module rng
  implicit none
  private

  public :: seed_rng

contains

  subroutine seed_rng(seed)
    integer, intent(in) :: seed
    integer :: k, i
    integer, allocatable :: put(:)
    call random_seed(size=k)
    allocate(put(k))
    do i = 1, k
      put(i) = seed + 104729*i + 7919*i*i
    end do
    call random_seed(put=put)
  end subroutine seed_rng

end module rng
