!> The one interface between the shared runner and a simulation method.
!>
!> A method (time-stepped MD, event-driven, DSMC, ...) extends method_t and
!> implements its deferred procedures; the runner (module runner) owns
!> everything else: the run directory, scene.nml, run.json, checkpoints and
!> resume, signals, --stop-at, progress lines and exit codes. The runner
!> calls, in this order:
!>   load -> [scene_text, open_outputs] -> { advance, [save_state] }* -> finish -> close_outputs
!> and on resume: load -> restore_state -> (files cut back) -> open_outputs(append) -> ...
!> `advance` performs one unit of work (a time step, an event, a DSMC step)
!> and writes the rows that are due; `counters` tells the runner how far the
!> run is (done/total units, simulated time) so the runner knows when to stop.
module method
  use kinds, only: dp, i8
  use errors, only: status_t
  use ckpt, only: ckpt_writer_t
  use schema, only: schema_t
  implicit none
  private

  public :: method_t, fname_len, max_out_files, add_output

  integer, parameter :: fname_len = 32      !< length of an output file name
  integer, parameter :: max_out_files = 8   !< output files per method (checkpoint sizes)

  type, abstract :: method_t
    logical :: writing = .false.            !< outputs are open (set by open_outputs/close_outputs)
    integer(i8) :: checkpoint_every = 0     !< units of work between checkpoints (0: none; set by load)
    integer(i8) :: progress_every = 0       !< units between progress lines (0: about 200 per run)
  contains
    procedure(load_i), deferred :: load
    procedure(keys_i), deferred :: keys
    procedure :: read => read_default
    procedure :: scene_text => scene_text_default
    procedure(open_i), deferred :: open_outputs
    procedure(advance_i), deferred :: advance
    procedure(advance_i), deferred :: finish
    procedure(close_i), deferred :: close_outputs
    procedure(files_i), deferred :: output_files
    procedure(save_i), deferred :: save_state
    procedure(restore_i), deferred :: restore_state
    procedure(counters_i), deferred :: counters
    procedure(text_i), deferred :: progress_text
    procedure(json_i), deferred :: json_fields
  end type method_t

  abstract interface
    !> Read and validate the scene at `path`, build the initial state. Writes nothing.
    subroutine load_i(self, path, st)
      import :: method_t, status_t
      class(method_t), intent(inout), target :: self
      character(len=*), intent(in) :: path
      type(status_t), intent(inout) :: st
    end subroutine load_i
    !> Declare the kind's scene (module schema): every group and key, bound to
    !> the variable that holds it (its current value is the default). The
    !> declaration drives reading, validation, scene.nml and the documentation.
    subroutine keys_i(self, s)
      import :: method_t, schema_t
      class(method_t), intent(inout), target :: self
      type(schema_t), intent(inout) :: s
    end subroutine keys_i
    !> Open the output files in `dir`: fresh with headers, or appended to after a resume.
    subroutine open_i(self, dir, append, st)
      import :: method_t, status_t
      class(method_t), intent(inout) :: self
      character(len=*), intent(in) :: dir
      logical, intent(in) :: append
      type(status_t), intent(inout) :: st
    end subroutine open_i
    !> One unit of work (advance) / the final rows of the run (finish).
    subroutine advance_i(self, st)
      import :: method_t, status_t
      class(method_t), intent(inout) :: self
      type(status_t), intent(inout) :: st
    end subroutine advance_i
    !> Flush (and, unless flush_only, close) the output files.
    subroutine close_i(self, flush_only, st)
      import :: method_t, status_t
      class(method_t), intent(inout) :: self
      logical, intent(in) :: flush_only
      type(status_t), intent(inout) :: st
    end subroutine close_i
    !> Names of the output files this scene writes (relative to the run directory).
    subroutine files_i(self, names, n)
      import :: method_t, fname_len, max_out_files
      class(method_t), intent(in) :: self
      character(len=fname_len), intent(out) :: names(max_out_files)
      integer, intent(out) :: n
    end subroutine files_i
    !> The complete dynamic state, appended to a checkpoint with
    !> ckpt_put(w, transfer(x, [0_int8])) (checked writes; the writer keeps the first failure).
    subroutine save_i(self, w)
      import :: method_t, ckpt_writer_t
      class(method_t), intent(in) :: self
      type(ckpt_writer_t), intent(inout) :: w
    end subroutine save_i
    subroutine restore_i(self, u, st)
      import :: method_t, status_t
      class(method_t), intent(inout) :: self
      integer, intent(in) :: u
      type(status_t), intent(inout) :: st
    end subroutine restore_i
    !> Units of work done and in the whole run, simulated time [method's time unit].
    subroutine counters_i(self, done, total, t)
      import :: method_t, i8, dp
      class(method_t), intent(in) :: self
      integer(i8), intent(out) :: done, total
      real(dp), intent(out) :: t
    end subroutine counters_i
    !> Two words for progress lines: a phase name and one number (e.g. the piston force).
    function text_i(self) result(s)
      import :: method_t
      class(method_t), intent(in) :: self
      character(len=:), allocatable :: s
    end function text_i
    !> The method's own run.json members: lines '  "key": value,' each ending in
    !> achar(10) (the runner adds the shared members and closes the object).
    function json_i(self) result(text)
      import :: method_t
      class(method_t), intent(in) :: self
      character(len=:), allocatable :: text
    end function json_i
  end interface

contains

  !> Append `name` to an output_files list when `on` (the file is written by this scene).
  subroutine add_output(names, n, on, name)
    character(len=fname_len), intent(inout) :: names(max_out_files)
    integer, intent(inout) :: n
    logical, intent(in) :: on
    character(len=*), intent(in) :: name
    if (.not. on) return
    n = n + 1
    names(n) = name
  end subroutine add_output

  !> Read the scene file only (file-level and type checks, no range
  !> validation), for resolving a scene as the engine reads it.
  subroutine read_default(self, path, st)
    class(method_t), intent(inout), target :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    type(schema_t) :: s
    call self%keys(s)
    call s%read(path, st)
  end subroutine read_default

  !> The fully resolved scene (every key, its value, unit and meaning), lines
  !> ending in achar(10); the first line starts with '! resolved scene:' (the
  !> runner recognises a run directory by it and never removes another scene.nml).
  function scene_text_default(self) result(text)
    class(method_t), intent(inout), target :: self
    character(len=:), allocatable :: text
    type(schema_t) :: s
    call self%keys(s)
    text = s%text()
  end function scene_text_default

end module method
