!> Running any method into a run directory: refuse a directory that holds
!> another run (unless overwrite), write the resolved scene, open the
!> method's outputs, step with progress lines, checkpoint (step 0 and every
!> checkpoint_every units), stop cleanly on a guard (checkpoint_failed.bin),
!> a signal or --stop-at, write run.json; resume from a verified checkpoint
!> with the output files cut back to their checkpoint sizes (never padded),
!> so a resumed run is byte-identical to an uninterrupted one. Both doors
!> (executable and f2py module) go through sim_execute / sim_resume.
module runner
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_ok, exit_interrupted, exit_io
  use method, only: method_t, fname_len, max_out_files
  use methods, only: method_for_scene
  use scene_input, only: kind_len, read_kind
  use files, only: file_exists, remove_file, make_dir, truncate_file
  use ckpt, only: ckpt_write, ckpt_read, file_crc64
  use run_meta, only: write_run_json
  use signals, only: stop_requested, stop_signal
  implicit none
  private

  public :: sim_execute, sim_resume, sim_check

  character(len=*), parameter :: ckpt_name = 'checkpoint.bin'
  character(len=*), parameter :: ckpt_failed = 'checkpoint_failed.bin'
  !> Files of every run besides the method's outputs (--overwrite removes them too).
  character(len=*), parameter :: run_files(7) = [character(len=25) :: 'scene.nml', 'run.json', &
       '.run.json.tmp', 'checkpoint.bin', 'checkpoint.bin.tmp', 'checkpoint_failed.bin', &
       'checkpoint_failed.bin.tmp']

  !> What the runner keeps of one run.
  type :: run_t
    class(method_t), allocatable :: m
    character(len=kind_len) :: kind = ''
    character(len=:), allocatable :: dir, scene_path
    integer(i8) :: hash = 0               !< CRC-64 of the resolved scene.nml
    integer(i8) :: clock0 = 0             !< system_clock at this process' start
    real(dp) :: wall_before = 0           !< wall time of earlier segments [s]
    integer(i8) :: progress_every = 1
    logical :: progress = .false.
  end type run_t

