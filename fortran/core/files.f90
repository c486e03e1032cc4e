!> Files of a run directory, the same for every method. Every byte goes
!> through the checked-file layer (C stdio: fopen, fwrite, fflush, fsync,
!> fclose, each return value checked): gfortran's own I/O library drops
!> ENOSPC silently (measured: a write to a full tmpfs returns iostat 0 and
!> leaves an empty file). The first failure of a file is kept with the file
!> name and the OS error and stops the run with exit 4. Plus the file-system
!> operations of the runner (exists, remove, atomic rename, directory fsync,
!> mkdir, truncate back to a checkpoint - never padding).
module files
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_ptr, c_null_ptr, &
       c_associated, c_size_t, c_long, c_int8_t, c_f_pointer
  use, intrinsic :: iso_fortran_env, only: int8
  use kinds, only: i8
  use errors, only: status_t, set_error, exit_io, exit_ok
  implicit none
  private

  public :: cfile_t, cf_open, cf_is_open, cf_write, cf_line, cf_sync, cf_close, cf_seek, &
       os_error, sync_dir, file_exists, remove_file, rename_into_place, make_dir, &
       truncate_file

  !> A file written through C stdio with every call checked.
  type :: cfile_t
    type(c_ptr) :: fp = c_null_ptr
    character(len=:), allocatable :: path
    integer(i8) :: bytes = 0      !< size of the file: at open (append) + bytes written since
  end type cfile_t

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
    integer(c_int) function c_fsync(fd) bind(C, name='fsync')
      import :: c_int
      integer(c_int), value :: fd
    end function c_fsync
    type(c_ptr) function c_fopen(path, mode) bind(C, name='fopen')
      import :: c_ptr, c_char
      character(kind=c_char), intent(in) :: path(*), mode(*)
    end function c_fopen
    integer(c_size_t) function c_fwrite(buf, size, n, fp) bind(C, name='fwrite')
      import :: c_size_t, c_ptr, c_int8_t
      integer(c_int8_t), intent(in) :: buf(*)
      integer(c_size_t), value :: size, n
      type(c_ptr), value :: fp
    end function c_fwrite
    integer(c_int) function c_fflush(fp) bind(C, name='fflush')
      import :: c_int, c_ptr
      type(c_ptr), value :: fp
    end function c_fflush
    integer(c_int) function c_fclose(fp) bind(C, name='fclose')
      import :: c_int, c_ptr
      type(c_ptr), value :: fp
    end function c_fclose
    integer(c_int) function c_fileno(fp) bind(C, name='fileno')
      import :: c_int, c_ptr
      type(c_ptr), value :: fp
    end function c_fileno
    integer(c_int) function c_fseek(fp, offset, whence) bind(C, name='fseek')
      import :: c_int, c_ptr, c_long
      type(c_ptr), value :: fp
      integer(c_long), value :: offset
      integer(c_int), value :: whence
    end function c_fseek
    type(c_ptr) function c_strerror(errnum) bind(C, name='strerror')
      import :: c_ptr, c_int
      integer(c_int), value :: errnum
    end function c_strerror
    integer(c_int) function c_truncate(path, length) bind(C, name='truncate')
      import :: c_int, c_char, c_long
      character(kind=c_char), intent(in) :: path(*)
      integer(c_long), value :: length
    end function c_truncate
  end interface

