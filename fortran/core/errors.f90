!> Status object returned by library routines. Library code never stops:
!> the executable turns a failed status into `error stop`, the f2py door into
!> a Python exception.
module errors
  implicit none
  private

  public :: status_t, set_error, msg_len
  public :: exit_ok, exit_internal, exit_bad_input, exit_numerical, exit_io, exit_interrupted

  integer, parameter :: msg_len = 1024
  integer, parameter :: exit_ok = 0          !< success
  integer, parameter :: exit_internal = 1    !< bug or unexpected state
  integer, parameter :: exit_bad_input = 2   !< the scene was refused
  integer, parameter :: exit_numerical = 3   !< a runtime guard stopped the run
  integer, parameter :: exit_io = 4          !< a file could not be read/written
  integer, parameter :: exit_interrupted = 5 !< SIGTERM/SIGINT: checkpoint written, resumable

  type :: status_t
    integer :: code = exit_ok              !< one of the exit_* codes
    character(len=msg_len) :: msg = ''     !< one-line human readable reason
  end type status_t

contains

  !> Record a failure (the first one wins, so the root cause is kept).
  subroutine set_error(st, code, msg)
    type(status_t), intent(inout) :: st
    integer, intent(in) :: code
    character(len=*), intent(in) :: msg
    if (st%code /= exit_ok) return
    st%code = code
    st%msg = msg
  end subroutine set_error

end module errors
