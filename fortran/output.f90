!> Output files of a run directory: thesis-style text with a header naming
!> every column and its unit, written only at their cadence; run.json with
!> status and metadata, replaced atomically (temporary file, flush, fsync,
!> rename).
!>
!> Every byte goes through the checked-file layer below (C stdio: fopen,
!> fwrite, fflush, fsync, fclose, each return value checked): gfortran's own
!> I/O library drops ENOSPC silently (measured: a write to a full tmpfs
!> returns iostat 0 and leaves an empty file). The first failure of a file is
!> kept with the file name and the OS error and stops the run with exit 4.
!> The layer (cfile_t, cf_open, cf_write, cf_line, cf_sync, cf_close,
!> rename_into_place, remove_file) knows nothing of beds: any simulation kind
!> writes its files with it.
module output
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_ptr, c_null_ptr, &
       c_associated, c_size_t, c_long, c_int8_t, c_f_pointer
  use, intrinsic :: iso_fortran_env, only: int8
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io, exit_ok
  use model, only: model_t
  use state, only: state_t
  implicit none
  private

  public :: output_t, output_open, output_close, write_piston, write_frame, &
       write_distance, write_energy, write_run_json, make_dir, output_flush, output_sizes, &
       output_names, rename_into_place
  public :: engine_version, cfile_t, cf_open, cf_write, cf_line, cf_sync, cf_close, cf_seek, &
       remove_file, file_exists, os_error, sync_dir

  character(len=*), parameter :: engine_version = '0.1.0'  !< bound into run.json and checkpoints

  !> A file written through C stdio with every call checked.
  type :: cfile_t
    type(c_ptr) :: fp = c_null_ptr
    character(len=:), allocatable :: path
    integer(i8) :: bytes = 0      !< size of the file: at open (append) + bytes written since
  end type cfile_t

  type :: output_t
    character(len=:), allocatable :: dir
    type(cfile_t) :: f(4)   !< piston, particles, mean_distance, energy (fp null: off)
    type(status_t) :: st    !< first failed write (code exit_io), kept until the runner reads it
  end type output_t

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
  end interface

  character(len=*), parameter :: rfmt = 'es24.16e3'
  character(len=*), parameter :: output_names(4) = [character(len=17) :: 'piston.dat', &
       'particles.dat', 'mean_distance.dat', 'energy.dat']

