!> Running a scene into a run directory: open the files, step with progress
!> lines, periodic checkpoints, SIGTERM/SIGINT handling, guards' final
!> checkpoint, run.json, and resuming from a checkpoint. Both doors (the
!> executable and the f2py module) go through sim_execute / sim_resume, so
!> they produce the same files for the same scene.
module runner
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_ok, exit_interrupted, exit_io
  use engine, only: sim_t, sim_load, sim_step, pairs_per_step
  use protocol, only: phase_names
  use output, only: output_open, output_close, output_flush, output_sizes, output_names, &
       write_run_json, make_dir, file_exists, remove_file, cfile_t, cf_open, cf_write, cf_close
  use scene, only: scene_text
  use, intrinsic :: iso_fortran_env, only: int8
  use checkpoint, only: checkpoint_write, checkpoint_read, truncate_file, file_crc64
  use signals, only: stop_requested, stop_signal
  implicit none
  private

  public :: sim_execute, sim_resume, run_files

  character(len=*), parameter :: ckpt_name = 'checkpoint.bin'
  character(len=*), parameter :: ckpt_failed = 'checkpoint_failed.bin'
  !> Every file a run writes into its directory (a directory holding any of
  !> them holds a run; --overwrite removes exactly these).
  character(len=*), parameter :: run_files(11) = [character(len=25) :: 'scene.nml', 'run.json', &
       '.run.json.tmp', 'piston.dat', 'particles.dat', 'mean_distance.dat', 'energy.dat', &
       'checkpoint.bin', 'checkpoint.bin.tmp', 'checkpoint_failed.bin', &
       'checkpoint_failed.bin.tmp']

