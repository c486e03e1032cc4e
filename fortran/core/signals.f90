!> SIGTERM/SIGINT turn into a request to stop at the end of the current step
!> (checkpoint, run.json, exit). Installed by the executable only: the f2py
!> door leaves Python's own signal handling alone.
module signals
  use, intrinsic :: iso_c_binding, only: c_int, c_funptr, c_funloc
  implicit none
  private

  public :: install_handlers, stop_requested, stop_signal

  logical, volatile, save :: stop_requested = .false.  !< set by the handler
  integer, volatile, save :: stop_signal = 0           !< which signal

  integer(c_int), parameter :: sigint = 2, sigterm = 15

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

  subroutine install_handlers()
    type(c_funptr) :: old
    old = c_signal(sigterm, c_funloc(on_signal))
    old = c_signal(sigint, c_funloc(on_signal))
  end subroutine install_handlers

end module signals
