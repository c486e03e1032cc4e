!> Text tables, the output format every method shares: line 1 describes the
!> file and its units, line 2 names the columns as name[unit], one row per
!> record. Every byte goes through the checked files of module files: a
!> failed write (full disk, I/O error) becomes an exit_io status naming the
!> file and the system's message.
module tables
  use errors, only: status_t, exit_ok
  use files, only: cfile_t, cf_open, cf_is_open, cf_line, cf_sync, cf_close
  implicit none
  private

  public :: table_t, table_open, table_line, table_flush, table_close, rfmt

  character(len=*), parameter :: rfmt = 'es24.16e3'   !< real format: round-trips a real64

  type :: table_t
    type(cfile_t) :: f
  end type table_t

contains

  !> Open `dir/name` fresh with its two header lines, or (append) at its end.
  subroutine table_open(t, dir, name, header1, header2, append, st)
    type(table_t), intent(inout) :: t
    character(len=*), intent(in) :: dir, name, header1, header2
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    if (st%code /= exit_ok) return
    if (append) then
      call cf_open(t%f, trim(dir)//'/'//trim(name), 'a', st)
      return
    end if
    call cf_open(t%f, trim(dir)//'/'//trim(name), 'w', st)
    call table_line(t, trim(header1), st)
    call table_line(t, trim(header2), st)
  end subroutine table_open

  !> One row (or header line); nothing after the first failure.
  subroutine table_line(t, text, st)
    type(table_t), intent(inout) :: t
    character(len=*), intent(in) :: text
    type(status_t), intent(inout) :: st
    if (st%code /= exit_ok) return
    call cf_line(t%f, text, st)
  end subroutine table_line

  !> Hand the buffered rows to the OS (no fsync).
  subroutine table_flush(t, st)
    type(table_t), intent(inout) :: t
    type(status_t), intent(inout) :: st
    call cf_sync(t%f, st, disk=.false.)
  end subroutine table_flush

  !> fflush + fsync + close, every step checked.
  subroutine table_close(t, st)
    type(table_t), intent(inout) :: t
    type(status_t), intent(inout) :: st
    call cf_close(t%f, st, sync=.true.)
  end subroutine table_close

end module tables
