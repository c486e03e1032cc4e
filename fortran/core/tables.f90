!> Text tables, the output format every method shares: line 1 describes the
!> file and its units, line 2 names the columns as name[unit], one row per
!> record. Every byte goes through the checked files of module files: a
!> failed write (full disk, I/O error) becomes an exit_io status naming the
!> file and the system's message. A row holding a non-finite number (a
!> field NaN, Inf or Infinity, as Fortran prints them) is never written: it
!> is an exit_numerical status naming the file and the row's step (its
!> first field); row_guard is the same check for rows written elsewhere.
module tables
  use errors, only: status_t, set_error, exit_ok, exit_numerical
  use files, only: cfile_t, cf_open, cf_is_open, cf_line, cf_sync, cf_close
  implicit none
  private

  public :: table_t, table_open, table_line, table_flush, table_close, rfmt, row_guard

  character(len=*), parameter :: rfmt = 'es24.16e3'   !< real format: round-trips a real64

  type :: table_t
    type(cfile_t) :: f
  end type table_t

contains

  !> Open `dir/name` fresh with its two header lines, or (append) at its end.
  subroutine table_open(t, dir, name, header1, header2, append, st)
    type(table_t), intent(inout) :: t
    character(len=*), intent(in) :: dir, name, header1, header2
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    if (st%code /= exit_ok) return
    if (append) then
      call cf_open(t%f, trim(dir)//'/'//trim(name), 'a', st)
      return
    end if
    call cf_open(t%f, trim(dir)//'/'//trim(name), 'w', st)
    call cf_line(t%f, trim(header1), st)
    call cf_line(t%f, trim(header2), st)
  end subroutine table_open

  !> One row; nothing after the first failure. A row with a non-finite
  !> number is refused (row_guard) and not written.
  subroutine table_line(t, text, st)
    type(table_t), intent(inout) :: t
    character(len=*), intent(in) :: text
    type(status_t), intent(inout) :: st
    if (st%code /= exit_ok .or. .not. cf_is_open(t%f)) return
    call row_guard(t%f%path, text, st)
    if (st%code /= exit_ok) return
    call cf_line(t%f, text, st)
  end subroutine table_line

  !> Refuse (exit_numerical, naming `path` and the row's step) a text row
  !> holding a non-finite number: a blank-separated field NaN, Inf or
  !> Infinity with an optional sign, any case. Each spelling holds an n or N:
  !> a row without one (every finite row of numbers) costs one pass over
  !> its characters (about 1 % of formatting it).
  subroutine row_guard(path, text, st)
    character(len=*), intent(in) :: path, text
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: step
    integer :: k, nn
    if (st%code /= exit_ok) return
    nn = 0
    do k = 1, len(text)      ! no early exit: the compiler vectorises the count
      if (iand(iachar(text(k:k)), 223) == iachar('N')) nn = nn + 1   ! n or N
    end do
    if (nn == 0) return
    if (.not. has_non_finite(text)) return
    step = first_field(text)
    if (verify(step, '0123456789') == 0 .and. len(step) > 0) then
      step = ' at step '//step
    else
      step = ''
    end if
    call set_error(st, exit_numerical, trim(path)//': the state became non-finite'//step// &
         ': a row holding NaN or Infinity was refused (not written); the run stops here')
  end subroutine row_guard

  logical function has_non_finite(text)
    character(len=*), intent(in) :: text
    integer :: a, b, n
    has_non_finite = .false.
    n = len(text)
    a = 1
    do while (a <= n)
      if (text(a:a) == ' ') then
        a = a + 1
        cycle
      end if
      b = index(text(a:), ' ')
      if (b == 0) then
        b = n
      else
        b = a + b - 2
      end if
      if (non_finite_word(text(a:b))) then
        has_non_finite = .true.
        return
      end if
      a = b + 1
    end do
  end function has_non_finite

  !> NaN, Inf, Infinity (optional sign, any case): how Fortran writes a non-finite real.
  logical function non_finite_word(w)
    character(len=*), intent(in) :: w
    character(len=len(w)) :: u
    integer :: k, c
    u = w
    do k = 1, len(u)
      c = iachar(u(k:k))
      if (c >= iachar('a') .and. c <= iachar('z')) u(k:k) = achar(c - 32)
    end do
    if (len(u) > 1) then
      if (u(1:1) == '+' .or. u(1:1) == '-') u = u(2:)
    end if
    non_finite_word = trim(u) == 'NAN' .or. trim(u) == 'INF' .or. trim(u) == 'INFINITY'
  end function non_finite_word

  function first_field(text) result(w)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: w
    integer :: b
    w = adjustl(text)
    b = index(w, ' ')
    if (b > 0) w = w(1:b - 1)
  end function first_field

  !> Hand the buffered rows to the OS (no fsync).
  subroutine table_flush(t, st)
    type(table_t), intent(inout) :: t
    type(status_t), intent(inout) :: st
    call cf_sync(t%f, st, disk=.false.)
  end subroutine table_flush

  !> fflush + fsync + close, every step checked.
  subroutine table_close(t, st)
    type(table_t), intent(inout) :: t
    type(status_t), intent(inout) :: st
    call cf_close(t%f, st, sync=.true.)
  end subroutine table_close

end module tables