contains

  !> Load and validate a scene (nothing written): units of work and a one-line summary.
  subroutine sim_check(path, total, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(out) :: total
    type(status_t), intent(inout) :: st
    class(method_t), allocatable :: m
    integer(i8) :: done
    real(dp) :: t
    total = 0
    call method_for_scene(path, m, st)
    if (st%code /= 0) return
    call m%load(path, st)
    if (st%code /= 0) return
    call m%counters(done, total, t)
  end subroutine sim_check

  !> The whole run: load (nothing written on bad input), open the run
  !> directory, run until the end (or unit stop_at >= 0), finish.
  subroutine sim_execute(path, dir, progress, stop_at, overwrite, st)
    character(len=*), intent(in) :: path, dir
    logical, intent(in) :: progress
    integer(i8), intent(in) :: stop_at   !< pause (checkpoint, exit 0) here; < 0: never
    logical, intent(in) :: overwrite     !< replace a run already in dir
    type(status_t), intent(inout) :: st
    type(run_t) :: r
    if (len_trim(dir) == 0) then
      call set_error(st, exit_io, 'the output directory name is empty')
      return
    end if
    call load(r, path, st)
    if (st%code /= 0) return
    r%dir = trim(dir)
    r%progress = progress
    call clear_dir(r, overwrite, st)
    if (st%code /= 0) return
    call make_dir(r%dir, st)
    if (st%code /= 0) return
    call r%m%write_scene(r%dir//'/scene.nml', st)
    if (st%code /= 0) return
    call file_crc64(r%dir//'/scene.nml', r%hash, st)
    if (st%code /= 0) return
    call start(r, .false., st)
    if (st%code /= 0) return
    call save(r, ckpt_name, st)      ! step 0: a run killed at once resumes from here
    if (st%code /= 0) then
      call finish(r, 'failed: '//trim(st%msg), st)
      return
    end if
    call run_loop(r, stop_at, st)
  end subroutine sim_execute

  !> Continue a run directory from its last checkpoint. The checkpoint must
  !> be intact (checksum), of this engine and kind, and bound to the run's
  !> scene.nml (hash); every output file must be at least as long as at the
  !> checkpoint (it is cut back, never padded).
  subroutine sim_resume(dir, progress, stop_at, st)
    character(len=*), intent(in) :: dir
    logical, intent(in) :: progress
    integer(i8), intent(in) :: stop_at
    type(status_t), intent(inout) :: st
    type(run_t) :: r
    character(len=fname_len) :: names(max_out_files), now(max_out_files)
    integer(i8) :: sizes(max_out_files), done
    integer :: k, nfiles, nnow
    if (len_trim(dir) == 0) then
      call set_error(st, exit_io, 'the run directory name is empty')
      return
    end if
    if (.not. file_exists(trim(dir)//'/scene.nml')) then
      call set_error(st, exit_io, trim(dir)//': not a run directory (no scene.nml)')
      return
    end if
    call load(r, trim(dir)//'/scene.nml', st)
    if (st%code /= 0) return
    r%dir = trim(dir)
    r%progress = progress
    call file_crc64(r%dir//'/scene.nml', r%hash, st)
    if (st%code /= 0) return
    call ckpt_read(r%dir//'/'//ckpt_name, r%kind, r%hash, r%wall_before, done, names, sizes, &
         nfiles, r%m, st)
    if (st%code /= 0) return
    call r%m%output_files(now, nnow)
    if (nnow /= nfiles .or. any(now(1:nnow) /= names(1:nfiles))) then
      call set_error(st, exit_io, r%dir//'/'//ckpt_name//': lists other output files than '// &
           'the scene writes')
      return
    end if
    do k = 1, nfiles
      call truncate_file(r%dir//'/'//trim(names(k)), sizes(k), st)
    end do
    if (st%code /= 0) return
    call start(r, .true., st)
    if (st%code /= 0) return
    call run_loop(r, stop_at, st)
  end subroutine sim_resume

  subroutine load(r, path, st)
    type(run_t), intent(inout) :: r
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer(i8) :: done, total
    real(dp) :: t
    call read_kind(path, r%kind, st)
    if (st%code /= 0) return
    call method_for_scene(path, r%m, st)
    if (st%code /= 0) return
    r%scene_path = trim(path)
    call r%m%load(path, st)
    if (st%code /= 0) return
    call r%m%counters(done, total, t)
    r%progress_every = r%m%progress_every
    if (r%progress_every <= 0) r%progress_every = max(1_i8, total/200)
  end subroutine load

  !> A directory holding another run is refused unless overwrite, which
  !> removes exactly that run's files (the method's outputs and the runner's).
  subroutine clear_dir(r, overwrite, st)
    type(run_t), intent(inout) :: r
    logical, intent(in) :: overwrite
    type(status_t), intent(inout) :: st
    character(len=fname_len) :: names(max_out_files)
    integer :: k, n
    call r%m%output_files(names, n)
    do k = 1, size(run_files) + n
      if (k <= size(run_files)) then
        call one(trim(run_files(k)))
      else
        call one(trim(names(k - size(run_files))))
      end if
      if (st%code /= 0) return
    end do
  contains
    subroutine one(name)
      character(len=*), intent(in) :: name
      if (.not. file_exists(r%dir//'/'//name)) return
      if (.not. overwrite) then
        call set_error(st, exit_io, r%dir//': holds another run ('//name//'); choose a new '// &
             'directory, resume it, or pass --overwrite to replace it')
        return
      end if
      call remove_file(r%dir//'/'//name, st)
    end subroutine one
  end subroutine clear_dir

  subroutine start(r, append, st)
    type(run_t), intent(inout) :: r
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    call r%m%open_outputs(r%dir, append, st)
    if (st%code /= 0) return
    call system_clock(r%clock0)
    call run_json(r, 'running', st)
  end subroutine start

  real(dp) function wall_time(r)
    type(run_t), intent(in) :: r
    integer(i8) :: c, rate
    call system_clock(c, rate)
    wall_time = r%wall_before + real(c - r%clock0, dp)/real(rate, dp)
  end function wall_time

  subroutine run_json(r, status, st)
    type(run_t), intent(in) :: r
    character(len=*), intent(in) :: status
    type(status_t), intent(inout) :: st
    integer(i8) :: done, total
    real(dp) :: t
    call r%m%counters(done, total, t)
    call write_run_json(r%dir, r%m, r%kind, r%scene_path, status, st%code, trim(st%msg), done, &
         total, t, wall_time(r), st)
  end subroutine run_json

  !> Checkpoint `name` after flushing the outputs; if the flush fails no
  !> checkpoint is written (the previous one stays valid).
  subroutine save(r, name, st)
    type(run_t), intent(inout) :: r
    character(len=*), intent(in) :: name
    type(status_t), intent(inout) :: st
    character(len=fname_len) :: names(max_out_files)
    integer(i8) :: sizes(max_out_files), done, total
    integer :: k, n
    real(dp) :: t
    call r%m%close_outputs(.true., st)
    if (st%code /= 0) return
    call r%m%output_files(names, n)
    do k = 1, n
      inquire(file=r%dir//'/'//trim(names(k)), size=sizes(k))
    end do
    call r%m%counters(done, total, t)
    call ckpt_write(r%dir//'/'//name, r%kind, r%hash, wall_time(r), done, names(1:n), &
         sizes(1:n), r%m, st)
  end subroutine save

  !> Advance to the end; checkpoints; clean stops on a guard, a signal or stop_at.
  subroutine run_loop(r, stop_at, st)
    type(run_t), intent(inout) :: r
    integer(i8), intent(in) :: stop_at
    type(status_t), intent(inout) :: st
    type(status_t) :: aux
    integer(i8) :: done, total
    real(dp) :: t
    character(len=200) :: buf
    do
      call r%m%counters(done, total, t)
      if (done >= total) exit
      if (stop_at >= 0 .and. done >= stop_at) then
        call save(r, ckpt_name, st)
        if (st%code /= 0) exit
        write(buf, '(a,i0,a)') 'paused at step ', done, ' (resume with --resume)'
        call finish(r, trim(buf), st)
        return
      end if
      call r%m%advance(st)
      if (st%code == exit_io) exit     ! a failed write: keep the last good checkpoint
      if (st%code /= 0) then
        call save(r, ckpt_failed, aux)
        call finish(r, 'failed: '//trim(st%msg), st)
        return
      end if
      call r%m%counters(done, total, t)
      if (r%progress .and. mod(done, r%progress_every) == 0) call progress_line(r)
      if (r%m%checkpoint_every > 0) then
        if (mod(done, r%m%checkpoint_every) == 0 .and. done < total) then
          call save(r, ckpt_name, st)
          if (st%code == 0) call run_json(r, 'running', st)
          if (st%code /= 0) exit
        end if
      end if
      if (stop_requested) then
        call save(r, ckpt_name, aux)
        if (aux%code /= exit_ok) then  ! the interruption cannot be resumed from here
          call set_error(st, aux%code, trim(aux%msg))
          call finish(r, 'failed: '//trim(st%msg), st)
          return
        end if
        write(buf, '(a,i0,a,i0,a)') 'signal ', stop_signal, ' at step ', done, &
             ' (checkpoint written; resume with --resume)'
        call set_error(st, exit_interrupted, trim(buf))
        call finish(r, 'interrupted: '//trim(buf), st)
        return
      end if
    end do
    if (st%code == 0) call r%m%finish(st)
    if (st%code == 0) then
      call finish(r, 'completed', st)
    else
      call finish(r, 'failed: '//trim(st%msg), st)
    end if
  end subroutine run_loop

  subroutine progress_line(r)
    type(run_t), intent(in) :: r
    integer(i8) :: done, total
    real(dp) :: t
    call r%m%counters(done, total, t)
    write(output_unit, '(a,i0,1x,i0,1x,es12.5,1x,a)') 'progress ', done, total, t, &
         r%m%progress_text()
    flush(output_unit)
  end subroutine progress_line

  !> Close the outputs and write the final run.json. A failed close (the
  !> last rows not on disk) turns a completed run into a failed one.
  subroutine finish(r, status, st)
    type(run_t), intent(inout) :: r
    character(len=*), intent(in) :: status
    type(status_t), intent(inout) :: st
    type(status_t) :: st2
    if (.not. r%m%writing) return
    st2 = st
    call r%m%close_outputs(.false., st2)
    if (st%code == exit_ok .and. st2%code /= exit_ok) then
      st = st2
      call run_json(r, 'failed: '//trim(st%msg), st2)
      return
    end if
    st2 = st
    call run_json(r, status, st2)
    if (st%code == exit_ok .and. st2%code /= exit_ok) st = st2
  end subroutine finish

end module runner
