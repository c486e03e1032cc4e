!> File-system operations every method's run directory needs, each
!> returning a status that names the path and the system's reason.
module files
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_long
  use kinds, only: i8
  use errors, only: status_t, set_error, exit_io, msg_len
  implicit none
  private

  public :: file_exists, dir_exists, remove_file, rename_into_place, make_dir, truncate_file, &
       file_size

  interface
    integer(c_int) function c_rename(old, new) bind(C, name='rename')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: old(*), new(*)
    end function c_rename
    integer(c_int) function c_mkdir(path, mode) bind(C, name='mkdir')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: mode
    end function c_mkdir
    integer(c_int) function c_truncate(path, length) bind(C, name='truncate')
      import :: c_int, c_char, c_long
      character(kind=c_char), intent(in) :: path(*)
      integer(c_long), value :: length
    end function c_truncate
  end interface

contains

  logical function file_exists(path)
    character(len=*), intent(in) :: path
    inquire(file=trim(path), exist=file_exists)
  end function file_exists

  logical function dir_exists(path)
    character(len=*), intent(in) :: path
    inquire(file=trim(path)//'/.', exist=dir_exists)
  end function dir_exists

  !> Size [bytes] of a file, -1 if it does not exist.
  function file_size(path) result(n)
    character(len=*), intent(in) :: path
    integer(i8) :: n
    logical :: there
    n = -1
    inquire(file=trim(path), exist=there)
    if (there) inquire(file=trim(path), size=n)
  end function file_size

  subroutine remove_file(path, st)
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: u, ios
    character(len=msg_len) :: iom
    if (.not. file_exists(path)) return
    iom = ''
    open(newunit=u, file=trim(path), status='old', iostat=ios, iomsg=iom)
    if (ios == 0) close(u, status='delete', iostat=ios, iomsg=iom)
    if (ios /= 0) call set_error(st, exit_io, trim(path)//': cannot remove: '//trim(iom))
  end subroutine remove_file

  !> Atomic replacement of `final` by the complete file `tmp` (POSIX rename).
  subroutine rename_into_place(tmp, final, st)
    character(len=*), intent(in) :: tmp, final
    type(status_t), intent(inout) :: st
    if (c_rename(trim(tmp)//c_null_char, trim(final)//c_null_char) /= 0) &
         call set_error(st, exit_io, trim(final)//': cannot rename into place')
  end subroutine rename_into_place

  !> Create a directory (parents must exist); an existing one is fine.
  subroutine make_dir(path, st)
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer(c_int) :: rc
    if (dir_exists(path)) return
    rc = c_mkdir(trim(path)//c_null_char, int(o'755', c_int))
    if (.not. dir_exists(path)) call set_error(st, exit_io, trim(path)// &
         ': cannot create output directory')
  end subroutine make_dir

  !> Cut a file back to `length` bytes (drops rows written after a
  !> checkpoint). A file shorter than `length` is refused, never padded.
  subroutine truncate_file(path, length, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: length
    type(status_t), intent(inout) :: st
    integer(i8) :: now
    character(len=24) :: a, b
    now = file_size(path)
    if (now < 0) then
      if (length > 0) call set_error(st, exit_io, trim(path)//': missing output file to resume')
      return
    end if
    if (now < length) then
      write(a, '(i0)') now
      write(b, '(i0)') length
      call set_error(st, exit_io, trim(path)//': shorter ('//trim(a)//' bytes) than at the '// &
           'checkpoint ('//trim(b)//' bytes): the run directory was altered; not resumed')
      return
    end if
    if (c_truncate(trim(path)//c_null_char, int(length, c_long)) /= 0) &
         call set_error(st, exit_io, trim(path)//': cannot truncate to the checkpoint')
  end subroutine truncate_file

end module files
