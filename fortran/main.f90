!> partsim: the standalone engine for every scene kind (dispatch on &scene kind).
!>   partsim SCENE.nml [--out DIR] [--overwrite] [--check] [--quiet] [--stop-at STEP]
!>   partsim --resume RUN_DIR [--quiet] [--stop-at STEP]
!> Exit codes: 0 ok (or paused by --stop-at), 2 bad input (nothing written),
!> 3 numerical guard, 4 I/O (a failed write, a refused checkpoint or run
!> directory), 5 interrupted by SIGTERM/SIGINT (checkpoint written).
program partsim
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use, intrinsic :: iso_c_binding, only: c_int
  use kinds, only: i8
  use errors, only: status_t, exit_bad_input
  use runner, only: sim_execute, sim_resume, sim_check, sim_describe
  use signals, only: install_handlers
  implicit none
  interface
    !> libc exit: a non-zero status without gfortran's "ERROR STOP"/backtrace noise
    subroutine c_exit(status) bind(C, name='exit')
      import :: c_int
      integer(c_int), value :: status
    end subroutine c_exit
  end interface
  type(status_t) :: st
  character(len=4096) :: arg, path, dir, resume_dir, describe_kind
  character(len=:), allocatable :: text
  logical :: as_json
  logical :: check, quiet, overwrite, out_given
  integer :: i, nargs, ios
  integer(i8) :: stop_at, total

  path = ''
  resume_dir = ''
  describe_kind = ''
  as_json = .false.
  stop_at = -1
  dir = '.'
  check = .false.
  quiet = .false.
  overwrite = .false.
  out_given = .false.
  nargs = command_argument_count()
  i = 1
  do while (i <= nargs)
    call get_command_argument(i, arg)
    select case (trim(arg))
    case ('--out', '-o')
      i = i + 1
      if (i > nargs) call usage('--out needs a directory')
      call get_command_argument(i, dir)
      if (len_trim(dir) == 0) call usage('--out needs a non-empty directory name')
      out_given = .true.
    case ('--overwrite')
      overwrite = .true.
    case ('--check')
      check = .true.
    case ('--resume')
      i = i + 1
      if (i > nargs) call usage('--resume needs a run directory')
      call get_command_argument(i, resume_dir)
      if (len_trim(resume_dir) == 0) call usage('--resume needs a non-empty directory name')
    case ('--stop-at')
      i = i + 1
      if (i > nargs) call usage('--stop-at needs a step number')
      call get_command_argument(i, arg)
      read(arg, *, iostat=ios) stop_at
      if (ios /= 0 .or. stop_at < 0) call usage('--stop-at needs a step number >= 0')
    case ('--describe', '--schema')
      as_json = trim(arg) == '--schema'
      i = i + 1
      if (i > nargs) call usage(trim(arg)//' needs a scene kind')
      call get_command_argument(i, describe_kind)
    case ('--quiet', '-q')
      quiet = .true.
    case ('--help', '-h')
      write(output_unit, '(a)') 'usage: partsim SCENE.nml [--out DIR] [--overwrite] [--check] '// &
           '[--quiet] [--stop-at STEP]'
      write(output_unit, '(a)') '       partsim --resume RUN_DIR [--quiet] [--stop-at STEP]'
      write(output_unit, '(a)') '       partsim --describe KIND | --schema KIND   (the scene''s keys: table | JSON)'
      stop
    case default
      if (arg(1:1) == '-') call usage('unknown option '//trim(arg))
      if (len_trim(path) > 0) call usage('only one scene file is accepted')
      path = arg
    end select
    i = i + 1
  end do
  if (len_trim(describe_kind) > 0) then
    call sim_describe(trim(describe_kind), as_json, text, st)
    if (st%code == 0) then
      write(output_unit, '(a)', advance='no') text
      stop
    end if
    write(error_unit, '(a)') 'partsim: error: '//trim(st%msg)
    flush(error_unit)
    call c_exit(int(st%code, c_int))
  end if
  if (len_trim(path) == 0 .and. len_trim(resume_dir) == 0) call usage('missing scene file')
  if (len_trim(path) > 0 .and. len_trim(resume_dir) > 0) &
       call usage('give a scene file or --resume RUN_DIR, not both')
  if (len_trim(resume_dir) > 0 .and. (out_given .or. overwrite)) &
       call usage('--resume continues RUN_DIR in place: no --out or --overwrite')

  if (len_trim(resume_dir) > 0) then
    call install_handlers()
    call sim_resume(trim(resume_dir), .not. quiet, stop_at, st)
  else if (check) then
    call sim_check(trim(path), total, st)
    if (st%code == 0) then
      write(output_unit, '(a,i0,a)') 'ok: ', total, ' steps'
      stop
    end if
  else
    call install_handlers()
    call sim_execute(trim(path), trim(dir), .not. quiet, stop_at, overwrite, st)
  end if
  if (st%code /= 0) then
    write(error_unit, '(a)') 'partsim: error: '//trim(st%msg)
    flush(error_unit)
    call c_exit(int(st%code, c_int))
  end if

contains

  subroutine usage(msg)
    character(len=*), intent(in) :: msg
    write(error_unit, '(a)') 'partsim: error: '//msg
    write(error_unit, '(a)') 'usage: partsim SCENE.nml [--out DIR] [--overwrite] [--check] '// &
         '[--quiet] [--stop-at STEP]'
    write(error_unit, '(a)') '       partsim --resume RUN_DIR [--quiet] [--stop-at STEP]'
    flush(error_unit)
    call c_exit(int(exit_bad_input, c_int))
  end subroutine usage

end program partsim