contains

  !> The whole run: load (nothing written on bad input), open the run
  !> directory, run until the end (or step stop_at >= 0), finish. A
  !> directory that holds another run is refused unless overwrite, which
  !> removes that run's files first.
  subroutine sim_execute(path, dir, progress, stop_at, overwrite, st)
    character(len=*), intent(in) :: path, dir
    logical, intent(in) :: progress
    integer(i8), intent(in) :: stop_at   !< pause (checkpoint, exit 0) at this step; < 0: never
    logical, intent(in) :: overwrite
    type(status_t), intent(inout) :: st
    type(sim_t) :: sim
    integer(i8) :: hash
    integer :: k
    if (len_trim(dir) == 0) then
      call set_error(st, exit_io, 'the output directory name is empty')
      return
    end if
    call sim_load(sim, path, st)
    if (st%code /= 0) return
    sim%progress = progress
    sim%dir = trim(dir)
    do k = 1, size(run_files)
      if (.not. file_exists(trim(dir)//'/'//trim(run_files(k)))) cycle
      if (.not. overwrite) then
        call set_error(st, exit_io, trim(dir)//': holds another run ('//trim(run_files(k))// &
             '); choose a new directory, resume it, or pass --overwrite to replace it')
        return
      end if
      if (trim(run_files(k)) == 'scene.nml' .and. .not. is_resolved_scene(trim(dir)// &
           '/scene.nml')) then   ! e.g. the user's own input file: never removed
        call set_error(st, exit_io, trim(dir)//'/scene.nml: not a run''s resolved scene; '// &
             'refusing to remove it (choose another directory)')
        return
      end if
      call remove_file(trim(dir)//'/'//trim(run_files(k)), st)
      if (st%code /= 0) return
    end do
    call make_dir(dir, st)
    if (st%code /= 0) return
    call write_scene(trim(dir)//'/scene.nml', sim, st)
    if (st%code /= 0) return
    call file_crc64(trim(dir)//'/scene.nml', hash, st)
    if (st%code /= 0) return
    call open_files(sim, .false., st)
    if (st%code /= 0) return
    call save(sim, ckpt_name, hash, st)   ! step 0: a run killed at once resumes from here
    if (st%code /= 0) then
      call finish(sim, 'failed: '//trim(st%msg), st)
      return
    end if
    call run_loop(sim, stop_at, hash, st)
  end subroutine sim_execute

  !> Continue a run directory from its last checkpoint: the output files are
  !> cut back to their size at the checkpoint and appended to, so the result
  !> is byte-identical to an uninterrupted run. The checkpoint must match
  !> the run's scene.nml (hash), this engine and be intact (checksum). A run
  !> directory without checkpoint (killed before its first was on disk)
  !> starts again from step 0.
  subroutine sim_resume(dir, progress, stop_at, st)
    character(len=*), intent(in) :: dir
    logical, intent(in) :: progress
    integer(i8), intent(in) :: stop_at
    type(status_t), intent(inout) :: st
    type(sim_t) :: sim
    integer(i8) :: sizes(4), hash
    real(dp) :: wall
    integer :: k
    logical :: on(4)
    if (len_trim(dir) == 0) then
      call set_error(st, exit_io, 'the run directory name is empty')
      return
    end if
    if (.not. file_exists(trim(dir)//'/scene.nml')) then
      call set_error(st, exit_io, trim(dir)//': not a run directory (no scene.nml)')
      return
    end if
    call sim_load(sim, trim(dir)//'/scene.nml', st)
    if (st%code /= 0) return
    sim%progress = progress
    sim%dir = trim(dir)
    call file_crc64(trim(dir)//'/scene.nml', hash, st)
    if (st%code /= 0) return
    if (.not. file_exists(trim(dir)//'/'//ckpt_name)) then
      call open_files(sim, .false., st)
      if (st%code /= 0) return
      call save(sim, ckpt_name, hash, st)
      if (st%code /= 0) then
        call finish(sim, 'failed: '//trim(st%msg), st)
        return
      end if
      call run_loop(sim, stop_at, hash, st)
      return
    end if
    call checkpoint_read(trim(dir)//'/'//ckpt_name, trim(sim%sc%kind), hash, sim%s, sim%nl, &
         sizes, wall, sim%pst, st)
    if (st%code /= 0) return
    sim%wall_before = wall
    on = [sim%sc%piston_every > 0, sim%sc%frame_every > 0, sim%sc%distance_every > 0, &
         sim%sc%energy_every > 0]
    do k = 1, 4
      if (on(k)) call truncate_file(trim(dir)//'/'//trim(output_names(k)), sizes(k), st)
    end do
    if (st%code /= 0) return
    call open_files(sim, .true., st)
    if (st%code /= 0) return
    call run_loop(sim, stop_at, hash, st)
  end subroutine sim_resume

  !> Does the file start like a scene.nml written by a run?
  logical function is_resolved_scene(path)
    character(len=*), intent(in) :: path
    integer :: u, ios
    character(len=80) :: first
    is_resolved_scene = .false.
    open(newunit=u, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) return
    read(u, '(a)', iostat=ios) first
    close(u)
    is_resolved_scene = ios == 0 .and. index(first, '! resolved scene:') == 1
  end function is_resolved_scene

  !> The resolved scene of the run (checked write, fsync).
  subroutine write_scene(path, sim, st)
    character(len=*), intent(in) :: path
    type(sim_t), intent(in) :: sim
    type(status_t), intent(inout) :: st
    type(cfile_t) :: f
    call cf_open(f, path, 'w', st)
    call cf_write(f, transfer(scene_text(sim%sc), [0_int8]), st)
    call cf_close(f, st, sync=.true.)
  end subroutine write_scene

  subroutine open_files(sim, append, st)
    type(sim_t), intent(inout) :: sim
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    call output_open(sim%o, sim%dir, sim%m, sim%sc%piston_every > 0, sim%sc%frame_every > 0, &
         sim%sc%distance_every > 0, sim%sc%energy_every > 0, append, st)
    if (st%code /= 0) return
    sim%writing = .true.
    call system_clock(sim%clock0)
    call run_json(sim, 'running', st)
  end subroutine open_files

  real(dp) function wall_time(sim)
    type(sim_t), intent(in) :: sim
    integer(i8) :: c, rate
    call system_clock(c, rate)
    wall_time = sim%wall_before + real(c - sim%clock0, dp)/real(rate, dp)
  end function wall_time

  subroutine run_json(sim, status, st)
    type(sim_t), intent(in) :: sim
    character(len=*), intent(in) :: status
    type(status_t), intent(inout) :: st
    call write_run_json(sim%dir, sim%scene_path, status, st%code, trim(st%msg), sim%s%step, &
         sim%p%n_steps, sim%s%t, wall_time(sim), sim%m, sim%s%n, sim%nl%builds, &
         pairs_per_step(sim), sim%nl%evaluated, st)
  end subroutine run_json

  !> Checkpoint `name`, bound to the scene hash. The output files are
  !> flushed and fsynced first; if that fails no checkpoint is written (the
  !> previous one stays valid) and the write error is returned.
  subroutine save(sim, name, hash, st)
    type(sim_t), intent(inout) :: sim
    character(len=*), intent(in) :: name
    integer(i8), intent(in) :: hash
    type(status_t), intent(inout) :: st
    integer(i8) :: sizes(4)
    call output_sizes(sim%o, sizes)
    if (sim%o%st%code /= exit_ok) then
      call set_error(st, sim%o%st%code, trim(sim%o%st%msg))
      return
    end if
    call checkpoint_write(sim%dir//'/'//name, trim(sim%sc%kind), hash, sim%s, sim%nl, sizes, &
         wall_time(sim), sim%pst, st)
  end subroutine save

  !> Step to the end; checkpoints every checkpoint_every steps; stop cleanly
  !> on a guard (checkpoint_failed.bin), a signal or stop_at.
  subroutine run_loop(sim, stop_at, hash, st)
    type(sim_t), intent(inout) :: sim
    integer(i8), intent(in) :: stop_at
    integer(i8), intent(in) :: hash   !< scene hash the checkpoints are bound to
    type(status_t), intent(inout) :: st
    type(status_t) :: aux
    integer(i8) :: every
    character(len=200) :: buf
    every = sim%sc%checkpoint_every
    do while (sim%s%step < sim%p%n_steps)
      if (stop_at >= 0 .and. sim%s%step >= stop_at) then
        call save(sim, ckpt_name, hash, st)
        if (st%code /= 0) exit
        write(buf, '(a,i0,a)') 'paused at step ', sim%s%step, ' (resume with --resume)'
        call finish(sim, trim(buf), st)
        return
      end if
      call sim_step(sim, st)
      if (st%code == 0 .and. sim%o%st%code /= exit_ok) &
           call set_error(st, sim%o%st%code, trim(sim%o%st%msg))
      if (st%code == exit_io) exit   ! a failed write: keep the last good checkpoint
      if (st%code /= 0) then
        call save(sim, ckpt_failed, hash, aux)
        call finish(sim, 'failed: '//trim(st%msg), st)
        return
      end if
      if (sim%progress .and. mod(sim%s%step, sim%progress_every) == 0) call progress_line(sim)
      if (every > 0) then
        if (mod(sim%s%step, every) == 0 .and. sim%s%step < sim%p%n_steps) then
          call save(sim, ckpt_name, hash, st)
          if (st%code == 0) call run_json(sim, 'running', st)
          if (st%code /= 0) exit
        end if
      end if
      if (stop_requested) then
        call save(sim, ckpt_name, hash, aux)
        if (aux%code /= exit_ok) then   ! the interruption cannot be resumed from here
          call set_error(st, aux%code, trim(aux%msg))
          call finish(sim, 'failed: '//trim(st%msg), st)
          return
        end if
        write(buf, '(a,i0,a,i0,a)') 'signal ', stop_signal, ' at step ', &
             sim%s%step, ' (checkpoint written; resume with --resume)'
        call set_error(st, exit_interrupted, trim(buf))
        call finish(sim, 'interrupted: '//trim(buf), st)
        return
      end if
    end do
    if (st%code == 0) call sim_step(sim, st, final=.true.)
    if (st%code == 0 .and. sim%o%st%code /= exit_ok) &
         call set_error(st, sim%o%st%code, trim(sim%o%st%msg))
    if (st%code == 0) then
      call finish(sim, 'completed', st)
    else
      call finish(sim, 'failed: '//trim(st%msg), st)
    end if
  end subroutine run_loop

  subroutine progress_line(sim)
    type(sim_t), intent(in) :: sim
    write(output_unit, '(a,i0,1x,i0,1x,es12.5,1x,a,1x,es12.5)') 'progress ', sim%s%step, &
         sim%p%n_steps, sim%s%t, trim(phase_names(sim%s%phase)), sim%s%piston_force
    flush(output_unit)
  end subroutine progress_line

  !> Close the files and write the final run.json.
  subroutine finish(sim, status, st)
    type(sim_t), intent(inout) :: sim
    character(len=*), intent(in) :: status
    type(status_t), intent(inout) :: st
    type(status_t) :: st2
    if (.not. sim%writing) return
    call output_flush(sim%o)
    call output_close(sim%o)
    if (st%code == exit_ok .and. sim%o%st%code /= exit_ok) then
      ! the last rows could not be written: the run did not complete
      call set_error(st, sim%o%st%code, trim(sim%o%st%msg))
      st2 = st
      call run_json(sim, 'failed: '//trim(st%msg), st2)
      sim%writing = .false.
      return
    end if
    st2 = st
    call run_json(sim, status, st2)
    if (st%code == exit_ok .and. st2%code /= exit_ok) st = st2
    sim%writing = .false.
  end subroutine finish

end module runner
