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
!>
!> What every method repeats has a default here, so a method is its physics:
!> - load: keys -> read -> resolve -> validate (each key's declared range) ->
!>   rules (across keys) -> setup (derived quantities, initial state, and the
!>   outputs registered in `out`, module output_set);
!> - open_outputs, close_outputs, output_files: through `out`;
!> - counters: `step` of `n_steps` units of `time_unit` each.
module method
  use kinds, only: dp, i8
  use errors, only: status_t
  use ckpt, only: ckpt_writer_t
  use schema, only: schema_t
  use output_set, only: output_set_t, fname_len, max_out_files
  implicit none
  private

  public :: method_t, fname_len, max_out_files, open_default

  type, abstract :: method_t
    logical :: writing = .false.            !< outputs are open (set by open_outputs/close_outputs)
    integer(i8) :: checkpoint_every = 0     !< units of work between checkpoints (0: none; set by load)
    integer(i8) :: progress_every = 0       !< units between progress lines (0: about 200 per run)
    type(output_set_t) :: out               !< the outputs this scene writes (registered by setup)
    integer(i8) :: step = 0                 !< units of work done (the default counters)
    integer(i8) :: n_steps = 0              !< units of work in the whole run
    real(dp) :: time_unit = 0               !< simulated time per unit of work [method's time]
  contains
    procedure :: load => load_default
    procedure(keys_i), deferred :: keys
    procedure :: resolve => resolve_default
    procedure :: rules => rules_default
    procedure(setup_i), deferred :: setup
    procedure :: read => read_default
    procedure :: scene_text => scene_text_default
    procedure :: open_outputs => open_default
    procedure(advance_i), deferred :: advance
    procedure(advance_i), deferred :: finish
    procedure :: close_outputs => close_default
    procedure :: output_files => files_default
    procedure(save_i), deferred :: save_state
    procedure(restore_i), deferred :: restore_state
    procedure :: counters => counters_default
    procedure(text_i), deferred :: progress_text
    procedure(json_i), deferred :: json_fields
  end type method_t

  abstract interface
    !> After the rules: derived quantities, the initial state, and the outputs
    !> this scene writes registered in self%out (module output_set). Writes nothing.
    subroutine setup_i(self, path, st)
      import :: method_t, status_t
      class(method_t), intent(inout) :: self
      character(len=*), intent(in) :: path
      type(status_t), intent(inout) :: st
    end subroutine setup_i
    !> Declare the kind's scene (module schema): every group and key, bound to
    !> the variable that holds it (its current value is the default). The
    !> declaration drives reading, validation, scene.nml and the documentation.
    subroutine keys_i(self, s)
      import :: method_t, schema_t
      class(method_t), intent(inout), target :: self
      type(schema_t), intent(inout) :: s
    end subroutine keys_i
    !> One unit of work (advance) / the final rows of the run (finish).
    subroutine advance_i(self, st)
      import :: method_t, status_t
      class(method_t), intent(inout) :: self
      type(status_t), intent(inout) :: st
    end subroutine advance_i
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

  !> The load sequence (nothing written): declare the keys, read the file,
  !> resolve what a key's default derives from others, validate each key's
  !> declared range, the rules across keys, then setup (derived quantities,
  !> the initial state, the outputs). A kind with another sequence overrides it.
  subroutine load_default(self, path, st)
    class(method_t), intent(inout), target :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    call load_sequence(self, path, .true., st)
  end subroutine load_default

  !> Keys and read (the file-level and type checks), then, when `whole`, the rest of load.
  subroutine load_sequence(self, path, whole, st)
    class(method_t), intent(inout), target :: self
    character(len=*), intent(in) :: path
    logical, intent(in) :: whole
    type(status_t), intent(inout) :: st
    type(schema_t) :: s
    call self%keys(s)
    call s%read(path, st)
    if (st%code /= 0 .or. .not. whole) return
    self%out = output_set_t()          ! a load again registers the outputs afresh
    call self%resolve()
    call s%validate(path, st)
    if (st%code /= 0) return
    call self%rules(s, path, st)
    if (st%code /= 0) return
    call self%setup(path, st)
  end subroutine load_sequence

  !> Keys resolved from others before validation (e.g. 'box centre' for a
  !> negative coordinate): none by default.
  subroutine resolve_default(self)
    class(method_t), intent(inout) :: self
  end subroutine resolve_default

  !> The rules across keys (each key's own range is the declaration's, checked
  !> before; `s` gives the line of a key for messages): none by default.
  subroutine rules_default(self, s, path, st)
    class(method_t), intent(inout) :: self
    type(schema_t), intent(in) :: s
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
  end subroutine rules_default

  !> Open the outputs in `dir`: fresh with headers, or appended to after a resume
  !> (public for a method that writes a row at once after it: it calls this first).
  subroutine open_default(self, dir, append, st)
    class(method_t), intent(inout) :: self
    character(len=*), intent(in) :: dir
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    call self%out%open(dir, append, st)
    self%writing = st%code == 0
  end subroutine open_default

  !> Flush (and, unless flush_only, close) the outputs.
  subroutine close_default(self, flush_only, st)
    class(method_t), intent(inout) :: self
    logical, intent(in) :: flush_only
    type(status_t), intent(inout) :: st
    call self%out%flush(st)
    if (flush_only) return
    call self%out%close(st)
    self%writing = .false.
  end subroutine close_default

  !> Names of the output files this scene writes (relative to the run directory).
  subroutine files_default(self, names, n)
    class(method_t), intent(in) :: self
    character(len=fname_len), intent(out) :: names(max_out_files)
    integer, intent(out) :: n
    call self%out%names(names, n)
  end subroutine files_default

  !> Units of work done and in the whole run, simulated time [method's time unit].
  subroutine counters_default(self, done, total, t)
    class(method_t), intent(in) :: self
    integer(i8), intent(out) :: done, total
    real(dp), intent(out) :: t
    done = self%step
    total = self%n_steps
    t = real(self%step, dp)*self%time_unit
  end subroutine counters_default

  !> Read the scene file only (file-level and type checks, no range
  !> validation), for resolving a scene as the engine reads it.
  subroutine read_default(self, path, st)
    class(method_t), intent(inout), target :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    call load_sequence(self, path, .false., st)
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
