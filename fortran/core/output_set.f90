!> The outputs of a run, declared once by the method: each is a text table
!> (module tables: two header lines, rows) or binary particle frames (module
!> frames: columns with units and dtypes, JSON meta). A method registers the
!> outputs its scene writes while it loads (an output that is off is not
!> registered: its id stays 0); the set then opens them (fresh with headers,
!> or appended to after a resume), hands their buffers to the OS before a
!> checkpoint, closes them and lists their names (the runner's .outputs,
!> checkpoint record and resume cut-back follow that list and its order).
!> The method writes its rows through the set by id; a row or frame for id 0
!> is nothing. Every byte goes through the checked layers of tables and frames.
!>
!>   call out%table(self%energy, 'energy.dat', '# energy.dat: ...', '# step t[T] ...', &
!>        on=self%energy_every > 0)
!>   call out%frames(self%bin, 'frames.bin', n, cols, units, dtypes, 'step', 'T', meta, on=...)
!>   ...  call out%line(self%energy, trim(row), st)
!>        call out%frame_begin(self%bin, step, t, st); call out%frame_put(self%bin, x, st) ...
!>        call out%frame_end(self%bin, st)
module output_set
  use, intrinsic :: iso_fortran_env, only: int32
  use kinds, only: dp, i8
  use errors, only: status_t
  use tables, only: table_t, table_open, table_line, table_flush, table_close
  use frames, only: frames_t, frames_open, frames_begin, frames_put, frames_end, frames_flush, &
       frames_close
  implicit none
  private

  public :: output_set_t, fname_len, max_out_files, due, frames_as

  integer, parameter :: fname_len = 32      !< length of an output file name
  integer, parameter :: max_out_files = 8   !< outputs per method (checkpoint record)
  integer, parameter :: col_len = 32        !< a frames column's name or unit

  !> One declared output: what it is, and its open file.
  type :: output_t
    character(len=fname_len) :: name = ''
    logical :: binary = .false.                  !< frames (else a text table)
    character(len=:), allocatable :: head1, head2   !< table: the two header lines
    integer :: n = 0                             !< frames: particles per frame
    character(len=col_len), allocatable :: cols(:), units(:)
    character(len=2), allocatable :: dtypes(:)   !< frames: per column 'i4' | 'f8'
    character(len=:), allocatable :: step_name, time_unit, meta
    type(table_t) :: tab
    type(frames_t) :: fr
  end type output_t

  !> The outputs of one run, in registration order.
  type :: output_set_t
    integer :: n = 0
    type(output_t) :: o(max_out_files)
  contains
    procedure :: table => add_table
    procedure :: frames => add_frames
    procedure :: open => open_all
    procedure :: flush => flush_all
    procedure :: close => close_all
    procedure :: names
    procedure :: line
    procedure :: frame_begin, frame_end
    procedure, private :: put_i4, put_f8
    generic :: frame_put => put_i4, put_f8
  end type output_set_t

