!> Plain text tables read line by line (the lj_box field table, the start files of the
!> time-stepped kinds): whole lines of any length, words separated by blanks, tabs or
!> carriage returns, integers and finite reals as Fortran writes them (no repeat counts,
!> separators, NaN or Infinity).
module text_table
  use kinds, only: dp
  use, intrinsic :: iso_fortran_env, only: iostat_eor
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  private

  public :: read_line, next_values, count_values, word, ints, reals, real_literal

contains

  !> The next line of unit u that holds values: '#' starts a comment, lines of blanks are
  !> skipped; ln counts the lines read (the file's line number of the one returned), nv its
  !> values; ios /= 0 at the end of the file.
  subroutine next_values(u, line, ln, nv, ios)
    integer, intent(in) :: u
    character(len=:), allocatable, intent(out) :: line
    integer, intent(inout) :: ln
    integer, intent(out) :: nv, ios
    integer :: c
    nv = 0
    do
      call read_line(u, line, ios)
      if (ios /= 0) return
      ln = ln + 1
      c = index(line, '#')
      if (c > 0) line = line(:c - 1)
      nv = count_values(line)
      if (nv > 0) return
    end do
  end subroutine next_values

  !> One whole line of unit u, however long (ios /= 0 at the end of the file).
  subroutine read_line(u, line, ios)
    integer, intent(in) :: u
    character(len=:), allocatable, intent(out) :: line
    integer, intent(out) :: ios
    character(len=256) :: buf
    integer :: got
    line = ''
    do
      got = 0
      read(u, '(a)', advance='no', size=got, iostat=ios) buf
      line = line//buf(:got)
      if (ios == iostat_eor) then
        ios = 0
        return
      end if
      if (ios /= 0) then
        if (is_iostat_end(ios) .and. len(line) > 0) ios = 0   ! last line without a newline
        return
      end if
    end do
  end subroutine read_line

  !> Is c a separator between a table's values (blank, tab, carriage return)?
  pure logical function is_sep(c)
    character, intent(in) :: c
    is_sep = c == ' ' .or. c == achar(9) .or. c == achar(13)
  end function is_sep

  !> Number of values (separated words) on a line.
  pure integer function count_values(line) result(n)
    character(len=*), intent(in) :: line
    integer :: p
    logical :: inword
    n = 0
    inword = .false.
    do p = 1, len(line)
      if (is_sep(line(p:p))) then
        inword = .false.
      else if (.not. inword) then
        n = n + 1
        inword = .true.
      end if
    end do
  end function count_values

  !> Word w (1-based) of a line ('' if it has fewer).
  pure function word(line, w) result(r)
    character(len=*), intent(in) :: line
    integer, intent(in) :: w
    character(len=:), allocatable :: r
    integer :: p, n, p0
    n = 0
    p = 1
    r = ''
    do while (p <= len(line))
      if (is_sep(line(p:p))) then
        p = p + 1
        cycle
      end if
      p0 = p
      do while (p <= len(line))
        if (is_sep(line(p:p))) exit
        p = p + 1
      end do
      n = n + 1
      if (n == w) then
        r = line(p0:p - 1)
        return
      end if
    end do
  end function word

  !> The line's first size(iv) words as integers (optional sign, at most 9 digits);
  !> ok = all are.
  subroutine ints(line, iv, ok)
    character(len=*), intent(in) :: line
    integer, intent(out) :: iv(:)
    logical, intent(out) :: ok
    integer :: w, m, ios
    character(len=:), allocatable :: t
    iv = 0
    ok = .true.
    do w = 1, size(iv)
      t = word(line, w)
      m = 1
      if (len(t) > 0) then
        if (index('+-', t(1:1)) > 0) m = 2
      end if
      ok = len(t) >= m .and. len(t) - m < 9
      if (ok) ok = verify(t(m:), '0123456789') == 0
      if (.not. ok) return
      read(t, *, iostat=ios) iv(w)
      ok = ios == 0
      if (.not. ok) return
    end do
  end subroutine ints

  !> The line's first size(v) words as finite reals (real_literal); ok = all are.
  subroutine reals(line, v, ok)
    character(len=*), intent(in) :: line
    real(dp), intent(out) :: v(:)
    logical, intent(out) :: ok
    integer :: w, ios
    character(len=:), allocatable :: t
    v = 0
    ok = .true.
    do w = 1, size(v)
      t = word(line, w)
      ok = real_literal(t)
      if (.not. ok) return
      read(t, *, iostat=ios) v(w)
      ok = ios == 0
      if (ok) ok = ieee_is_finite(v(w))
      if (.not. ok) return
    end do
  end subroutine reals

  !> A number as Fortran writes one: [sign] (digits [. [digits]] | . digits)
  !> [(e|E|d|D) [sign] digits]. No repeat counts, separators, NaN or Infinity.
  logical function real_literal(t) result(ok)
    character(len=*), intent(in) :: t
    integer :: p, nd
    ok = .false.
    if (len(t) == 0) return
    p = 1
    if (index('+-', t(1:1)) > 0) p = 2
    nd = 0
    call digits()
    if (p <= len(t)) then
      if (t(p:p) == '.') then
        p = p + 1
        call digits()
      end if
    end if
    if (nd == 0) return
    if (p <= len(t)) then
      if (index('eEdD', t(p:p)) == 0) return
      p = p + 1
      if (p <= len(t)) then
        if (index('+-', t(p:p)) > 0) p = p + 1
      end if
      nd = 0
      call digits()
      if (nd == 0) return
    end if
    ok = p > len(t)
  contains
    subroutine digits()
      do while (p <= len(t))
        if (index('0123456789', t(p:p)) == 0) exit
        p = p + 1
        nd = nd + 1
      end do
    end subroutine digits
  end function real_literal

end module text_table
