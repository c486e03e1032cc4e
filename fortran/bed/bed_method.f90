!> Kind 'magnet_bed' behind the runner's interface (module method): the
!> time-stepped MD engine of the magnetic granular bed (module engine) with
!> its outputs (module output) and checkpoint payload (module checkpoint).
!> Units: length D1, time T = sqrt(D1/g), mass m1, force m1 g.
module bed_method
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_ok
  use method, only: method_t, fname_len, max_out_files
  use ckpt, only: ckpt_writer_t, ckpt_put
  use start_file, only: start_json, check_start_crc
  use, intrinsic :: iso_fortran_env, only: int8
  use scene_input, only: int_str, json_real
  use engine, only: sim_t, sim_load, sim_step, pairs_per_step, sim_note_mu
  use protocol, only: phase_names
  use scene, only: scene_keys
  use nlist_upkeep, only: nlist_prune_json
  use pair_table, only: table_json
  use schema, only: schema_t
  use output, only: output_declare
  use output_set, only: frames_as
  use checkpoint, only: checkpoint_save, checkpoint_restore
  implicit none
  private

  public :: bed_t

  type, extends(method_t) :: bed_t
    type(sim_t) :: sim
  contains
    procedure :: load, keys, setup, open_outputs, advance, finish, close_outputs, output_files
    procedure :: save_state, restore_state, counters, progress_text, json_fields
  end type bed_t


contains

  subroutine load(self, path, st)
    class(bed_t), intent(inout), target :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    call sim_load(self%sim, path, st)
    if (st%code /= 0) return
    call self%setup(path, st)
  end subroutine load

  !> After the engine's load: the runner's cadences and the outputs.
  subroutine setup(self, path, st)
    class(bed_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    associate (sc => self%sim%sc)
      self%checkpoint_every = sc%checkpoint_every
      self%progress_every = sc%progress_every
      call output_declare(self%sim%o, self%sim%m, sc%piston_every > 0, &
           frames_as(int(sc%frame_every, i8), sc%frames_format, 'text'), sc%distance_every > 0, &
           sc%energy_every > 0, frames_as(int(sc%frame_every, i8), sc%frames_format, 'binary'), &
           self%sim%s%n)
    end associate
  end subroutine setup

  !> The bed's scene declaration (module scene), bound to this run's scene.
  subroutine keys(self, s)
    class(bed_t), intent(inout), target :: self
    type(schema_t), intent(inout) :: s
    call scene_keys(self%sim%sc, s)
  end subroutine keys

  !> A failed write recorded by the bed's outputs becomes the run's status.
  subroutine output_status(self, st)
    class(bed_t), intent(in) :: self
    type(status_t), intent(inout) :: st
    if (st%code == exit_ok .and. self%sim%o%st%code /= exit_ok) &
         call set_error(st, self%sim%o%st%code, trim(self%sim%o%st%msg))
  end subroutine output_status

  subroutine open_outputs(self, dir, append, st)
    class(bed_t), intent(inout) :: self
    character(len=*), intent(in) :: dir
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    self%sim%o%st = status_t()
    call self%sim%o%set%open(dir, append, st)
    if (st%code /= 0) return
    self%sim%writing = .true.
    self%writing = .true.
  end subroutine open_outputs

  subroutine advance(self, st)
    class(bed_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call sim_step(self%sim, st)
    call output_status(self, st)
  end subroutine advance

  subroutine finish(self, st)
    class(bed_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call sim_step(self%sim, st, final=.true.)
    call output_status(self, st)
  end subroutine finish

  subroutine close_outputs(self, flush_only, st)
    class(bed_t), intent(inout) :: self
    logical, intent(in) :: flush_only
    type(status_t), intent(inout) :: st
    call self%sim%o%set%flush(st)
    if (.not. flush_only) then
      call self%sim%o%set%close(st)
      self%sim%writing = .false.
      self%writing = .false.
    end if
    call output_status(self, st)
  end subroutine close_outputs

  subroutine output_files(self, names, n)
    class(bed_t), intent(in) :: self
    character(len=fname_len), intent(out) :: names(max_out_files)
    integer, intent(out) :: n
    call self%sim%o%set%names(names, n)
  end subroutine output_files

  !> The MD payload, then the CRC-64 of the start file (0 without one): a resume refuses a
  !> start file that changed since the run began (the scene names it, its bytes are bound).
  subroutine save_state(self, w)
    class(bed_t), intent(in) :: self
    type(ckpt_writer_t), intent(inout) :: w
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    call checkpoint_save(w, self%sim%s, self%sim%nl, self%sim%pst)
    call ckpt_put(w, transfer(self%sim%start%crc, b))
  end subroutine save_state

  subroutine restore_state(self, u, st)
    class(bed_t), intent(inout) :: self
    integer, intent(in) :: u
    type(status_t), intent(inout) :: st
    call checkpoint_restore(u, self%sim%s, self%sim%nl, self%sim%pst, st)
    if (st%code /= 0) return
    call sim_note_mu(self%sim)
    call check_start_crc(u, self%sim%start, st)
  end subroutine restore_state

  subroutine counters(self, done, total, t)
    class(bed_t), intent(in) :: self
    integer(i8), intent(out) :: done, total
    real(dp), intent(out) :: t
    done = self%sim%s%step
    total = self%sim%p%n_steps
    t = self%sim%s%t
  end subroutine counters

  function progress_text(self) result(s)
    class(bed_t), intent(in) :: self
    character(len=:), allocatable :: s
    character(len=16) :: buf
    write(buf, '(es12.5)') self%sim%s%piston_force
    s = trim(phase_names(self%sim%s%phase))//' '//trim(adjustl(buf))
  end function progress_text

  function json_fields(self) result(text)
    class(bed_t), intent(in) :: self
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = achar(10)
    associate (m => self%sim%m, sim => self%sim)
      text = '  "n_particles": '//int_str(int(sim%s%n, i8))//','//nl// &
           '  "species_counts": '//counts()//','//nl//start_json(sim%start)// &
           '  "list_builds": '//int_str(sim%nl%builds)//','//nl//nlist_prune_json(sim%nl)// &
           '  "pairs_per_step": '//int_str(pairs_per_step(sim))//','//nl// &
           '  "pair_evaluations": '//int_str(sim%nl%evaluated)//','//nl// &
           table_json(m%tab)// &
           '  "units": {'//nl// &
           '    "length_m": '//json_real(m%length_unit)//','//nl// &
           '    "time_s": '//json_real(m%time_unit)//','//nl// &
           '    "mass_kg": '//json_real(m%mass_unit)//','//nl// &
           '    "force_N": '//json_real(m%force_unit)//','//nl// &
           '    "moment_Am2": '//json_real(m%moment_unit)//nl// &
           '  },'//nl// &
           '  "groups": {'//nl// &
           '    "F": '//json_real(m%big_f)//','//nl// &
           '    "G": '//json_real(m%big_g)//nl// &
           '  },'//nl
    end associate
  contains
    !> Particles placed of each species (the composition realised), e.g. [200, 200].
    function counts() result(t)
      character(len=:), allocatable :: t
      integer :: k
      t = '['
      do k = 1, self%sim%m%n_species
        if (k > 1) t = t//', '
        t = t//int_str(int(count(self%sim%s%species(1:self%sim%s%n) == k), i8))
      end do
      t = t//']'
    end function counts
  end function json_fields

end module bed_method
