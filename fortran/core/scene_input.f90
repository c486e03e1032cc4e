!> Scene-input helpers shared by every kind: which kind a scene file is, the
!> file as checked text, range checks for the rules across keys whose messages
!> name the file, group, key, value and allowed range, and the number and string
!> formats of scene.nml (strings quoted so that they round-trip, reals with
!> every digit). The reader itself is module schema.
module scene_input
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, exit_io, msg_len
  implicit none
  private

  public :: kind_len, read_kind, read_text, printable, lower_case, &
       check_real, check_int, choice_index, quoted, real_str, int_str, json_real

  integer, parameter :: kind_len = 32
  integer(i8), parameter :: max_scene_bytes = 1048576   !< a scene file is text of at most 1 MiB

contains

  !> The whole file as one string (at most max_scene_bytes); bytes that are
  !> not text (controls other than tab, CR, LF) are refused.
  subroutine read_text(path, text, st)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: text
    type(status_t), intent(inout) :: st
    integer :: u, ios, i, line
    integer(i8) :: n
    character(len=msg_len) :: iom
    character(len=8) :: hx
    text = ''
    iom = ''
    open(newunit=u, file=path, access='stream', form='unformatted', status='old', &
         action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot open scene file: '//trim(iom))
      return
    end if
    inquire(unit=u, size=n)
    if (n < 0 .or. n > max_scene_bytes) then
      close(u)
      call set_error(st, exit_bad_input, trim(path)//': not a scene file (larger than '// &
           int_str(max_scene_bytes)//' bytes)')
      return
    end if
    deallocate(text)
    allocate(character(len=n) :: text)
    ios = 0
    if (n > 0) read(u, iostat=ios, iomsg=iom) text
    close(u)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot read scene file: '//trim(iom))
      return
    end if
    line = 1
    do i = 1, len(text)
      if (text(i:i) == achar(10)) line = line + 1
      if ((iachar(text(i:i)) < 32 .and. index(achar(9)//achar(10)//achar(13), text(i:i)) == 0) &
           .or. iachar(text(i:i)) == 127) then
        write(hx, '(z2.2)') iachar(text(i:i))
        call set_error(st, exit_bad_input, trim(path)//': line '//int_str(int(line, i8))//': byte 0x'// &
             trim(hx)//' is not text (a binary file?): not a scene file')
        return
      end if
    end do
  end subroutine read_text

  !> The scene kind (&scene kind = '...'), from a kind-agnostic scan of the
  !> file: text only (read_text), at least one group, strings closed on their
  !> line, a &scene group naming the kind. Everything else (the kind's groups,
  !> keys, types) is the kind's own reader's.
  subroutine read_kind(path, allowed, kind, st)
    character(len=*), intent(in) :: path
    character(len=*), intent(in) :: allowed   !< e.g. "'magnet_bed' | 'oscillator'" (messages)
    character(len=kind_len), intent(out) :: kind
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: text, group, word
    integer :: i, line, p0, ngroups
    logical :: in_scene, after_kind
    character(len=1) :: c, q
    kind = ''
    call read_text(path, text, st)
    if (st%code /= 0) return
    i = 1
    line = 1
    ngroups = 0
    in_scene = .false.
    after_kind = .false.
    group = ''
    do while (i <= len(text))
      c = text(i:i)
      if (c == achar(10)) then
        line = line + 1
      else if (c == '!') then                 ! comment to the end of the line
        do while (i < len(text))
          if (text(i + 1:i + 1) == achar(10)) exit
          i = i + 1
        end do
      else if (c == "'" .or. c == '"') then    ! a string, closed on its line
        q = c
        p0 = i
        i = i + 1
        do
          if (i > len(text)) then
            call fail('string not closed: '//text(p0:min(p0 + 30, len(text))))
            return
          end if
          if (text(i:i) == achar(10)) then
            call fail('string not closed on its line: '//text(p0:i - 1))
            return
          end if
          if (text(i:i) == q) then
            if (i < len(text)) then
              if (text(i + 1:i + 1) == q) then
                i = i + 2
                cycle
              end if
            end if
            exit
          end if
          i = i + 1
        end do
        if (in_scene .and. after_kind .and. len_trim(kind) == 0) kind = text(p0 + 1:i - 1)
        after_kind = .false.
      else if (c == '&' .or. c == '$') then
        word = ident_at(i + 1)
        group = lower_case(word)
        if (group /= 'end' .and. len(group) > 0) ngroups = ngroups + 1
        in_scene = group == 'scene'
        i = i + len(word)
      else if (c == '/') then
        in_scene = .false.
      else if (in_scene .and. is_letter(c)) then
        word = ident_at(i)
        after_kind = lower_case(word) == 'kind'
        i = i + len(word) - 1
      end if
      i = i + 1
    end do
    if (ngroups == 0) then
      call set_error(st, exit_bad_input, trim(path)//': no namelist group: a scene file '// &
           'names its kind (&scene kind = '//allowed//' /) and holds its groups')
    else if (len_trim(kind) == 0) then
      call set_error(st, exit_bad_input, trim(path)//': the scene does not name its kind: '// &
           'add &scene kind = ... / (allowed: '//allowed//')')
    end if
  contains
    subroutine fail(msg)
      character(len=*), intent(in) :: msg
      call set_error(st, exit_bad_input, trim(path)//': line '//int_str(int(line, i8))//': '//msg)
    end subroutine fail
    function ident_at(j) result(w)
      integer, intent(in) :: j
      character(len=:), allocatable :: w
      integer :: k
      k = j
      do while (k <= len(text))
        if (.not. (is_letter(text(k:k)) .or. index('0123456789_', text(k:k)) > 0)) exit
        k = k + 1
      end do
      w = text(j:k - 1)
    end function ident_at
  end subroutine read_kind

  pure logical function is_letter(c)
    character(len=1), intent(in) :: c
    is_letter = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z')
  end function is_letter

  !> Control and non-ASCII bytes shown as '?', so a message is one clean line.
  pure function printable(s) result(r)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: r
    integer :: i, c
    r = s
    do i = 1, len(s)
      c = iachar(s(i:i))
      if (c < 32 .or. c > 126) r(i:i) = '?'
    end do
  end function printable

  pure function lower_case(s) result(r)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: r
    integer :: k
    r = s
    do k = 1, len(s)
      if (s(k:k) >= 'A' .and. s(k:k) <= 'Z') r(k:k) = achar(iachar(s(k:k)) + 32)
    end do
  end function lower_case



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


  !> Position of v in allowed (1-based, compared trimmed; 0 when absent): a checked choice
  !> (check_choice) mapped to the method's code.
  pure integer function choice_index(v, allowed) result(k)
    character(len=*), intent(in) :: v
    character(len=*), intent(in) :: allowed(:)
    do k = 1, size(allowed)
      if (trim(allowed(k)) == trim(v)) return
    end do
    k = 0
  end function choice_index

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

  !> Shortest text that reads back to exactly v (17 significant digits at
  !> most): plain for 1e-4 <= |v| < 1e7 (e.g. 0.001, 6.283185307179586,
  !> 75.0), else with an exponent (2.5e-07, 1.0e+12); valid JSON too.
  function real_str(v) result(s)
    real(dp), intent(in) :: v
    character(len=:), allocatable :: s
    character(len=40) :: buf
    character(len=:), allocatable :: b, digits, sgn
    real(dp) :: back
    integer :: d, ios, ie, e, nd
    do d = 1, 17
      write(buf, '(es40.'//int_str(int(d - 1, i8))//'e3)') v
      read(buf, *, iostat=ios) back
      if (ios == 0 .and. (back == v .or. .not. ieee_is_finite(v))) exit
    end do
    b = trim(adjustl(buf))
    if (.not. ieee_is_finite(v)) then
      s = b
      return
    end if
    if (v == 0.0_dp) then
      s = merge('-0.0', '0.0 ', sign(1.0_dp, v) < 0.0_dp)
      s = trim(s)
      return
    end if
    sgn = ''
    if (b(1:1) == '-') then
      sgn = '-'
      b = b(2:)
    end if
    ie = index(b, 'E')
    read(b(ie + 1:), *) e
    digits = b(1:1)//b(3:ie - 1)          ! mantissa digits without the point
    nd = len(digits)
    do while (nd > 1)
      if (digits(nd:nd) /= '0') exit
      nd = nd - 1
    end do
    digits = digits(1:nd)
    if (e >= -4 .and. e < 7) then
      if (e >= 0) then
        if (nd <= e + 1) then
          s = sgn//digits//repeat('0', e + 1 - nd)//'.0'
        else
          s = sgn//digits(1:e + 1)//'.'//digits(e + 2:)
        end if
      else
        s = sgn//'0.'//repeat('0', -e - 1)//digits
      end if
    else
      if (nd == 1) then
        s = sgn//digits//'.0e'
      else
        s = sgn//digits(1:1)//'.'//digits(2:)//'e'
      end if
      if (e < 0) then
        s = s//'-'
      else
        s = s//'+'
      end if
      write(buf, '(i0)') abs(e)
      if (abs(e) < 10) buf = '0'//buf
      s = s//trim(buf)
    end if
  end function real_str

  function int_str(v) result(s)
    integer(i8), intent(in) :: v
    character(len=:), allocatable :: s
    character(len=24) :: buf
    write(buf, '(i0)') v
    s = trim(buf)
  end function int_str

  !> A real as a JSON number that round-trips a real64 (e.g. 2.0000000000000000E+001).
  function json_real(v) result(s)
    real(dp), intent(in) :: v
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write(buf, '(es24.16e3)') v
    s = trim(adjustl(buf))
  end function json_real


end module scene_input
