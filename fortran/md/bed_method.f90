!> Kind 'magnet_bed' behind the runner's interface (module method): the
!> time-stepped MD engine of the magnetic granular bed (module engine) with
!> its outputs (module output) and checkpoint payload (module checkpoint).
!> Units: length D1, time T = sqrt(D1/g), mass m1, force m1 g.
module bed_method
  use kinds, only: dp, i8
  use errors, only: status_t
  use method, only: method_t, fname_len, max_out_files
  use engine, only: sim_t, sim_load, sim_step, pairs_per_step
  use protocol, only: phase_names
  use scene, only: scene_write
  use output, only: output_open, output_close, output_flush, output_names
  use checkpoint, only: checkpoint_save, checkpoint_restore
  implicit none
  private

  public :: bed_t

  type, extends(method_t) :: bed_t
    type(sim_t) :: sim
  contains
    procedure :: load, write_scene, open_outputs, advance, finish, close_outputs, output_files
    procedure :: save_state, restore_state, counters, progress_text, json_fields
  end type bed_t

  character(len=*), parameter :: rfmt = 'es24.16e3'

contains

  subroutine load(self, path, st)
    class(bed_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    call sim_load(self%sim, path, st)
    if (st%code /= 0) return
    self%checkpoint_every = self%sim%sc%checkpoint_every
    self%progress_every = self%sim%sc%progress_every
  end subroutine load

  subroutine write_scene(self, path, st)
    class(bed_t), intent(in) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    call scene_write(path, self%sim%sc, st)
  end subroutine write_scene

  subroutine open_outputs(self, dir, append, st)
    class(bed_t), intent(inout) :: self
    character(len=*), intent(in) :: dir
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    associate (sc => self%sim%sc)
      call output_open(self%sim%o, dir, self%sim%m, sc%piston_every > 0, sc%frame_every > 0, &
           sc%distance_every > 0, sc%energy_every > 0, append, st)
    end associate
    if (st%code /= 0) return
    self%sim%writing = .true.
    self%writing = .true.
  end subroutine open_outputs

  subroutine advance(self, st)
    class(bed_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call sim_step(self%sim, st)
  end subroutine advance

  subroutine finish(self, st)
    class(bed_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call sim_step(self%sim, st, final=.true.)
  end subroutine finish

  subroutine close_outputs(self, flush_only, st)
    class(bed_t), intent(inout) :: self
    logical, intent(in) :: flush_only
    type(status_t), intent(inout) :: st
    call output_flush(self%sim%o)
    if (flush_only) return
    call output_close(self%sim%o)
    self%sim%writing = .false.
    self%writing = .false.
  end subroutine close_outputs

  subroutine output_files(self, names, n)
    class(bed_t), intent(in) :: self
    character(len=fname_len), intent(out) :: names(max_out_files)
    integer, intent(out) :: n
    logical :: on(4)
    integer :: k
    associate (sc => self%sim%sc)
      on = [sc%piston_every > 0, sc%frame_every > 0, sc%distance_every > 0, sc%energy_every > 0]
    end associate
    names = ''
    n = 0
    do k = 1, 4
      if (.not. on(k)) cycle
      n = n + 1
      names(n) = output_names(k)
    end do
  end subroutine output_files

  subroutine save_state(self, u, st)
    class(bed_t), intent(in) :: self
    integer, intent(in) :: u
    type(status_t), intent(inout) :: st
    call checkpoint_save(u, self%sim%s, self%sim%nl, self%sim%pst, st)
  end subroutine save_state

  subroutine restore_state(self, u, st)
    class(bed_t), intent(inout) :: self
    integer, intent(in) :: u
    type(status_t), intent(inout) :: st
    call checkpoint_restore(u, self%sim%s, self%sim%nl, self%sim%pst, st)
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

  subroutine json_fields(self, u)
    class(bed_t), intent(in) :: self
    integer, intent(in) :: u
    associate (m => self%sim%m, sim => self%sim)
      write(u, '(a,i0,a)') '  "n_particles": ', sim%s%n, ','
      write(u, '(a,i0,a)') '  "list_builds": ', sim%nl%builds, ','
      write(u, '(a,i0,a)') '  "pairs_per_step": ', pairs_per_step(sim), ','
      write(u, '(a,i0,a)') '  "pair_evaluations": ', sim%nl%evaluated, ','
      write(u, '(a)') '  "units": {'
      write(u, '(a,'//rfmt//',a)') '    "length_m": ', m%length_unit, ','
      write(u, '(a,'//rfmt//',a)') '    "time_s": ', m%time_unit, ','
      write(u, '(a,'//rfmt//',a)') '    "mass_kg": ', m%mass_unit, ','
      write(u, '(a,'//rfmt//',a)') '    "force_N": ', m%force_unit, ','
      write(u, '(a,'//rfmt//')') '    "moment_Am2": ', m%moment_unit
      write(u, '(a)') '  },'
      write(u, '(a)') '  "groups": {'
      write(u, '(a,'//rfmt//',a)') '    "F": ', m%big_f, ','
      write(u, '(a,'//rfmt//')') '    "G": ', m%big_g
      write(u, '(a)') '  },'
    end associate
  end subroutine json_fields

end module bed_method