contains

  ! ---- checked files ------------------------------------------------------------

  !> Text of the last OS error (errno), e.g. 'No space left on device'.
  function os_error() result(msg)
    character(len=:), allocatable :: msg
    character(kind=c_char), pointer :: cs(:)
    type(c_ptr) :: p
    integer :: e, k
    e = ierrno()
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

  !> Create a directory (parents must exist); an existing one is fine.
  subroutine make_dir(path, st)
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer(c_int) :: rc
    logical :: there
    if (len_trim(path) == 0) then
      call set_error(st, exit_io, 'the output directory name is empty')
      return
    end if
    inquire(file=trim(path)//'/.', exist=there)
    if (there) return
    rc = c_mkdir(trim(path)//c_null_char, int(o'755', c_int))
    inquire(file=trim(path)//'/.', exist=there)
    if (.not. there) call set_error(st, exit_io, trim(path)//': cannot create output directory: ' &
         //os_error())
  end subroutine make_dir

  ! ---- the bed's files ------------------------------------------------------------

  !> Open the output files: fresh with headers, or (append) continued after a
  !> resume, the files having been cut back to the checkpoint's sizes.
  subroutine output_open(o, dir, m, piston_on, frames_on, dist_on, energy_on, append, st)
    type(output_t), intent(inout) :: o
    character(len=*), intent(in) :: dir
    type(model_t), intent(in) :: m
    logical, intent(in) :: piston_on, frames_on, dist_on, energy_on, append
    type(status_t), intent(inout) :: st
    character(len=200) :: units
    o%dir = trim(dir)
    o%st = status_t()
    write(units, '(a,es10.4,a,es10.4,a,es10.4,a)') 'Units: D1 = ', m%length_unit, ' m, T = ', &
         m%time_unit, ' s, m1*g = ', m%force_unit, ' N'
    if (piston_on) call open1(1, &
         '# piston.dat: piston history (force = push of all particles on the piston). '// &
         trim(units), '# step t[T] H[D1] F_piston[m1*g] phi[1] phase')
    if (frames_on) call open1(2, &
         '# particles.dat: particle frames (f = total force; fm = magnetic force of pairs + walls). '// &
         trim(units), '# step t[T] id species x[D1] y[D1] vx[D1/T] vy[D1/T] fx[m1*g] fy[m1*g] '// &
         'fmag[m1*g] fmx[m1*g] fmy[m1*g]')
    if (dist_on) call open1(3, &
         '# mean_distance.dat: mean inter-particle distance, thesis eq. (2.1). '//trim(units), &
         '# step t[T] D_hat[D1]')
    if (energy_on) call open1(4, &
         '# energy.dat: mechanical energy (gravity potential from y = 0). '//trim(units), &
         '# step t[T] E_kin[m1*g*D1] E_pair[m1*g*D1] E_wall[m1*g*D1] E_grav[m1*g*D1] '// &
         'E_piston[m1*g*D1] E_total[m1*g*D1]')
  contains
    subroutine open1(k, head1, head2)
      integer, intent(in) :: k
      character(len=*), intent(in) :: head1, head2
      if (st%code /= exit_ok) return
      if (append) then
        call cf_open(o%f(k), o%dir//'/'//trim(output_names(k)), 'a', st)
        return
      end if
      call cf_open(o%f(k), o%dir//'/'//trim(output_names(k)), 'w', st)
      call cf_line(o%f(k), head1, st)
      call cf_line(o%f(k), head2, st)
    end subroutine open1
  end subroutine output_open

  !> Hand every open file's buffer to the OS; a failure is recorded in o%st.
  subroutine output_flush(o)
    type(output_t), intent(inout) :: o
    integer :: k
    do k = 1, 4
      call cf_sync(o%f(k), o%st, disk=.false.)
    end do
  end subroutine output_flush

  !> Sizes [bytes] of the four files (0 when off), for checkpoints. The
  !> files are flushed to the OS first (a killed process loses nothing
  !> before the checkpoint); they are not fsynced: after a power loss a file
  !> may be shorter than its checkpoint says, and the resume then refuses it
  !> (it never pads). Check o%st before trusting the sizes.
  subroutine output_sizes(o, sizes)
    type(output_t), intent(inout) :: o
    integer(i8), intent(out) :: sizes(4)
    integer :: k
    sizes = 0
    do k = 1, 4
      if (.not. cf_is_open(o%f(k))) cycle
      call cf_sync(o%f(k), o%st, disk=.false.)
      sizes(k) = o%f(k)%bytes
    end do
  end subroutine output_sizes

  !> Close every file (the last buffered data is checked into o%st).
  subroutine output_close(o)
    type(output_t), intent(inout) :: o
    integer :: k
    do k = 1, 4
      call cf_close(o%f(k), o%st, sync=.true.)
    end do
  end subroutine output_close

  subroutine put(o, k, line)
    type(output_t), intent(inout) :: o
    integer, intent(in) :: k
    character(len=*), intent(in) :: line
    if (o%st%code /= exit_ok) return
    call cf_line(o%f(k), line, o%st)
  end subroutine put

  subroutine write_piston(o, s, phi)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: phi
    character(len=160) :: line
    write(line, '(i0,4(1x,'//rfmt//'),1x,i0)') s%step, s%t, s%piston_h, s%piston_force, phi, &
         s%phase
    call put(o, 1, trim(line))
  end subroutine write_piston

  subroutine write_frame(o, s)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    integer :: i, k
    integer :: at(s%n)
    character(len=400) :: line
    at(s%id) = [(k, k = 1, s%n)]     ! rows in particle-id order
    do k = 1, s%n
      i = at(k)
      write(line, '(i0,1x,'//rfmt//',1x,i0,1x,i0,9(1x,'//rfmt//'))') s%step, s%t, s%id(i), &
           s%species(i), s%x(i), s%y(i), s%vx(i), s%vy(i), s%fx(i), s%fy(i), s%fmag(i), &
           s%fmx(i), s%fmy(i)
      call put(o, 2, trim(line))
    end do
  end subroutine write_frame

  subroutine write_distance(o, s, d)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: d
    character(len=100) :: line
    write(line, '(i0,2(1x,'//rfmt//'))') s%step, s%t, d
    call put(o, 3, trim(line))
  end subroutine write_distance

  subroutine write_energy(o, s, ek, ep, ew, eg, epis)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: ek, ep, ew, eg, epis   !< epis: free piston kinetic + gravity
    character(len=260) :: line
    write(line, '(i0,7(1x,'//rfmt//'))') s%step, s%t, ek, ep, ew, eg, epis, &
         ek + ep + ew + eg + epis
    call put(o, 4, trim(line))
  end subroutine write_energy

  !> run.json, replaced atomically.
  subroutine write_run_json(dir, scene_path, status, code, message, steps_done, steps_total, &
       t_now, wall, m, n, builds, pairs, evaluated, st)
    character(len=*), intent(in) :: dir, scene_path, status, message
    integer, intent(in) :: code, n
    integer(i8), intent(in) :: steps_done, steps_total
    integer(i8), intent(in) :: builds   !< neighbour-list builds
    integer(i8), intent(in) :: pairs    !< pairs evaluated per step (list length or N(N-1)/2)
    integer(i8), intent(in) :: evaluated  !< pair evaluations of the whole run
    real(dp), intent(in) :: t_now, wall
    type(model_t), intent(in) :: m
    type(status_t), intent(inout) :: st   !< a failure here is recorded unless st already failed
    type(status_t) :: lst, junk
    type(cfile_t) :: f
    character(len=200) :: line
    character(len=:), allocatable :: tmp, final
    real(dp) :: per_step
    tmp = trim(dir)//'/.run.json.tmp'
    final = trim(dir)//'/run.json'
    per_step = 0
    if (steps_done > 0) per_step = wall/real(steps_done, dp)
    call cf_open(f, tmp, 'w', lst)
    call cf_line(f, '{', lst)
    call cf_line(f, '  "program": "magbed",', lst)
    call cf_line(f, '  "version": "'//engine_version//'",', lst)
    call cf_line(f, '  "compiler": "'//esc(compiler_id())//'",', lst)
    call cf_line(f, '  "scene": "'//esc(trim(scene_path))//'",', lst)
    call cf_line(f, '  "status": "'//esc(trim(status))//'",', lst)
    write(line, '(a,i0,a)') '  "exit_code": ', code, ','
    call cf_line(f, trim(line), lst)
    call cf_line(f, '  "message": "'//esc(trim(message))//'",', lst)
    write(line, '(a,i0,a)') '  "n_particles": ', n, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,i0,a)') '  "steps_done": ', steps_done, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,i0,a)') '  "steps_total": ', steps_total, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//',a)') '  "t_reached": ', t_now, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//',a)') '  "wall_time_s": ', wall, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//',a)') '  "wall_time_per_step_s": ', per_step, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,i0,a)') '  "list_builds": ', builds, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,i0,a)') '  "pairs_per_step": ', pairs, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,i0,a)') '  "pair_evaluations": ', evaluated, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,i0,a)') '  "threads": ', n_threads(), ','
    call cf_line(f, trim(line), lst)
    call cf_line(f, '  "units": {', lst)
    write(line, '(a,'//rfmt//',a)') '    "length_m": ', m%length_unit, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//',a)') '    "time_s": ', m%time_unit, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//',a)') '    "mass_kg": ', m%mass_unit, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//',a)') '    "force_N": ', m%force_unit, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//')') '    "moment_Am2": ', m%moment_unit
    call cf_line(f, trim(line), lst)
    call cf_line(f, '  },', lst)
    call cf_line(f, '  "groups": {', lst)
    write(line, '(a,'//rfmt//',a)') '    "F": ', m%big_f, ','
    call cf_line(f, trim(line), lst)
    write(line, '(a,'//rfmt//')') '    "G": ', m%big_g
    call cf_line(f, trim(line), lst)
    call cf_line(f, '  }', lst)
    call cf_line(f, '}', lst)
    ! fsync for the final status; the 'running' updates after each checkpoint
    ! are only flushed (one fsync per checkpoint is enough: the checkpoint's)
    call cf_close(f, lst, sync=trim(status) /= 'running')
    if (lst%code == exit_ok) then
      call rename_into_place(tmp, final, lst)
    else
      call remove_file(tmp, junk)
    end if
    if (lst%code /= exit_ok) call set_error(st, lst%code, trim(lst%msg))
  contains
    function esc(s) result(r)
      character(len=*), intent(in) :: s
      character(len=:), allocatable :: r
      integer :: i
      r = ''
      do i = 1, len(s)
        select case (s(i:i))
        case ('"'); r = r//'\"'
        case ('\'); r = r//'\\'
        case default
          if (iachar(s(i:i)) < 32) then
            r = r//' '
          else
            r = r//s(i:i)
          end if
        end select
      end do
    end function esc
  end subroutine write_run_json

  integer function n_threads()
    !$ use omp_lib, only: omp_get_max_threads
    n_threads = 1
    !$ n_threads = omp_get_max_threads()
  end function n_threads

  function compiler_id() result(s)
    use, intrinsic :: iso_fortran_env, only: compiler_version
    character(len=:), allocatable :: s
    s = compiler_version()
  end function compiler_id

end module output
