!> SIGTERM/SIGINT turn into a request to stop at the end of the current step
!> (checkpoint, run.json, exit). The executable installs the handlers for its
!> whole life; the f2py door installs them for the duration of one run and
!> then restores Python's own handlers (restore_handlers), so Ctrl-C stops a
!> run started from Python at the next step, with a checkpoint.
module signals
  use, intrinsic :: iso_c_binding, only: c_int, c_funptr, c_funloc
  implicit none
  private

  public :: install_handlers, restore_handlers, stop_requested, stop_signal

  logical, volatile, save :: stop_requested = .false.  !< set by the handler
  integer, volatile, save :: stop_signal = 0           !< which signal

  integer(c_int), parameter :: sigint = 2, sigterm = 15
  type(c_funptr), save :: old_int, old_term   !< handlers replaced by install_handlers
  logical, save :: installed = .false.

  interface
    function c_signal(sig, handler) bind(C, name='signal') result(old)
      import :: c_int, c_funptr
      integer(c_int), value :: sig
      type(c_funptr), value :: handler
      type(c_funptr) :: old
    end function c_signal
  end interface

contains

  subroutine on_signal(sig) bind(C)
    integer(c_int), value :: sig
    stop_requested = .true.
    stop_signal = int(sig)
  end subroutine on_signal

  !> Clear any earlier request and catch SIGTERM/SIGINT.
  subroutine install_handlers()
    stop_requested = .false.
    stop_signal = 0
    if (installed) return
    old_term = c_signal(sigterm, c_funloc(on_signal))
    old_int = c_signal(sigint, c_funloc(on_signal))
    installed = .true.
  end subroutine install_handlers

  !> Put back the handlers that install_handlers replaced.
  subroutine restore_handlers()
    type(c_funptr) :: mine
    if (.not. installed) return
    mine = c_signal(sigterm, old_term)
    mine = c_signal(sigint, old_int)
    installed = .false.
  end subroutine restore_handlers

end module signals
