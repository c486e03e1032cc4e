!> run.json of a run directory: the fields every kind shares, then the
!> method's own (json_fields); replaced atomically (temporary file + rename).
module run_meta
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io, msg_len
  use method, only: method_t
  use files, only: rename_into_place
  use ckpt, only: engine_version
  implicit none
  private

  public :: write_run_json, json_escape, n_threads

  character(len=*), parameter :: rfmt = 'es24.16e3'

contains

  subroutine write_run_json(dir, m, kind, scene_path, status, code, message, done, total, &
       t_now, wall, st)
    character(len=*), intent(in) :: dir, kind, scene_path, status, message
    class(method_t), intent(in) :: m
    integer, intent(in) :: code
    integer(i8), intent(in) :: done, total
    real(dp), intent(in) :: t_now, wall
    type(status_t), intent(inout) :: st
    integer :: u, ios
    character(len=msg_len) :: iom
    character(len=:), allocatable :: tmp
    real(dp) :: per_step
    tmp = trim(dir)//'/.run.json.tmp'
    per_step = 0
    if (done > 0) per_step = wall/real(done, dp)
    iom = ''
    open(newunit=u, file=tmp, status='replace', action='write', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, tmp//': cannot write run metadata: '//trim(iom))
      return
    end if
    write(u, '(a)') '{'
    write(u, '(a)') '  "program": "magbed",'
    write(u, '(a)') '  "version": "'//trim(engine_version)//'",'
    write(u, '(a)') '  "compiler": "'//json_escape(compiler_id())//'",'
    write(u, '(a)') '  "kind": "'//json_escape(trim(kind))//'",'
    write(u, '(a)') '  "scene": "'//json_escape(trim(scene_path))//'",'
    write(u, '(a)') '  "status": "'//json_escape(trim(status))//'",'
    write(u, '(a,i0,a)') '  "exit_code": ', code, ','
    write(u, '(a)') '  "message": "'//json_escape(trim(message))//'",'
    write(u, '(a,i0,a)') '  "steps_done": ', done, ','
    write(u, '(a,i0,a)') '  "steps_total": ', total, ','
    write(u, '(a,'//rfmt//',a)') '  "t_reached": ', t_now, ','
    write(u, '(a,'//rfmt//',a)') '  "wall_time_s": ', wall, ','
    write(u, '(a,'//rfmt//',a)') '  "wall_time_per_step_s": ', per_step, ','
    call m%json_fields(u)
    write(u, '(a,i0)', iostat=ios, iomsg=iom) '  "threads": ', n_threads()
    if (ios == 0) write(u, '(a)', iostat=ios, iomsg=iom) '}'
    if (ios == 0) flush(u, iostat=ios, iomsg=iom)
    if (ios == 0) then
      close(u, iostat=ios, iomsg=iom)
    else
      close(u)
    end if
    if (ios /= 0) then
      call set_error(st, exit_io, tmp//': write failed: '//trim(iom))
      return
    end if
    call rename_into_place(tmp, trim(dir)//'/run.json', st)
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
