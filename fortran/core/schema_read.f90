!> The scene reader of `schema` (a submodule: the type and its declarations are
!> in schema.f90; this file is the tokenizer and the checks of what it reads).
!>
!> Grammar accepted: Fortran namelist groups `&name ... /` with `key = value`,
!> `key(i) = v`, `key(i:j) = v, ...` and `key = v1, v2, ...`; `!` comments;
!> quoted strings with doubled quotes. Refused, naming the file, the line and
!> what is allowed: text outside groups, unknown, foreign or repeated groups,
!> unknown keys, indices out of range or on scalars, wrong types, non-finite
!> reals, repeat counts (`3*0.1`) and strings that are not UTF-8.
!>
!> find_key and line_of are separate module procedures (declared in schema.f90), not private
!> ones: gfortran 12 gives a private module procedure no external symbol, so a submodule that
!> calls one fails to link ("undefined reference to __schema_MOD_...").
submodule (schema) schema_reader
  implicit none

contains

  ! ---------------------------------------------------------------- reading

  !> Read the scene file at `path` into the bound variables (types and syntax
  !> checked, ranges not: see validate). Absent groups and keys keep their defaults.
  module subroutine schema_read(s, path, st)
    class(schema_t), intent(inout) :: s
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: text
    integer :: pos, line, g
    call read_text(path, text, st)
    if (st%code /= 0) return
    pos = 1
    line = 1
    do g = 1, s%ng
      s%groups(g)%seen = .false.
    end do
    call parse_file()
  contains

    subroutine parse_file()
      integer :: g
      character(len=:), allocatable :: name
      do
        call skip_blank()
        if (pos > len(text)) exit
        if (text(pos:pos) /= '&') then
          call fail('text outside a group: '''//snippet()//''' (a scene is a sequence of '// &
               '&group ... / blocks and ! comments)')
          return
        end if
        pos = pos + 1
        name = lower_case(ident())
        if (len(name) == 0) then
          call fail('''&'' without a group name')
          return
        end if
        g = find_group(s, name)
        if (g == 0) then
          call fail('unknown namelist group &'//trim(printable(name))//' for kind '''// &
               s%kind//''' (allowed: '//s%group_names()//')')
          return
        end if
        if (s%groups(g)%seen) then
          call fail('group &'//trim(name)//' given twice (first at line '// &
               istr(s%groups(g)%line)//'): give each group once')
          return
        end if
        s%groups(g)%seen = .true.
        s%groups(g)%line = line
        call parse_group(g)
        if (st%code /= 0) return
      end do
      if (.not. any(s%groups(1:s%ng)%seen)) then
        call set_error(st, exit_bad_input, trim(path)//': no namelist group: a scene file '// &
             'names its kind (&scene kind = '''//s%kind//''' /) and holds its groups')
        return
      end if
      do g = 1, s%ng
        if (s%groups(g)%required .and. .not. s%groups(g)%seen) then
          call set_error(st, exit_bad_input, trim(path)//': missing group &'// &
               trim(s%groups(g)%name))
          return
        end if
      end do
    end subroutine parse_file

    !> One group: assignments until '/'.
    subroutine parse_group(g)
      integer, intent(in) :: g
      integer :: start_line, kline, idx, nv, k, first, e
      character(len=:), allocatable :: key, tok, vals, grp
      grp = trim(s%groups(g)%name)
      start_line = line
      do
        call skip_blank()
        if (pos > len(text)) then
          call fail('group &'//grp//' (line '//istr(start_line)//') is not closed with ''/''')
          return
        end if
        if (text(pos:pos) == '/') then
          pos = pos + 1
          return
        end if
        if (text(pos:pos) == '&') then
          call fail('group &'//grp//' (line '//istr(start_line)//') is not closed with '// &
               '''/'' before the next group')
          return
        end if
        if (text(pos:pos) == ',') then
          pos = pos + 1
          cycle
        end if
        kline = line
        key = lower_case(ident())
        if (len(key) == 0) then
          call fail('&'//grp//': expected key = value, found '''//snippet()//'''')
          return
        end if
        k = find_key(s, grp, key)
        if (k == 0) then
          call fail('&'//grp//': unknown key '''//trim(printable(key))//''' (keys: '// &
               key_list(grp)//')')
          return
        end if
        idx = 0
        call skip_spaces()
        if (peek() == '(') then
          pos = pos + 1
          call skip_spaces()
          tok = digit_run()
          call skip_spaces()
          if (len(tok) == 0 .or. len(tok) > 6 .or. peek() /= ')') then
            call fail('&'//grp//' '//key//'(: the index must be a whole number, e.g. '// &
                 key//'(2)')
            return
          end if
          read(tok, *) idx
          pos = pos + 1
          if (.not. s%keys(k)%is_array) then
            call fail('&'//grp//' '//key//'('//tok//'): '//key//' is not an array')
            return
          end if
          if (idx < 1 .or. idx > s%keys(k)%size) then
            call fail('&'//grp//' '//key//'('//tok//'): index out of range [1, '// &
                 istr(s%keys(k)%size)//']')
            return
          end if
          call skip_spaces()
        end if
        if (peek() /= '=') then
          call fail('&'//grp//' '//key//': expected ''='' after the key, found '''// &
               snippet()//'''')
          return
        end if
        pos = pos + 1
        vals = ''
        nv = 0
        first = max(idx, 1)
        do
          call skip_blank()
          if (nv > 0) then
            if (peek() == ',') then
              pos = pos + 1
              call skip_blank()
            end if
          end if
          if (pos > len(text)) exit
          if (index('/&,', text(pos:pos)) > 0) exit
          if (nv > 0 .and. next_is_key()) exit
          call value_token(tok)
          if (st%code /= 0) return
          call check_value(s%keys(k), grp, key, tok, kline)
          if (st%code /= 0) return
          nv = nv + 1
          if (nv > 1) vals = vals//', '
          vals = vals//tok
          e = first + nv - 1
          if (e > s%keys(k)%size) then
            if (s%keys(k)%is_array) then
              call fail_at(kline, '&'//grp//' '//key//' = '//printable(vals)//': at most '// &
                   istr(s%keys(k)%size - first + 1)//' values from index '//istr(first))
            else
              call fail_at(kline, '&'//grp//' '//key//' = '//printable(vals)// &
                   ': one value expected')
            end if
            return
          end if
          if (s%keys(k)%given(e)) then
            call fail_at(kline, '&'//grp//' '//key//': given twice in the group')
            return
          end if
          call store(s%keys(k), e, tok)
          s%keys(k)%given(e) = .true.
          if (s%keys(k)%line == 0) s%keys(k)%line = kline
        end do
        if (nv == 0) then
          call fail_at(kline, '&'//grp//' '//key//' = : no value (give a value or leave the '// &
               'key out for its default)')
          return
        end if
      end do
    end subroutine parse_group

    function key_list(grp) result(r)
      character(len=*), intent(in) :: grp
      character(len=:), allocatable :: r
      integer :: k
      r = ''
      do k = 1, s%nk
        if (trim(s%keys(k)%group) /= grp) cycle
        if (len(r) > 0) r = r//', '
        r = r//trim(s%keys(k)%name)
      end do
    end function key_list

    !> The value's type must be the key's: integer (within the key's storage),
    !> finite real, logical, or a quoted UTF-8 string no longer than the key holds.
    subroutine check_value(kk, grp, key, tok, kline)
      type(key_t), intent(in) :: kk
      character(len=*), intent(in) :: grp, key, tok
      integer, intent(in) :: kline
      integer :: ios, m
      integer(i8) :: iv, big
      real(dp) :: rv
      character(len=:), allocatable :: what, low
      what = '&'//grp//' '//key//' = '//printable(tok)//': '
      low = lower_case(tok)
      if (index(tok, '*') > 0 .and. tok(1:1) /= '''' .and. tok(1:1) /= '"') then
        call fail_at(kline, what//'repeat counts (r*value) are not accepted: write the values out')
        return
      end if
      select case (kk%type)
      case (t_int8, t_int4)
        big = huge(1_i8)
        if (kk%type == t_int4) big = int(huge(1), i8)
        m = 1
        if (index('+-', tok(1:1)) > 0) m = 2
        if (len(tok) < m) then
          call fail_at(kline, what//'must be an integer')
          return
        end if
        if (verify(tok(m:), '0123456789') /= 0) then
          if (verify(low(m:), '0123456789.ed+-') == 0 .and. scan(low, '.ed') > 0) then
            call fail_at(kline, what//'must be an integer (write it without a decimal point '// &
                 'or exponent)')
          else
            call fail_at(kline, what//'must be an integer')
          end if
          return
        end if
        iv = 0
        ios = 1
        if (len(tok) - m + 1 <= 18) read(tok, *, iostat=ios) iv
        if (ios /= 0 .or. abs(iv) > big) then
          call fail_at(kline, what//'integer out of range [-'//int_str(big)//', '// &
               int_str(big)//']')
          return
        end if
      case (t_real)
        if (verify(low, '0123456789+-.ed') /= 0 .or. scan(low, '0123456789') == 0) then
          if (index(low, 'nan') > 0 .or. index(low, 'inf') > 0) then
            call fail_at(kline, what//'must be a finite number')
          else if (tok(1:1) == '''' .or. tok(1:1) == '"') then
            call fail_at(kline, what//'must be a number, not a string')
          else
            call fail_at(kline, what//'must be a number')
          end if
          return
        end if
        read(tok, *, iostat=ios) rv
        if (ios /= 0) then
          call fail_at(kline, what//'must be a number')
        else if (.not. ieee_is_finite(rv)) then
          call fail_at(kline, what//'must be a finite number (it overflows)')
        end if
      case (t_logical)
        select case (low)
        case ('.true.', '.false.', 't', 'f', '.t.', '.f.', 'true', 'false')
        case default
          call fail_at(kline, what//'must be .true. or .false.')
        end select
      case (t_str)
        if (tok(1:1) /= '''' .and. tok(1:1) /= '"') then
          call fail_at(kline, what//'must be a quoted string, e.g. '''//printable(tok)//'''')
        else if (len(unquote(tok)) > kk%strlen) then
          call fail_at(kline, what//'longer than '//istr(kk%strlen)//' characters')
        else if (.not. utf8_ok(tok)) then
          call fail_at(kline, what//'not UTF-8 text (a byte outside ASCII that starts no '// &
               'UTF-8 character: save the file as UTF-8)')
        end if
      end select
    end subroutine check_value

    !> Store the checked token tok as element e of key kk.
    subroutine store(kk, e, tok)
      type(key_t), intent(inout) :: kk
      integer, intent(in) :: e
      character(len=*), intent(in) :: tok
      character(len=:), allocatable :: low
      select case (kk%type)
      case (t_real); read(tok, *) kk%r(e)
      case (t_int8); read(tok, *) kk%i8v(e)
      case (t_int4); read(tok, *) kk%i4v(e)
      case (t_logical)
        low = lower_case(tok)
        kk%lv(e) = low(1:1) == 't' .or. low(1:2) == '.t'
      case (t_str); kk%c = unquote(tok)
      end select
    end subroutine store

    !> One value: a quoted string (quotes doubled inside), or a run of
    !> characters up to a blank, ',', '/', '!', '&' or '='.
    subroutine value_token(tok)
      character(len=:), allocatable, intent(out) :: tok
      integer :: p0
      character :: q
      p0 = pos
      q = text(pos:pos)
      tok = ''
      if (q == '''' .or. q == '"') then
        pos = pos + 1
        do
          if (pos > len(text)) then
            call fail('string not closed: '''//printable(text(p0:min(p0 + 30, len(text))))//'''')
            return
          end if
          if (text(pos:pos) == achar(10)) then
            call fail('string not closed on its line: '''//printable(text(p0:pos - 1))//'''')
            return
          end if
          if (text(pos:pos) == q) then
            if (pos < len(text)) then
              if (text(pos + 1:pos + 1) == q) then
                pos = pos + 2
                cycle
              end if
            end if
            pos = pos + 1
            exit
          end if
          pos = pos + 1
        end do
        tok = text(p0:pos - 1)
        return
      end if
      do while (pos <= len(text))
        if (index(' ,/!&='//achar(9)//achar(10)//achar(13), text(pos:pos)) > 0) exit
        if (iachar(text(pos:pos)) > 126 .or. text(pos:pos) == '''' .or. &
             text(pos:pos) == '"' .or. text(pos:pos) == '(' .or. text(pos:pos) == ')') then
          call fail('unexpected character in a value: '''//snippet()//'''')
          return
        end if
        pos = pos + 1
      end do
      tok = text(p0:pos - 1)
      if (len(tok) == 0) call fail('expected a value, found '''//snippet()//'''')
    end subroutine value_token

    !> Does an identifier followed by '=' or '(' start at pos (a new key)?
    logical function next_is_key()
      integer :: p
      p = pos
      next_is_key = .false.
      if (p > len(text)) return
      if (.not. is_alpha(text(p:p))) return
      do while (p <= len(text))
        if (.not. (is_alpha(text(p:p)) .or. index('0123456789', text(p:p)) > 0)) exit
        p = p + 1
      end do
      do while (p <= len(text))
        if (text(p:p) /= ' ' .and. text(p:p) /= achar(9)) exit
        p = p + 1
      end do
      if (p > len(text)) return
      next_is_key = text(p:p) == '=' .or. text(p:p) == '('
    end function next_is_key

    !> An identifier at pos (letters, digits, '_'), possibly empty.
    function ident() result(r)
      character(len=:), allocatable :: r
      integer :: p0
      p0 = pos
      if (pos <= len(text)) then
        if (is_alpha(text(pos:pos))) then
          do while (pos <= len(text))
            if (.not. (is_alpha(text(pos:pos)) .or. index('0123456789', text(pos:pos)) > 0)) exit
            pos = pos + 1
          end do
        end if
      end if
      r = text(p0:pos - 1)
    end function ident

    function digit_run() result(r)
      character(len=:), allocatable :: r
      integer :: p0
      p0 = pos
      do while (pos <= len(text))
        if (index('0123456789', text(pos:pos)) == 0) exit
        pos = pos + 1
      end do
      r = text(p0:pos - 1)
    end function digit_run

    character function peek()
      peek = achar(0)
      if (pos <= len(text)) peek = text(pos:pos)
    end function peek

    subroutine skip_spaces()
      do while (pos <= len(text))
        if (text(pos:pos) /= ' ' .and. text(pos:pos) /= achar(9)) exit
        pos = pos + 1
      end do
    end subroutine skip_spaces

    !> Skip blanks, newlines and ! comments (comments may hold any text).
    subroutine skip_blank()
      do while (pos <= len(text))
        select case (text(pos:pos))
        case (' ', achar(9), achar(13))
          pos = pos + 1
        case (achar(10))
          pos = pos + 1
          line = line + 1
        case ('!')
          do while (pos <= len(text))
            if (text(pos:pos) == achar(10)) exit
            pos = pos + 1
          end do
        case default
          exit
        end select
      end do
    end subroutine skip_blank

    !> Up to 30 characters from pos, for messages.
    function snippet() result(r)
      character(len=:), allocatable :: r
      integer :: e
      e = pos
      do while (e <= len(text) .and. e < pos + 30)
        if (text(e:e) == achar(10)) exit
        e = e + 1
      end do
      r = printable(text(pos:e - 1))
    end function snippet

    subroutine fail(msg)
      character(len=*), intent(in) :: msg
      call fail_at(line, msg)
    end subroutine fail

    subroutine fail_at(l, msg)
      integer, intent(in) :: l
      character(len=*), intent(in) :: msg
      call set_error(st, exit_bad_input, trim(path)//': line '//istr(l)//': '//msg)
    end subroutine fail_at

  end subroutine schema_read

  pure logical function is_alpha(c)
    character, intent(in) :: c
    is_alpha = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z') .or. c == '_'
  end function is_alpha

  !> The text of a quoted token: outer quotes removed, doubled quotes single.
  pure function unquote(tok) result(r)
    character(len=*), intent(in) :: tok
    character(len=:), allocatable :: r
    integer :: i
    r = ''
    i = 2
    do while (i < len(tok))
      r = r//tok(i:i)
      if (tok(i:i) == tok(1:1)) i = i + 1
      i = i + 1
    end do
  end function unquote

  !> Is s well-formed UTF-8 (ASCII, or multi-byte sequences with their continuation bytes)?
  pure logical function utf8_ok(s) result(ok)
    character(len=*), intent(in) :: s
    integer :: i, c, n, j
    ok = .true.
    i = 1
    do while (i <= len(s))
      c = iachar(s(i:i))
      if (c < 128) then
        n = 0
      else if (c >= 194 .and. c <= 223) then
        n = 1
      else if (c >= 224 .and. c <= 239) then
        n = 2
      else if (c >= 240 .and. c <= 244) then
        n = 3
      else
        ok = .false.
        return
      end if
      if (i + n > len(s)) then
        ok = .false.
        return
      end if
      do j = i + 1, i + n
        c = iachar(s(j:j))
        if (c < 128 .or. c > 191) then
          ok = .false.
          return
        end if
      end do
      i = i + n + 1
    end do
  end function utf8_ok

  integer function find_group(s, name) result(g)
    class(schema_t), intent(in) :: s
    character(len=*), intent(in) :: name
    do g = 1, s%ng
      if (trim(s%groups(g)%name) == trim(name)) return
    end do
    g = 0
  end function find_group


  function istr(v) result(s)
    integer, intent(in) :: v
    character(len=:), allocatable :: s
    s = int_str(int(v, i8))
  end function istr


  module function find_key(s, group, name) result(k)
    class(schema_t), intent(in) :: s
    character(len=*), intent(in) :: group, name
    integer :: k
    do k = 1, s%nk
      if (trim(s%keys(k)%group) == trim(group) .and. trim(s%keys(k)%name) == trim(name)) return
    end do
    k = 0
  end function find_key

  module integer function line_of(s, group, name)
    class(schema_t), intent(in) :: s
    character(len=*), intent(in) :: group, name
    integer :: k
    k = find_key(s, group, name)
    line_of = 0
    if (k > 0) line_of = s%keys(k)%line
  end function line_of

end submodule schema_reader
