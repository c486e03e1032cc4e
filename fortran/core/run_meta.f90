!> run.json of a run directory: the fields every kind shares, then the
!> method's own (json_fields); replaced atomically (temporary file + rename).
module run_meta
  use kinds, only: dp, i8
  use, intrinsic :: iso_fortran_env, only: int8
  use errors, only: status_t, set_error, exit_io, exit_ok
  use method, only: method_t
  use files, only: rename_into_place, remove_file, cfile_t, cf_open, cf_write, cf_close
  use ckpt, only: engine_version
  use scene_input, only: int_str, json_real
  implicit none
  private

  public :: write_run_json, json_escape, n_threads


contains

  !> run.json: the shared members, then the method's (json_fields). Written
  !> through the checked layer and renamed into place; fsynced for a final
  !> status (the 'running' updates are only flushed).
  subroutine write_run_json(dir, m, kind, scene_path, run_id, status, code, message, done, &
       total, t_now, wall, st)
    character(len=*), intent(in) :: dir, kind, scene_path, status, message
    integer(i8), intent(in) :: run_id   !< the run's random id (also in its checkpoints)
    class(method_t), intent(in) :: m
    integer, intent(in) :: code
    integer(i8), intent(in) :: done, total
    real(dp), intent(in) :: t_now, wall
    type(status_t), intent(inout) :: st   !< a failure here is recorded unless st already failed
    type(status_t) :: lst, junk
    type(cfile_t) :: f
    character(len=:), allocatable :: tmp, text
    character(len=1), parameter :: nl = achar(10)
    character(len=16) :: id_hex
    real(dp) :: per_step
    tmp = trim(dir)//'/.run.json.tmp'
    per_step = 0
    if (done > 0) per_step = wall/real(done, dp)
    write(id_hex, '(z16.16)') run_id
    text = '{'//nl// &
         '  "program": "partsim",'//nl// &
         '  "version": "'//trim(engine_version)//'",'//nl// &
         '  "compiler": "'//json_escape(compiler_id())//'",'//nl// &
         '  "kind": "'//json_escape(trim(kind))//'",'//nl// &
         '  "scene": "'//json_escape(trim(scene_path))//'",'//nl// &
         '  "run_id": "'//id_hex//'",'//nl// &
         '  "status": "'//json_escape(trim(status))//'",'//nl// &
         '  "exit_code": '//int_str(int(code, i8))//','//nl// &
         '  "message": "'//json_escape(trim(message))//'",'//nl// &
         '  "steps_done": '//int_str(done)//','//nl// &
         '  "steps_total": '//int_str(total)//','//nl// &
         '  "t_reached": '//json_real(t_now)//','//nl// &
         '  "wall_time_s": '//json_real(wall)//','//nl// &
         '  "wall_time_per_step_s": '//json_real(per_step)//','//nl// &
         m%json_fields()// &
         '  "threads": '//int_str(int(n_threads(), i8))//nl//'}'//nl
    call cf_open(f, tmp, 'w', lst)
    call cf_write(f, transfer(text, [0_int8]), lst)
    call cf_close(f, lst, sync=trim(status) /= 'running')
    if (lst%code == exit_ok) then
      call rename_into_place(tmp, trim(dir)//'/run.json', lst)
    else
      call remove_file(tmp, junk)
    end if
    if (lst%code /= exit_ok) call set_error(st, lst%code, trim(lst%msg))
  end subroutine write_run_json

  function json_escape(s) result(r)
    character(len=*), intent(in) :: s
    character(len=:), allocatable :: r
    integer :: i
    r = ''
    do i = 1, len(s)
      select case (s(i:i))
      case ('"'); r = r//'\"'
      case ('\'); r = r//'\\'
      case default
        if (iachar(s(i:i)) < 32 .or. iachar(s(i:i)) > 126) then
          r = r//'?'
        else
          r = r//s(i:i)
        end if
      end select
    end do
  end function json_escape

  integer function n_threads()
    !$ use omp_lib, only: omp_get_max_threads
    n_threads = 1
    !$ n_threads = omp_get_max_threads()
  end function n_threads

  function compiler_id() result(s)
    use, intrinsic :: iso_fortran_env, only: compiler_version
    character(len=:), allocatable :: s
    s = compiler_version()
  end function compiler_id

end module run_meta
