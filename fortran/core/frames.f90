!> Binary particle frames, one format for every method (file suffix .bin;
!> the Python reader is pyorch.trajectory, which memory-maps it).
!>
!> File layout (little-endian; a big-endian machine is refused at open):
!>   bytes 0-7    magic 'PYORCHFR'
!>   bytes 8-11   uint32 format version (1)
!>   bytes 12-15  uint32 header_bytes H (a multiple of 64)
!>   bytes 16-H   a JSON object (ASCII, blank-filled, ending in a newline):
!>                {"format": "pyorch-frames", "version": 1, "byteorder": "little",
!>                 "n": N, "record_bytes": R,
!>                 "frame": [{"name": "step", "dtype": "<i8", "unit": "", "offset": 0},
!>                           {"name": "t", "dtype": "<f8", "unit": "T", "offset": 8}],
!>                 "columns": [{"name": "x", "dtype": "<f8", "unit": "D1", "offset": 16}, ...],
!>                 "meta": {...the method's own members...}}
!>   then frame records of exactly R bytes each, back to back:
!>                int64 step, float64 t, then each column's N values in turn
!>                (the column's byte offset in the record is in the header).
!> The number of frames is (file size - H) / R; a file whose size is not
!> H + k R (a torn last record) is refused by the reader, never padded. A
!> numpy reader maps it as np.memmap(path, dtype=record_dtype, offset=H).
!>
!> Interface (a method registers the file in its output set, module output_set,
!> which opens, flushes, closes and lists it; the runner does checkpoints,
!> resume cut-back and run.json):
!>   type(frames_t) :: fr
!>   call frames_open(fr, dir//'/particles.bin', n, names, units, dtypes, 'step', 'T', &
!>        meta, append, st)      ! names/units/dtypes: one per column, dtype 'i4' | 'f8'
!>                              ! (names and units plain text: no quote, backslash, newline);
!>                              ! meta: JSON members without braces ('' for none;
!>                              ! json_real(v) writes a real as a JSON number);
!>                              ! append: continue after a resume (header verified)
!>   each frame:  call frames_begin(fr, step, t, st)
!>                call frames_put(fr, column, st)   ! every column in header order,
!>                                                 ! integer (int32) or real(dp), size n
!>                call frames_end(fr, st)
!>   before a checkpoint: call frames_flush(fr, st);  at the end: call frames_close(fr, st)
!> Every byte goes through the checked C-stdio files of module files (a
!> failed write is an exit_io status naming the file); a misuse (wrong
!> column order, size or type) is an exit_internal status. A record is
!> assembled in memory and written whole by frames_end: a non-finite time
!> or real value (NaN, Infinity) is an exit_numerical status naming the
!> file, the step and the column, and that record is not written.
module frames
  use, intrinsic :: iso_fortran_env, only: int8, int32, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_ok, exit_io, exit_internal, exit_numerical
  use files, only: cfile_t, cf_open, cf_is_open, cf_write, cf_sync, cf_close, file_exists
  use scene_input, only: int_str, json_real
  implicit none
  private

  public :: frames_t, frames_open, frames_begin, frames_put, frames_end, frames_flush, &
       frames_close, frames_is_open, frames_magic, frames_version

  character(len=8), parameter :: frames_magic = 'PYORCHFR'
  integer, parameter :: frames_version = 1
  integer, parameter :: align = 64          !< header size granularity [bytes]

  !> One binary frames file being written.
  type :: frames_t
    type(cfile_t) :: f                      !< f%bytes: the file's size so far
    integer :: n = 0                        !< particles per frame
    character(len=2), allocatable :: dtype(:)   !< per column: 'i4' | 'f8'
    integer :: next = -1                    !< columns written in the open record (-1: none open)
    integer(i8) :: header_bytes = 0, record_bytes = 0
    character(len=32), allocatable :: name(:)   !< per column (for messages)
    integer(int8), allocatable :: rec(:)    !< the open record (record_bytes), written by frames_end
    integer(i8) :: fill = 0                 !< bytes of rec given so far
    integer(i8) :: step = 0                 !< step of the open record
  end type frames_t

  interface frames_put
    module procedure put_i4, put_f8
  end interface frames_put

contains

  logical function frames_is_open(fr)
    type(frames_t), intent(in) :: fr
    frames_is_open = cf_is_open(fr%f)
  end function frames_is_open

  !> Open `path` for frames of `n` particles with the given columns: fresh
  !> (header written) or, with append, after a resume: the file (already cut
  !> back to its checkpoint size by the runner) must hold exactly this header
  !> and whole records.
  subroutine frames_open(fr, path, n, names, units, dtypes, step_name, time_unit, meta, append, &
       st)
    type(frames_t), intent(inout) :: fr
    character(len=*), intent(in) :: path
    integer, intent(in) :: n
    character(len=*), intent(in) :: names(:), units(:), dtypes(:)
    character(len=*), intent(in) :: step_name, time_unit, meta
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    integer(int8), allocatable :: head(:)
    integer(int8) :: probe(4)
    integer :: k
    if (st%code /= exit_ok) return
    probe = transfer(1_int32, probe)
    if (probe(1) /= 1_int8) then
      call set_error(st, exit_internal, trim(path)//': binary frames are little-endian; '// &
           'this machine is big-endian (use frames_format = ''text'')')
      return
    end if
    if (size(units) /= size(names) .or. size(dtypes) /= size(names) .or. n < 0) then
      call set_error(st, exit_internal, trim(path)//': frames_open: columns, units and '// &
           'dtypes differ in number (or n < 0)')
      return
    end if
    if (any([(scan(names(k)//units(k), '"\'//achar(10)) > 0, k = 1, size(names))]) .or. &
         scan(step_name//time_unit, '"\'//achar(10)) > 0) then
      call set_error(st, exit_internal, trim(path)//': frames_open: a column name or unit '// &
           'holds a quote, backslash or newline (the header is JSON)')
      return
    end if
    fr%n = n
    fr%dtype = [(dtypes(k)(1:2), k = 1, size(dtypes))]
    if (any(fr%dtype /= 'i4' .and. fr%dtype /= 'f8')) then
      call set_error(st, exit_internal, trim(path)//': frames_open: a dtype is not i4 or f8')
      return
    end if
    fr%record_bytes = 16
    do k = 1, size(fr%dtype)
      fr%record_bytes = fr%record_bytes + int(n, i8)*width(fr%dtype(k))
    end do
    head = header(fr, names, units, step_name, time_unit, meta)
    fr%header_bytes = size(head, kind=i8)
    fr%next = -1
    fr%name = [(names(k)(1:min(32, len(names(k)))), k = 1, size(names))]
    if (allocated(fr%rec)) deallocate(fr%rec)
    allocate(fr%rec(fr%record_bytes))
    fr%fill = 0
    if (append) then
      call check_existing(fr, path, head, st)
      if (st%code /= exit_ok) return
      call cf_open(fr%f, path, 'a', st)
      return
    end if
    call cf_open(fr%f, path, 'w', st)
    call cf_write(fr%f, head, st)
  end subroutine frames_open

  !> Start a frame record: step and time t [the header's time unit].
  subroutine frames_begin(fr, step, t, st)
    type(frames_t), intent(inout) :: fr
    integer(i8), intent(in) :: step
    real(dp), intent(in) :: t
    type(status_t), intent(inout) :: st
    if (st%code /= exit_ok .or. .not. cf_is_open(fr%f)) return
    if (fr%next /= -1) then
      call set_error(st, exit_internal, fr%f%path//': frames_begin inside an open record')
      return
    end if
    fr%step = step
    if (.not. ieee_is_finite(t)) then
      call refuse_non_finite(fr, 'its time', st)
      return
    end if
    fr%rec(1:16) = [transfer(int(step, int64), [0_int8]), transfer(t, [0_int8])]
    fr%fill = 16
    fr%next = 0
  end subroutine frames_begin

  !> The next column of the open record, integer (int32) values.
  subroutine put_i4(fr, a, st)
    type(frames_t), intent(inout) :: fr
    integer(int32), intent(in) :: a(:)
    type(status_t), intent(inout) :: st
    integer(i8) :: m
    if (.not. next_ok(fr, 'i4', size(a), st)) return
    m = 4*int(fr%n, i8)
    if (fr%n > 0) fr%rec(fr%fill + 1:fr%fill + m) = transfer(a, [0_int8])
    fr%fill = fr%fill + m
    fr%next = fr%next + 1
  end subroutine put_i4

  !> The next column of the open record, real(dp) values (all finite).
  subroutine put_f8(fr, a, st)
    type(frames_t), intent(inout) :: fr
    real(dp), intent(in) :: a(:)
    type(status_t), intent(inout) :: st
    integer(i8) :: m
    integer :: bad
    if (.not. next_ok(fr, 'f8', size(a), st)) return
    if (.not. all(ieee_is_finite(a))) then
      bad = findloc(ieee_is_finite(a), .false., 1)
      call refuse_non_finite(fr, 'column '''//trim(fr%name(fr%next + 1))//''' (value '// &
           int_str(int(bad, i8))//' of '//int_str(int(fr%n, i8))//')', st)
      return
    end if
    m = 8*int(fr%n, i8)
    if (fr%n > 0) fr%rec(fr%fill + 1:fr%fill + m) = transfer(a, [0_int8])
    fr%fill = fr%fill + m
    fr%next = fr%next + 1
  end subroutine put_f8

  !> Close the record: every column must have been given; the record is written.
  subroutine frames_end(fr, st)
    type(frames_t), intent(inout) :: fr
    type(status_t), intent(inout) :: st
    if (st%code /= exit_ok .or. .not. cf_is_open(fr%f)) return
    if (fr%next /= size(fr%dtype) .or. fr%fill /= fr%record_bytes) then
      call set_error(st, exit_internal, fr%f%path//': frames_end: a record misses columns')
    else
      call cf_write(fr%f, fr%rec, st)
    end if
    fr%next = -1
    fr%fill = 0
  end subroutine frames_end

  !> The record of fr%step holds a non-finite number (in `what`): refused, not written.
  subroutine refuse_non_finite(fr, what, st)
    type(frames_t), intent(inout) :: fr
    character(len=*), intent(in) :: what
    type(status_t), intent(inout) :: st
    call set_error(st, exit_numerical, fr%f%path//': the state became non-finite at step '// &
         int_str(fr%step)//': '//what//' is NaN or Infinity; the frame was refused (not '// &
         'written) and the run stops here')
    fr%next = -1
    fr%fill = 0
  end subroutine refuse_non_finite

  !> Hand the buffered bytes to the OS (before a checkpoint reads the size).
  subroutine frames_flush(fr, st)
    type(frames_t), intent(inout) :: fr
    type(status_t), intent(inout) :: st
    call cf_sync(fr%f, st, disk=.false.)
  end subroutine frames_flush

  !> fflush + fsync + close, every step checked.
  subroutine frames_close(fr, st)
    type(frames_t), intent(inout) :: fr
    type(status_t), intent(inout) :: st
    call cf_close(fr%f, st, sync=.true.)
    fr%next = -1
    fr%fill = 0
  end subroutine frames_close

  ! ---- inside ----------------------------------------------------------------------

  integer(i8) function width(dtype)
    character(len=2), intent(in) :: dtype
    width = merge(4_i8, 8_i8, dtype == 'i4')
  end function width

  logical function next_ok(fr, dtype, m, st)
    type(frames_t), intent(inout) :: fr
    character(len=2), intent(in) :: dtype
    integer, intent(in) :: m
    type(status_t), intent(inout) :: st
    next_ok = .false.
    if (st%code /= exit_ok .or. .not. cf_is_open(fr%f)) return
    if (fr%next < 0 .or. fr%next >= size(fr%dtype)) then
      call set_error(st, exit_internal, fr%f%path//': frames_put outside a record or past '// &
           'its last column')
    else if (fr%dtype(fr%next + 1) /= dtype .or. m /= fr%n) then
      call set_error(st, exit_internal, fr%f%path//': frames_put: column '// &
           int_str(int(fr%next + 1, i8))//' is '//fr%dtype(fr%next + 1)//' of '// &
           int_str(int(fr%n, i8))//' values, given '//dtype//' of '//int_str(int(m, i8)))
    else
      next_ok = .true.
    end if
  end function next_ok

  !> The complete header: magic, version, size, JSON padded with blanks to a
  !> multiple of `align` bytes, ending in a newline.
  function header(fr, names, units, step_name, time_unit, meta) result(b)
    type(frames_t), intent(in) :: fr
    character(len=*), intent(in) :: names(:), units(:), step_name, time_unit, meta
    integer(int8), allocatable :: b(:)
    character(len=:), allocatable :: js
    character(len=1), parameter :: nl = achar(10)
    integer(i8) :: off, total
    integer :: k
    js = '{"format": "pyorch-frames", "version": '//int_str(int(frames_version, i8))// &
         ', "byteorder": "little",'//nl//' "n": '//int_str(int(fr%n, i8))//', "record_bytes": '// &
         int_str(fr%record_bytes)//','//nl//' "frame": ['// &
         col(step_name, 'i8', '', 0_i8)//', '//col('t', 'f8', time_unit, 8_i8)//'],'//nl// &
         ' "columns": ['
    off = 16
    do k = 1, size(names)
      if (k > 1) js = js//','//nl//'   '
      js = js//col(names(k), fr%dtype(k), units(k), off)
      off = off + int(fr%n, i8)*width(fr%dtype(k))
    end do
    js = js//'],'//nl//' "meta": {'//trim(meta)//'}}'
    total = ((16 + len(js) + 1 + align - 1)/align)*align
    js = js//repeat(' ', int(total) - 16 - len(js) - 1)//nl
    b = [transfer(frames_magic, [0_int8]), transfer(int(frames_version, int32), [0_int8]), &
         transfer(int(total, int32), [0_int8]), transfer(js, [0_int8])]
  contains
    function col(name, dtype, unit, offset) result(s)
      character(len=*), intent(in) :: name, dtype, unit
      integer(i8), intent(in) :: offset
      character(len=:), allocatable :: s
      s = '{"name": "'//trim(name)//'", "dtype": "<'//dtype//'", "unit": "'//trim(unit)// &
           '", "offset": '//int_str(offset)//'}'
    end function col
  end function header

  !> A frames file to continue: it must start with `head` and hold whole records.
  subroutine check_existing(fr, path, head, st)
    type(frames_t), intent(in) :: fr
    character(len=*), intent(in) :: path
    integer(int8), intent(in) :: head(:)
    type(status_t), intent(inout) :: st
    integer(i8) :: size_now
    integer(int8) :: have(size(head))
    integer :: u, ios
    if (.not. file_exists(path)) then
      call set_error(st, exit_io, trim(path)//': missing output file to resume')
      return
    end if
    inquire(file=trim(path), size=size_now)
    if (size_now < fr%header_bytes .or. mod(size_now - fr%header_bytes, fr%record_bytes) /= 0) &
         then
      call set_error(st, exit_io, trim(path)//': refused: '//int_str(size_now)//' bytes is not '// &
           'the header ('//int_str(fr%header_bytes)//') plus whole frames of '// &
           int_str(fr%record_bytes)//' bytes; the run directory is damaged')
      return
    end if
    open(newunit=u, file=trim(path), access='stream', form='unformatted', status='old', &
         action='read', iostat=ios)
    if (ios == 0) read(u, iostat=ios) have
    if (ios == 0) close(u, iostat=ios)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot read its header to resume')
    else if (any(have /= head)) then
      call set_error(st, exit_io, trim(path)//': refused: its header differs from the '// &
           'columns this scene writes')
    end if
  end subroutine check_existing

end module frames