contains

  ! ---- checked files ------------------------------------------------------------

  !> Text of the last OS error (errno), e.g. 'No space left on device', or of
  !> the error number `errnum` (an errno kept before other calls could change it).
  function os_error(errnum) result(msg)
    integer, intent(in), optional :: errnum
    character(len=:), allocatable :: msg
    character(kind=c_char), pointer :: cs(:)
    type(c_ptr) :: p
    integer :: e, k
    if (present(errnum)) then
      e = errnum
    else
      e = ierrno()
    end if
    p = c_strerror(int(e, c_int))
    msg = 'unknown error'
    if (.not. c_associated(p)) return
    call c_f_pointer(p, cs, [256])
    msg = ''
    do k = 1, 256
      if (cs(k) == c_null_char) exit
      msg = msg//cs(k)
    end do
  end function os_error

  !> Open a file for writing: mode 'w' (replace) or 'a' (append; f%bytes
  !> starts at its current size).
  subroutine cf_open(f, path, mode, st)
    type(cfile_t), intent(inout) :: f
    character(len=*), intent(in) :: path, mode
    type(status_t), intent(inout) :: st
    integer(i8) :: n
    f%path = trim(path)
    f%bytes = 0
    if (mode == 'a') then
      inquire(file=f%path, size=n)
      f%bytes = max(0_i8, n)
    end if
    f%fp = c_fopen(f%path//c_null_char, mode//'b'//c_null_char)
    if (.not. c_associated(f%fp)) call set_error(st, exit_io, f%path// &
         ': cannot open for writing: '//os_error())
  end subroutine cf_open

  logical function cf_is_open(f)
    type(cfile_t), intent(in) :: f
    cf_is_open = c_associated(f%fp)
  end function cf_is_open

  !> Write bytes; a short write is an error (with the OS reason).
  subroutine cf_write(f, b, st)
    type(cfile_t), intent(inout) :: f
    integer(int8), intent(in) :: b(:)
    type(status_t), intent(inout) :: st
    integer(c_size_t) :: done
    if (.not. c_associated(f%fp)) return
    if (size(b) == 0) return
    done = c_fwrite(b, 1_c_size_t, int(size(b), c_size_t), f%fp)
    if (done /= int(size(b), c_size_t)) then
      call set_error(st, exit_io, f%path//': write failed: '//os_error())
      return
    end if
    f%bytes = f%bytes + size(b)
  end subroutine cf_write

  !> Write one text line (text and a newline).
  subroutine cf_line(f, text, st)
    type(cfile_t), intent(inout) :: f
    character(len=*), intent(in) :: text
    type(status_t), intent(inout) :: st
    call cf_write(f, transfer(text//achar(10), [0_int8]), st)
  end subroutine cf_line

  !> Move to byte offset (from the start).
  subroutine cf_seek(f, offset, st)
    type(cfile_t), intent(inout) :: f
    integer(i8), intent(in) :: offset
    type(status_t), intent(inout) :: st
    if (.not. c_associated(f%fp)) return
    if (c_fseek(f%fp, int(offset, c_long), 0_c_int) /= 0) call set_error(st, exit_io, &
         f%path//': seek failed: '//os_error())
  end subroutine cf_seek

  !> Hand the buffered bytes to the OS (fflush) and, if disk, to the disk (fsync).
  subroutine cf_sync(f, st, disk)
    type(cfile_t), intent(inout) :: f
    type(status_t), intent(inout) :: st
    logical, intent(in), optional :: disk
    logical :: d
    if (.not. c_associated(f%fp)) return
    d = .true.
    if (present(disk)) d = disk
    if (c_fflush(f%fp) /= 0) then
      call set_error(st, exit_io, f%path//': write failed: '//os_error())
      return
    end if
    if (d) then
      if (c_fsync(c_fileno(f%fp)) /= 0) call set_error(st, exit_io, f%path// &
           ': fsync failed: '//os_error())
    end if
  end subroutine cf_sync

  !> Close (sync = .true.: fflush + fsync first); the last buffered bytes are checked.
  subroutine cf_close(f, st, sync)
    type(cfile_t), intent(inout) :: f
    type(status_t), intent(inout) :: st
    logical, intent(in), optional :: sync
    if (.not. c_associated(f%fp)) return
    if (present(sync)) then
      if (sync) call cf_sync(f, st)
    end if
    if (c_fclose(f%fp) /= 0) call set_error(st, exit_io, f%path//': write failed on close: '// &
         os_error())
    f%fp = c_null_ptr
  end subroutine cf_close

  logical function file_exists(path)
    character(len=*), intent(in) :: path
    inquire(file=trim(path), exist=file_exists)
  end function file_exists

  !> Delete a file if it exists.
  subroutine remove_file(path, st)
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: u, ios
    if (.not. file_exists(path)) return
    open(newunit=u, file=trim(path), status='old', iostat=ios)
    if (ios == 0) close(u, status='delete', iostat=ios)
    if (ios /= 0 .or. file_exists(path)) call set_error(st, exit_io, trim(path)// &
         ': cannot remove')
  end subroutine remove_file

  !> Atomic replacement of `final` by the complete file `tmp` (POSIX
  !> rename): on failure the previous `final` is untouched.
  subroutine rename_into_place(tmp, final, st)
    character(len=*), intent(in) :: tmp, final
    type(status_t), intent(inout) :: st
    if (c_rename(tmp//c_null_char, final//c_null_char) /= 0) &
         call set_error(st, exit_io, final//': cannot rename into place: '//os_error()// &
         ' (the previous version is kept)')
  end subroutine rename_into_place

  !> fsync the directory holding `path`, so a rename into it survives a power
  !> loss (best effort: a file system that cannot open or sync a directory
  !> is left as it is; the rename itself was checked).
  subroutine sync_dir(path)
    character(len=*), intent(in) :: path
    type(c_ptr) :: fp
    integer(c_int) :: rc
    integer :: k
    k = index(path, '/', back=.true.)
    if (k > 1) then
      fp = c_fopen(path(1:k - 1)//c_null_char, 'r'//c_null_char)
    else if (k == 1) then
      fp = c_fopen('/'//c_null_char, 'r'//c_null_char)
    else
      fp = c_fopen('.'//c_null_char, 'r'//c_null_char)
    end if
    if (.not. c_associated(fp)) return
    rc = c_fsync(c_fileno(fp))
    rc = c_fclose(fp)
  end subroutine sync_dir

  !> Create a directory (parents must exist); an existing one is fine. A
  !> failure names the system's reason (errno of mkdir itself, kept before
  !> any other call: read-only file system, permission denied, not a
  !> directory, ...).
  subroutine make_dir(path, st)
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer(c_int) :: rc
    integer :: e
    logical :: there
    if (len_trim(path) == 0) then
      call set_error(st, exit_io, 'the output directory name is empty')
      return
    end if
    inquire(file=trim(path)//'/.', exist=there)
    if (there) return
    rc = c_mkdir(trim(path)//c_null_char, int(o'755', c_int))
    if (rc == 0) return
    e = ierrno()
    inquire(file=trim(path)//'/.', exist=there)
    if (there) return                  ! created meanwhile (another process)
    if (file_exists(path)) then
      call set_error(st, exit_io, trim(path)//': cannot create output directory: it exists '// &
           'and is not a directory')
    else
      call set_error(st, exit_io, trim(path)//': cannot create output directory: '// &
           os_error(e))
    end if
  end subroutine make_dir


  !> Cut a file back to `length` bytes (drops rows written after a
  !> checkpoint). A file shorter than the checkpoint recorded is refused:
  !> it is never padded.
  subroutine truncate_file(path, length, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: length
    type(status_t), intent(inout) :: st
    integer(i8) :: now
    character(len=64) :: b
    if (.not. file_exists(path)) then
      if (length > 0) call set_error(st, exit_io, trim(path)//': missing output file to resume')
      return
    end if
    inquire(file=trim(path), size=now)
    if (now < length) then
      write(b, '(i0,a,i0)') now, ' bytes, the checkpoint recorded ', length
      call set_error(st, exit_io, trim(path)//': refused: shorter than at the checkpoint ('// &
           trim(b)//'); the run directory is damaged')
      return
    end if
    if (c_truncate(trim(path)//c_null_char, int(length, c_long)) /= 0) &
         call set_error(st, exit_io, trim(path)//': cannot truncate to the checkpoint: '// &
         os_error())
  end subroutine truncate_file

end module files
