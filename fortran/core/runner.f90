!> Running any method into a run directory: refuse a directory that holds
!> another run (unless overwrite), write the resolved scene, open the
!> method's outputs, step with progress lines, checkpoint (step 0 and every
!> checkpoint_every units), stop cleanly on a guard (checkpoint_failed.bin),
!> a signal or --stop-at, write run.json; resume from a verified checkpoint
!> with the output files cut back to their checkpoint sizes (never padded),
!> so a resumed run is byte-identical to an uninterrupted one. A checkpoint
!> is bound to its outputs: it records each output's size and the CRC-64 of
!> its bytes up to that size (kept incrementally: a checkpoint reads only
!> the bytes written since the previous one), and a resume verifies every
!> output (exists, long enough, same prefix CRC) before it cuts any. Both
!> doors (executable and f2py module) go through sim_execute / sim_resume.
module runner
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_ok, exit_interrupted, exit_io
  use method, only: method_t, fname_len, max_out_files
  use methods, only: method_for_scene, method_for_kind
  use schema, only: schema_t
  use, intrinsic :: iso_fortran_env, only: int8, int32
  use scene_input, only: kind_len, read_text
  use files, only: file_exists, remove_file, make_dir, truncate_file, cfile_t, cf_open, &
       cf_write, cf_close
  use ckpt, only: ckpt_writer_t, ckpt_begin, ckpt_put, ckpt_commit, ckpt_open, ckpt_close, &
       file_crc64, file_crc64_extend, crc64
  use run_meta, only: write_run_json
  use signals, only: stop_requested, stop_signal
  implicit none
  private

  public :: sim_execute, sim_resume, sim_check, sim_resolve, sim_describe, write_text

  character(len=*), parameter :: ckpt_name = 'checkpoint.bin'
  character(len=*), parameter :: ckpt_failed = 'checkpoint_failed.bin'
  !> Files of every run besides the method's outputs (--overwrite removes them too).
  character(len=*), parameter :: run_files(8) = [character(len=25) :: 'scene.nml', 'run.json', &
       '.run.json.tmp', 'checkpoint.bin', 'checkpoint.bin.tmp', 'checkpoint_failed.bin', &
       'checkpoint_failed.bin.tmp', '.outputs']
  !> The output files of the run in a directory, one name a line (what --overwrite removes).
  character(len=*), parameter :: outputs_list = '.outputs'

  !> What the runner keeps of one run.
  type :: run_t
    class(method_t), allocatable :: m
    character(len=kind_len) :: kind = ''
    character(len=:), allocatable :: dir, scene_path
    integer(i8) :: hash = 0               !< CRC-64 of the resolved scene.nml
    integer(i8) :: run_id = 0             !< random at a fresh start, kept by resumes
    !> per output file (output_files order): bytes covered by out_crc, and the
    !> CRC-64 of the file's first out_bytes bytes (extended at each checkpoint)
    integer(i8) :: out_bytes(max_out_files) = 0, out_crc(max_out_files) = 0
    integer(i8) :: clock0 = 0             !< system_clock at this process' start
    real(dp) :: wall_before = 0           !< wall time of earlier segments [s]
    integer(i8) :: progress_every = 1
    logical :: progress = .false.
  end type run_t

