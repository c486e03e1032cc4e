!> Text tables, the output format every method shares: line 1 describes the
!> file and its units, line 2 names the columns as name[unit], one row per
!> record. Every write is checked: a failed write (full disk, I/O error)
!> becomes an exit_io status naming the file and the system's message.
module tables
  use kinds, only: i8
  use errors, only: status_t, set_error, exit_io, msg_len
  implicit none
  private

  public :: table_t, table_open, table_flush, table_close, table_check, table_size, rfmt

  character(len=*), parameter :: rfmt = 'es24.16e3'   !< real format: round-trips a real64

  type :: table_t
    character(len=:), allocatable :: path
    integer :: u = -1                    !< -1: not open (newunit never returns -1)
  end type table_t

contains

  !> Open `dir/name` fresh with its two header lines, or (append) at its end.
  subroutine table_open(t, dir, name, header1, header2, append, st)
    type(table_t), intent(inout) :: t
    character(len=*), intent(in) :: dir, name, header1, header2
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    integer :: ios
    character(len=msg_len) :: iom
    if (st%code /= 0) return
    t%path = trim(dir)//'/'//trim(name)
    iom = ''
    if (append) then
      open(newunit=t%u, file=t%path, status='old', position='append', action='write', &
           iostat=ios, iomsg=iom)
    else
      open(newunit=t%u, file=t%path, status='replace', action='write', iostat=ios, iomsg=iom)
    end if
    if (ios /= 0) then
      t%u = -1
      call set_error(st, exit_io, t%path//': cannot open for writing: '//trim(iom))
      return
    end if
    if (.not. append) then
      write(t%u, '(a)', iostat=ios, iomsg=iom) trim(header1)
      if (ios == 0) write(t%u, '(a)', iostat=ios, iomsg=iom) trim(header2)
      call table_check(t, ios, iom, st)
    end if
  end subroutine table_open

  !> Turn the iostat of a write into a status naming the file.
  subroutine table_check(t, ios, iom, st)
    type(table_t), intent(in) :: t
    integer, intent(in) :: ios
    character(len=*), intent(in) :: iom
    type(status_t), intent(inout) :: st
    if (ios /= 0) call set_error(st, exit_io, t%path//': write failed: '//trim(iom))
  end subroutine table_check

  subroutine table_flush(t, st)
    type(table_t), intent(in) :: t
    type(status_t), intent(inout) :: st
    integer :: ios
    character(len=msg_len) :: iom
    if (t%u == -1) return
    iom = ''
    flush(t%u, iostat=ios, iomsg=iom)
    if (ios /= 0) call set_error(st, exit_io, t%path//': flush failed: '//trim(iom))
  end subroutine table_flush

  !> Flushed size [bytes] of an open table (0 when closed).
  function table_size(t) result(nbytes)
    type(table_t), intent(in) :: t
    integer(i8) :: nbytes
    nbytes = 0
    if (t%u /= -1) inquire(unit=t%u, size=nbytes)
  end function table_size

  subroutine table_close(t, st)
    type(table_t), intent(inout) :: t
    type(status_t), intent(inout) :: st
    integer :: ios
    character(len=msg_len) :: iom
    if (t%u == -1) return
    iom = ''
    close(t%u, iostat=ios, iomsg=iom)
    if (ios /= 0) call set_error(st, exit_io, t%path//': close failed: '//trim(iom))
    t%u = -1
  end subroutine table_close

end module tables
