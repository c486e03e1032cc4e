!> Scene-input framework shared by every kind: which kind a scene file is,
!> range checks whose messages name the file, group, key, value and allowed
!> range, and the writers of the resolved scene (strings quoted so that they
!> round-trip, reals with every digit).
module scene_input
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, exit_io, msg_len
  implicit none
  private

  public :: kind_len, read_kind, check_real, check_int, check_choice, &
       put_real, put_int, put_str, put_logical, quoted, real_str, int_str

  integer, parameter :: kind_len = 32

contains

  !> The scene kind (&scene kind = '...'); a file without it is refused.
  subroutine read_kind(path, kind, st)
    character(len=*), intent(in) :: path
    character(len=kind_len), intent(out) :: kind
    type(status_t), intent(inout) :: st
    character(len=128) :: title
    integer :: u, ios
    character(len=msg_len) :: iom
    namelist /scene/ kind, title
    kind = ''
    title = ''
    open(newunit=u, file=path, status='old', action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot open scene file: '//trim(iom))
      return
    end if
    read(u, nml=scene, iostat=ios, iomsg=iom)
    close(u)
    if (ios < 0) then
      call set_error(st, exit_bad_input, trim(path)//': no &scene group: a scene must name '// &
           "its kind (&scene kind = 'magnet_bed' | 'oscillator' | 'rods' /)")
    else if (ios > 0) then
      call set_error(st, exit_bad_input, trim(path)//': &scene: cannot read group: '//trim(iom))
    else if (len_trim(kind) == 0) then
      call set_error(st, exit_bad_input, trim(path)//": &scene kind: missing (allowed: "// &
           "'magnet_bed' | 'oscillator' | 'rods')")
    end if
  end subroutine read_kind

  !> A finite real in [lo, hi] (open at lo unless lo_closed).
  subroutine check_real(path, group, key, v, lo, hi, lo_closed, st)
    character(len=*), intent(in) :: path, group, key
    real(dp), intent(in) :: v, lo, hi
    logical, intent(in) :: lo_closed
    type(status_t), intent(inout) :: st
    character(len=1) :: br
    logical :: ok
    ok = ieee_is_finite(v)
    if (ok) ok = v <= hi .and. (v > lo .or. (lo_closed .and. v == lo))
    if (ok) return
    br = merge('[', '(', lo_closed)
    call set_error(st, exit_bad_input, trim(path)//': &'//group//' '//key//' = '// &
         real_str(v)//': allowed '//br//real_str(lo)//', '//real_str(hi)//'] (finite)')
  end subroutine check_real

  subroutine check_int(path, group, key, v, lo, hi, st)
    character(len=*), intent(in) :: path, group, key
    integer(i8), intent(in) :: v, lo, hi
    type(status_t), intent(inout) :: st
    if (v >= lo .and. v <= hi) return
    call set_error(st, exit_bad_input, trim(path)//': &'//group//' '//key//' = '// &
         int_str(v)//': allowed integers in ['//int_str(lo)//', '//int_str(hi)//']')
  end subroutine check_int

  !> `v` must be one of `allowed` (compared trimmed, case-sensitive).
  subroutine check_choice(path, group, key, v, allowed, st)
    character(len=*), intent(in) :: path, group, key, v
    character(len=*), intent(in) :: allowed(:)
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: list
    integer :: k
    if (any([(trim(allowed(k)) == trim(v), k = 1, size(allowed))])) return
    list = ''
    do k = 1, size(allowed)
      list = list//merge(' | ', '   ', k > 1)//quoted(trim(allowed(k)))
    end do
    call set_error(st, exit_bad_input, trim(path)//': &'//group//' '//key//' = '// &
         quoted(trim(v))//': allowed '//adjustl(list))
  end subroutine check_choice

  !> Fortran string literal of s: quotes doubled, so any text round-trips.
  function quoted(s) result(r)
    character(len=*), intent(in) :: s
    character(len=:), allocatable :: r
    integer :: i
    r = "'"
    do i = 1, len(s)
      if (s(i:i) == "'") then
        r = r//"''"
      else
        r = r//s(i:i)
      end if
    end do
    r = r//"'"
  end function quoted

  !> Shortest text that reads back to exactly v (17 significant digits at most).
  function real_str(v) result(s)
    real(dp), intent(in) :: v
    character(len=:), allocatable :: s
    character(len=40) :: buf
    real(dp) :: back
    integer :: d, ios
    do d = 1, 17
      write(buf, '(es40.'//int_str(int(d - 1, i8))//'e3)') v
      read(buf, *, iostat=ios) back
      if (ios == 0 .and. (back == v .or. .not. ieee_is_finite(v))) exit
    end do
    s = trim(adjustl(buf))
  end function real_str

  function int_str(v) result(s)
    integer(i8), intent(in) :: v
    character(len=:), allocatable :: s
    character(len=24) :: buf
    write(buf, '(i0)') v
    s = trim(buf)
  end function int_str

  !> Lines of a resolved scene: '  key = value  ! note'.
  subroutine put_real(u, key, v, note)
    integer, intent(in) :: u
    character(len=*), intent(in) :: key, note
    real(dp), intent(in) :: v
    write(u, '(a)') trim('  '//key//' = '//real_str(v)//merge('  ! '//note, repeat(' ', len(note)+4), &
         len(note) > 0))
  end subroutine put_real

  subroutine put_int(u, key, v, note)
    integer, intent(in) :: u
    character(len=*), intent(in) :: key, note
    integer(i8), intent(in) :: v
    write(u, '(a)') trim('  '//key//' = '//int_str(v)//merge('  ! '//note, repeat(' ', len(note)+4), &
         len(note) > 0))
  end subroutine put_int

  subroutine put_str(u, key, v, note)
    integer, intent(in) :: u
    character(len=*), intent(in) :: key, v, note
    write(u, '(a)') trim('  '//key//' = '//quoted(trim(v))//merge('  ! '//note, &
         repeat(' ', len(note)+4), len(note) > 0))
  end subroutine put_str

  subroutine put_logical(u, key, v, note)
    integer, intent(in) :: u
    character(len=*), intent(in) :: key, note
    logical, intent(in) :: v
    write(u, '(a)') trim('  '//key//' = '//merge('.true. ', '.false.', v)// &
         merge('  ! '//note, repeat(' ', len(note)+4), len(note) > 0))
  end subroutine put_logical

end module scene_input