contains

  !> Load and validate a scene (nothing written): units of work and a one-line summary.
  !> The declaration of kind `kind`'s scene: a Markdown table of every group and
  !> key (type, default, allowed values, unit, meaning), or JSON when `as_json`.
  subroutine sim_describe(kind, as_json, text, st)
    character(len=*), intent(in) :: kind
    logical, intent(in) :: as_json
    character(len=:), allocatable, intent(out) :: text
    type(status_t), intent(inout) :: st
    class(method_t), allocatable :: m
    type(schema_t) :: s
    text = ''
    call method_for_kind(kind, m, st)
    if (st%code /= 0) return
    call m%keys(s)
    if (as_json) then
      text = s%json()
    else
      text = s%describe()
    end if
  end subroutine sim_describe

  subroutine sim_check(path, total, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(out) :: total
    type(status_t), intent(inout) :: st
    class(method_t), allocatable :: m
    integer(i8) :: done
    real(dp) :: t
    character(len=kind_len) :: kind
    total = 0
    call method_for_scene(path, m, kind, st)
    if (st%code /= 0) return
    call m%load(path, st)
    if (st%code /= 0) return
    call m%counters(done, total, t)
  end subroutine sim_check

  !> The engine's one reading of a scene file, for pyorch: read `path` (its
  !> kind's groups, keys and types; no range validation) and write it back to
  !> `outpath` in the resolved-scene format (every key, as understood).
  subroutine sim_resolve(path, outpath, st)
    character(len=*), intent(in) :: path, outpath
    type(status_t), intent(inout) :: st
    class(method_t), allocatable :: m
    character(len=kind_len) :: kind
    call method_for_scene(path, m, kind, st)
    if (st%code /= 0) return
    call m%read(path, st)
    if (st%code /= 0) return
    call write_text(outpath, m%scene_text(), st)
  end subroutine sim_resolve

  !> A whole text file through the checked layer (fsync before close).
  subroutine write_text(path, text, st)
    character(len=*), intent(in) :: path, text
    type(status_t), intent(inout) :: st
    type(cfile_t) :: f
    call cf_open(f, path, 'w', st)
    call cf_write(f, transfer(text, [0_int8]), st)
    call cf_close(f, st, sync=.true.)
  end subroutine write_text

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
    r%run_id = new_run_id()
    call clear_dir(r, overwrite, st)
    if (st%code /= 0) return
    call make_dir(r%dir, st)
    if (st%code /= 0) return
    call write_text(r%dir//'/'//outputs_list, outputs_text(r), st)
    if (st%code /= 0) return
    call write_text(r%dir//'/scene.nml', r%m%scene_text(), st)
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
  !> scene.nml (hash); every output file must exist, be at least as long as
  !> at the checkpoint and hold the bytes the checkpoint recorded (CRC-64 of
  !> its first `size` bytes). All of that is checked before any file is
  !> touched: a refused resume leaves the directory as it was. Then the
  !> outputs are cut back (never padded) and continued.
  subroutine sim_resume(dir, progress, stop_at, st)
    character(len=*), intent(in) :: dir
    logical, intent(in) :: progress
    integer(i8), intent(in) :: stop_at
    type(status_t), intent(inout) :: st
    type(run_t) :: r
    character(len=fname_len) :: names(max_out_files), now(max_out_files)
    integer(i8) :: sizes(max_out_files), crcs(max_out_files)
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
    if (.not. file_exists(r%dir//'/'//ckpt_name)) then
      ! killed before the step-0 checkpoint was on disk: start again from step 0
      r%run_id = new_run_id()
      call start(r, .false., st)
      if (st%code /= 0) return
      call save(r, ckpt_name, st)
      if (st%code /= 0) then
        call finish(r, 'failed: '//trim(st%msg), st)
        return
      end if
      call run_loop(r, stop_at, st)
      return
    end if
    call restore(r, names, sizes, crcs, nfiles, st)
    if (st%code /= 0) return
    call r%m%output_files(now, nnow)
    if (nnow /= nfiles .or. any(now(1:nnow) /= names(1:nfiles))) then
      call set_error(st, exit_io, r%dir//'/'//ckpt_name//': refused: lists other output '// &
           'files than the scene writes')
      return
    end if
    do k = 1, nfiles      ! every file verified before any is cut
      call verify_output(r%dir, trim(names(k)), sizes(k), crcs(k), st)
      if (st%code /= 0) return
    end do
    do k = 1, nfiles
      call truncate_file(r%dir//'/'//trim(names(k)), sizes(k), st)
      if (st%code /= 0) return
    end do
    r%out_bytes(1:nfiles) = sizes(1:nfiles)
    r%out_crc(1:nfiles) = crcs(1:nfiles)
    call start(r, .true., st)
    if (st%code /= 0) return
    call run_loop(r, stop_at, st)
  end subroutine sim_resume

  !> An output file a checkpoint recorded with `size` bytes and the CRC-64
  !> `crc` of them: it must exist (unless size 0), be at least that long and
  !> start with those bytes. Reads only; the message names the file.
  subroutine verify_output(dir, name, size, crc, st)
    character(len=*), intent(in) :: dir, name
    integer(i8), intent(in) :: size, crc
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: path
    integer(i8) :: now, c
    character(len=64) :: b
    path = dir//'/'//name
    if (.not. file_exists(path)) then
      if (size > 0) call set_error(st, exit_io, path//': missing output file to resume')
      return
    end if
    inquire(file=path, size=now)
    if (now < size) then
      write(b, '(i0,a,i0)') now, ' bytes, the checkpoint recorded ', size
      call set_error(st, exit_io, path//': refused: shorter than at the checkpoint ('// &
           trim(b)//'); the run directory is damaged')
      return
    end if
    c = 0
    call file_crc64_extend(path, 0_i8, size, c, st)
    if (st%code /= 0) return
    if (c /= crc) then
      write(b, '(i0)') size
      call set_error(st, exit_io, path//': refused: output '//name//' does not belong to '// &
           'this checkpoint: its first '//trim(b)//' bytes differ from those '//ckpt_name// &
           ' recorded (CRC-64): the file was changed, or the checkpoint comes from another run')
    end if
  end subroutine verify_output

  !> A random 64-bit run id (/dev/urandom; else clock and process id mixed by CRC-64).
  integer(i8) function new_run_id() result(id)
    integer :: u, ios
    integer(i8) :: c
    id = 0
    open(newunit=u, file='/dev/urandom', access='stream', form='unformatted', status='old', &
         action='read', iostat=ios)
    if (ios == 0) then
      read(u, iostat=ios) id
      close(u)
    end if
    if (ios /= 0 .or. id == 0) then
      call system_clock(c)
      id = 0
      call crc64(id, transfer([c, int(getpid(), i8)], [0_int8]))
    end if
  end function new_run_id

  subroutine load(r, path, st)
    type(run_t), intent(inout) :: r
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer(i8) :: done, total
    real(dp) :: t
    call method_for_scene(path, r%m, r%kind, st)
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
    character(len=:), allocatable :: text
    integer :: k, n, a, b
    if (overwrite .and. file_exists(r%dir//'/scene.nml')) then
      if (.not. is_resolved_scene(r%dir//'/scene.nml')) then
        call set_error(st, exit_io, r%dir//'/scene.nml: not a run''s resolved scene; '// &
             'refusing to remove it (choose another directory)')
        return
      end if
    end if
    call r%m%output_files(names, n)
    do k = 1, n
      call one(trim(names(k)))
      if (st%code /= 0) return
    end do
    ! the earlier run's outputs, as it listed them (another kind, other cadences)
    if (file_exists(r%dir//'/'//outputs_list)) then
      call read_text(r%dir//'/'//outputs_list, text, st)
      if (st%code /= 0) return
      a = 1
      do while (a <= len(text))
        b = index(text(a:), achar(10))
        if (b == 0) b = len(text) - a + 2
        if (b > 1) then
          if (index(text(a:a + b - 2), '/') == 0) call one(text(a:a + b - 2))
        end if
        if (st%code /= 0) return
        a = a + b
      end do
    end if
    do k = 1, size(run_files)
      call one(trim(run_files(k)))
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

  !> The names of the run's output files, one a line.
  function outputs_text(r) result(text)
    type(run_t), intent(in) :: r
    character(len=:), allocatable :: text
    character(len=fname_len) :: names(max_out_files)
    integer :: k, n
    call r%m%output_files(names, n)
    text = ''
    do k = 1, n
      text = text//trim(names(k))//achar(10)
    end do
  end function outputs_text

  !> A scene.nml written by the engine (its first line says so).
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
    call write_run_json(r%dir, r%m, r%kind, r%scene_path, r%run_id, status, st%code, &
         trim(st%msg), done, total, t, wall_time(r), st)
  end subroutine run_json

  !> Checkpoint `name` after flushing the outputs; if the flush fails no
  !> checkpoint is written (the previous one stays valid). The runner's
  !> record (wall time, units done, run id, output names, sizes and prefix
  !> CRC-64s) comes first, then the method's payload.
  subroutine save(r, name, st)
    type(run_t), intent(inout) :: r
    character(len=*), intent(in) :: name
    type(status_t), intent(inout) :: st
    character(len=fname_len) :: names(max_out_files)
    integer(i8) :: done, total
    integer :: n
    real(dp) :: t
    type(ckpt_writer_t) :: w
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    call r%m%close_outputs(.true., st)
    if (st%code /= 0) return
    call r%m%output_files(names, n)
    call extend_crcs(r, names, n, st)
    if (st%code /= 0) return
    call r%m%counters(done, total, t)
    call ckpt_begin(w, r%dir//'/'//name)
    call ckpt_put(w, [transfer(wall_time(r), b), transfer(done, b), transfer(r%run_id, b), &
         transfer(int(n, int32), b)])
    if (n > 0) then
      call ckpt_put(w, transfer(names(1:n), b))
      call ckpt_put(w, transfer(r%out_bytes(1:n), b))
      call ckpt_put(w, transfer(r%out_crc(1:n), b))
    end if
    call r%m%save_state(w)
    call ckpt_commit(w, r%kind, r%hash, st)
  end subroutine save

  !> Bring each output's prefix CRC up to its present size, reading only the
  !> bytes written since the last checkpoint (the files only grow between
  !> checkpoints; one found shorter is checksummed again from its start).
  subroutine extend_crcs(r, names, n, st)
    type(run_t), intent(inout) :: r
    character(len=fname_len), intent(in) :: names(max_out_files)
    integer, intent(in) :: n
    type(status_t), intent(inout) :: st
    integer(i8) :: now
    integer :: k
    do k = 1, n
      inquire(file=r%dir//'/'//trim(names(k)), size=now)
      now = max(now, 0_i8)
      if (now < r%out_bytes(k)) then
        r%out_bytes(k) = 0
        r%out_crc(k) = 0
      end if
      call file_crc64_extend(r%dir//'/'//trim(names(k)), r%out_bytes(k), now - r%out_bytes(k), &
           r%out_crc(k), st)
      if (st%code /= 0) return
      r%out_bytes(k) = now
    end do
  end subroutine extend_crcs

  !> Verify the checkpoint (container), read the runner's record and the method's payload.
  subroutine restore(r, names, sizes, crcs, nfiles, st)
    type(run_t), intent(inout) :: r
    character(len=fname_len), intent(out) :: names(max_out_files)
    integer(i8), intent(out) :: sizes(max_out_files), crcs(max_out_files)
    integer, intent(out) :: nfiles
    type(status_t), intent(inout) :: st
    integer :: u, ios
    integer(int32) :: nf
    integer(i8) :: done
    character(len=:), allocatable :: path
    path = r%dir//'/'//ckpt_name
    names = ''
    sizes = 0
    crcs = 0
    nfiles = 0
    call ckpt_open(path, r%kind, r%hash, u, st)
    if (u == -1) return
    read(u, iostat=ios) r%wall_before, done, r%run_id, nf
    if (ios == 0 .and. (nf < 0 .or. nf > max_out_files)) ios = 1
    if (ios == 0 .and. nf > 0) read(u, iostat=ios) names(1:nf), sizes(1:nf), crcs(1:nf)
    if (ios == 0) then
      nfiles = nf
      call r%m%restore_state(u, st)
      if (st%code /= 0) ios = 1
    end if
    call ckpt_close(u, path, ios, st)
  end subroutine restore

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
