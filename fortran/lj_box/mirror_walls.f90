!> Inelastic mirror walls of seed 000, eq. (10): v' = sqrt(gamma) (v - 2 (v.n) n) on every
!> wall hit, gamma in (0, 1], applied after the position update of a step. The wall is where
!> the particle's centre may reach: lo = a and hi = L - a ('surface': the disk of radius a
!> touches the wall) or lo = 0, hi = L ('centre'). The overshoot beyond the wall is mirrored
!> and scaled by sqrt(gamma) (the rest of the step at the reduced normal speed); the
!> tangential position is not corrected (an error of order h |v| per hit, as the explicit
!> step itself). A corner crossed in one step is two hits (both components reflected,
!> |v|^2 scaled by gamma twice).
module mirror_walls
  use kinds, only: dp, i8
  implicit none
  private

  public :: mirror_reflect

contains

  !> Reflect positions x, y and the velocities ux, uy that the integrator carries to the
  !> next step. hits += wall hits; escaped = a particle still outside after its
  !> reflection (it moved further than the box in one step), 0 if none.
  subroutine mirror_reflect(n, x, y, ux, uy, lo, hi, gamma, hits, escaped)
    integer, intent(in) :: n
    real(dp), intent(inout) :: x(n), y(n), ux(n), uy(n)
    real(dp), intent(in) :: lo, hi, gamma
    integer(i8), intent(inout) :: hits
    integer, intent(out) :: escaped
    integer, parameter :: block = 256   !< particles per vectorised test
    integer :: i, b0, b1
    real(dp) :: sg
    sg = sqrt(gamma)
    escaped = 0
    ! blocks of particles all inside (a vectorised test each) are left alone: a step with a few
    ! hits runs the scalar loop over their blocks only (a particle inside stays inside)
    do b0 = 1, n, block
      b1 = min(n, b0 + block - 1)
      if (all_inside(b1 - b0 + 1, x(b0:b1), y(b0:b1), lo, hi)) cycle
      do i = b0, b1
        if (x(i) < lo .or. x(i) > hi) call hit(x(i), ux(i), uy(i))
        if (y(i) < lo .or. y(i) > hi) call hit(y(i), uy(i), ux(i))
        if (escaped == 0 .and. .not. (x(i) >= lo .and. x(i) <= hi .and. y(i) >= lo .and. &
             y(i) <= hi)) escaped = i
      end do
    end do
  contains
    !> One wall hit along the coordinate c (normal velocity un, tangential ut).
    subroutine hit(c, un, ut)
      real(dp), intent(inout) :: c, un, ut
      if (c < lo) then
        c = lo + sg*(lo - c)
      else
        c = hi - sg*(c - hi)
      end if
      un = -sg*un
      ut = sg*ut
      hits = hits + 1
    end subroutine hit
  end subroutine mirror_reflect

  !> Whether every centre is inside [lo, hi]^2 (false for NaN).
  logical function all_inside(n, x, y, lo, hi) result(ok)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), lo, hi
    integer :: i
    integer(i8) :: out
    out = 0
    ! four counts, not one .and. chain (GCC short-circuits that: no vectors); 64-bit counts,
    ! as wide as the compared doubles (32-bit ones cost a shuffle of every mask)
    do i = 1, n
      out = out + merge(0_i8, 1_i8, x(i) >= lo) + merge(0_i8, 1_i8, x(i) <= hi) + &
           merge(0_i8, 1_i8, y(i) >= lo) + merge(0_i8, 1_i8, y(i) <= hi)
    end do
    ok = out == 0
  end function all_inside

end module mirror_walls