contains

  !> Register the text table `name` (headers: line 1 the file and its units,
  !> line 2 the columns as name[unit]); id 0 when not `on`.
  subroutine add_table(self, id, name, head1, head2, on)
    class(output_set_t), intent(inout) :: self
    integer, intent(out) :: id
    character(len=*), intent(in) :: name, head1, head2
    logical, intent(in) :: on
    id = 0
    if (.not. on) return
    id = next_id(self, name)
    self%o(id)%head1 = head1
    self%o(id)%head2 = head2
  end subroutine add_table

  !> Register the binary frames file `name`: n particles, one column per
  !> name/unit/dtype ('i4' | 'f8'), the frame's step column name, the time
  !> unit and the method's JSON meta members (module frames); id 0 when not `on`.
  subroutine add_frames(self, id, name, n, cols, units, dtypes, step_name, time_unit, meta, on)
    class(output_set_t), intent(inout) :: self
    integer, intent(out) :: id
    character(len=*), intent(in) :: name, cols(:), units(:), dtypes(:), step_name, time_unit, &
         meta
    integer, intent(in) :: n
    logical, intent(in) :: on
    id = 0
    if (.not. on) return
    id = next_id(self, name)
    associate (o => self%o(id))
      o%binary = .true.
      o%n = n
      o%cols = cols
      o%units = units
      o%dtypes = dtypes
      o%step_name = step_name
      o%time_unit = time_unit
      o%meta = meta
    end associate
  end subroutine add_frames

  integer function next_id(self, name) result(id)
    class(output_set_t), intent(inout) :: self
    character(len=*), intent(in) :: name
    if (self%n >= max_out_files) error stop 'output_set: more than max_out_files outputs'
    if (len_trim(name) > fname_len) error stop 'output_set: an output name longer than fname_len'
    self%n = self%n + 1
    id = self%n
    self%o(id)%name = name
  end function next_id

  !> Open every output in `dir`: fresh with its header, or (append) at its end
  !> after a resume (the runner has cut it back; frames verify their header).
  subroutine open_all(self, dir, append, st)
    class(output_set_t), intent(inout) :: self
    character(len=*), intent(in) :: dir
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    integer :: k
    do k = 1, self%n
      associate (o => self%o(k))
        if (o%binary) then
          call frames_open(o%fr, trim(dir)//'/'//trim(o%name), o%n, o%cols, o%units, o%dtypes, &
               o%step_name, o%time_unit, o%meta, append, st)
        else
          call table_open(o%tab, dir, o%name, o%head1, o%head2, append, st)
        end if
      end associate
    end do
  end subroutine open_all

  !> Hand every open output's buffer to the OS (before a checkpoint reads the sizes).
  subroutine flush_all(self, st)
    class(output_set_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call each(self, .false., st)
  end subroutine flush_all

  !> fflush + fsync + close every output (each is closed even after a failure).
  subroutine close_all(self, st)
    class(output_set_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call each(self, .true., st)
  end subroutine close_all

  !> Flush (closing: fsync and close) every output, in registration order.
  subroutine each(self, closing, st)
    class(output_set_t), intent(inout) :: self
    logical, intent(in) :: closing
    type(status_t), intent(inout) :: st
    integer :: k
    do k = 1, self%n
      associate (o => self%o(k))
        if (o%binary .and. closing) then
          call frames_close(o%fr, st)
        else if (o%binary) then
          call frames_flush(o%fr, st)
        else if (closing) then
          call table_close(o%tab, st)
        else
          call table_flush(o%tab, st)
        end if
      end associate
    end do
  end subroutine each

  !> The names of the outputs, in registration order (relative to the run directory).
  subroutine names(self, list, n)
    class(output_set_t), intent(in) :: self
    character(len=fname_len), intent(out) :: list(max_out_files)
    integer, intent(out) :: n
    list = ''
    n = self%n
    list(1:n) = self%o(1:n)%name
  end subroutine names

  !> One row of table `id` (nothing for id 0; the guards of module tables).
  subroutine line(self, id, text, st)
    class(output_set_t), intent(inout) :: self
    integer, intent(in) :: id
    character(len=*), intent(in) :: text
    type(status_t), intent(inout) :: st
    if (id > 0) call table_line(self%o(id)%tab, text, st)
  end subroutine line

  !> Start a frame of frames output `id` at step and time t (nothing for id 0).
  subroutine frame_begin(self, id, step, t, st)
    class(output_set_t), intent(inout) :: self
    integer, intent(in) :: id
    integer(i8), intent(in) :: step
    real(dp), intent(in) :: t
    type(status_t), intent(inout) :: st
    if (id > 0) call frames_begin(self%o(id)%fr, step, t, st)
  end subroutine frame_begin

  subroutine put_i4(self, id, a, st)
    class(output_set_t), intent(inout) :: self
    integer, intent(in) :: id
    integer(int32), intent(in) :: a(:)
    type(status_t), intent(inout) :: st
    if (id > 0) call frames_put(self%o(id)%fr, a, st)
  end subroutine put_i4

  subroutine put_f8(self, id, a, st)
    class(output_set_t), intent(inout) :: self
    integer, intent(in) :: id
    real(dp), intent(in) :: a(:)
    type(status_t), intent(inout) :: st
    if (id > 0) call frames_put(self%o(id)%fr, a, st)
  end subroutine put_f8

  subroutine frame_end(self, id, st)
    class(output_set_t), intent(inout) :: self
    integer, intent(in) :: id
    type(status_t), intent(inout) :: st
    if (id > 0) call frames_end(self%o(id)%fr, st)
  end subroutine frame_end

  !> A row with cadence `every` (0: off) is due at `step`: every `every` steps, and at the last.
  pure logical function due(every, step, last)
    integer(i8), intent(in) :: every, step
    logical, intent(in) :: last
    due = every > 0
    if (due) due = last .or. mod(step, every) == 0
  end function due

  !> Frames go out as `which` ('text' | 'binary') under &output frames_format
  !> (text | binary | both) when their cadence `every` is on.
  pure logical function frames_as(every, format, which)
    integer(i8), intent(in) :: every
    character(len=*), intent(in) :: format, which
    frames_as = every > 0 .and. (trim(format) == which .or. trim(format) == 'both')
  end function frames_as

end module output_set
