!> One scene reader for every kind, driven by the kind's declaration of its keys.
!>
!> A kind declares each namelist group and key once (name, type, shape,
!> range or choices, unit, one-line doc), binding the key to the variable
!> that holds it (its default is that variable's value at declaration):
!>
!>   call s%group('oscillator', 'the oscillators and their integration')
!>   call s%key('omega', self%omega, 'rad/tau', 'natural angular frequency', lo=0.0_dp, lo_open=.true.)
!>
!> The same declaration then drives
!>   - reading (`read`): a quote-aware tokenizer; unknown or repeated groups
!>     and keys, indices out of range, wrong types, non-finite reals, repeat
!>     counts, text outside groups and strings that are not UTF-8 are refused
!>     naming the file, the line and what is allowed;
!>   - validation (`validate`): every key's range or choices (rules across
!>     keys stay a few lines in the kind);
!>   - the resolved scene (`text`): every key with its value, unit and doc,
!>     reals with every digit, strings quoted so that they round-trip;
!>   - the documentation (`describe`: a table; `json`: for pyorch's checks).
!>
!> The bindings are pointers to the kind's variables: a schema is built,
!> used and dropped inside one call on a TARGET object (never kept).
module schema
  use, intrinsic :: iso_c_binding, only: c_loc, c_f_pointer
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input
  use scene_input, only: read_text, printable, lower_case, quoted, real_str, int_str
  implicit none
  private

  public :: schema_t, max_steps_all

  !> One rule for every kind: at most 1e12 units of work (steps, ticks) per run.
  integer(i8), parameter :: max_steps_all = 1000000000000_i8

  integer, parameter :: name_len = 32
  integer, parameter :: max_keys = 256, max_groups = 24   !< per kind
  integer, parameter :: t_real = 1, t_int8 = 2, t_int4 = 3, t_logical = 4, t_str = 5
  character(len=*), parameter :: type_names(5) = [character(len=7) :: 'real', 'integer', &
       'integer', 'logical', 'string']

  type :: key_t
    character(len=name_len) :: group = '', name = ''
    integer :: type = 0
    integer :: size = 1                       !< elements (1 = scalar)
    logical :: is_array = .false.
    integer :: strlen = 0                     !< string keys: characters held
    logical :: ranged = .false.
    real(dp) :: lo = 0, hi = 0                !< real range
    integer(i8) :: ilo = 0, ihi = 0           !< integer range
    logical :: lo_open = .false., hi_open = .false.
    character(len=:), allocatable :: choices  !< string keys: '|a|b|c|' ('' = free text)
    character(len=:), allocatable :: unit, doc, default
    character(len=name_len) :: size_key = ''  !< arrays: integer key holding the elements in use
    integer :: line = 0                       !< line of the first assignment (0 = default)
    logical, allocatable :: given(:)
    real(dp), pointer :: r(:) => null()
    integer(i8), pointer :: i8v(:) => null()
    integer, pointer :: i4v(:) => null()
    logical, pointer :: lv(:) => null()
    character(len=:), pointer :: c => null()
  end type key_t

  type :: group_t
    character(len=name_len) :: name = ''
    character(len=:), allocatable :: doc
    logical :: required = .false.
    logical :: seen = .false.
    integer :: line = 0
  end type group_t

  !> The keys of one kind's scene.
  type :: schema_t
    character(len=:), allocatable :: kind      !< the kind's name
    character(len=:), allocatable :: header    !< first line of the resolved scene (after '! resolved scene: ')
    type(key_t), allocatable :: keys(:)
    type(group_t), allocatable :: groups(:)
    integer :: nk = 0, ng = 0
  contains
    procedure :: init
    procedure :: group => add_group
    procedure :: scene_group
    generic :: key => key_scalar, key_array
    procedure, private :: key_scalar, key_array
    procedure :: read => schema_read
    procedure :: validate => schema_validate
    procedure :: text => schema_text
    procedure :: describe => schema_describe
    procedure :: json => schema_json
    procedure :: line_of
    procedure :: group_names
  end type schema_t

contains

  ! ---------------------------------------------------------------- declaration

  !> Start the declaration of `kind`'s scene; `header` follows '! resolved scene: ' in scene.nml.
  subroutine init(s, kind, header)
    class(schema_t), intent(inout) :: s
    character(len=*), intent(in) :: kind, header
    s%kind = kind
    s%header = header
    s%nk = 0
    s%ng = 0
    allocate(s%keys(max_keys), s%groups(max_groups))
  end subroutine init

  !> A namelist group; the keys declared next belong to it.
  subroutine add_group(s, name, doc, required)
    class(schema_t), intent(inout) :: s
    character(len=*), intent(in) :: name, doc
    logical, intent(in), optional :: required
    if (s%ng == size(s%groups)) error stop 'schema: more than max_groups groups'
    s%ng = s%ng + 1
    s%groups(s%ng)%name = name
    s%groups(s%ng)%doc = doc
    if (present(required)) s%groups(s%ng)%required = required
  end subroutine add_group

  !> The group every kind opens with: &scene kind (this schema's kind only) and title,
  !> bound to the method's `kind` and `title`.
  subroutine scene_group(s, kind, title)
    class(schema_t), intent(inout) :: s
    character(len=*), intent(inout), target :: kind, title
    call s%group('scene', 'what this scene is', required=.true.)
    call s%key('kind', kind, '', 'the method and system of this scene', choices=s%kind)
    call s%key('title', title, '', 'free text (UTF-8)')
  end subroutine scene_group

  !> A new key in the current group (common part of every key_* procedure).
  function new_key(s, name, type, n, unit, doc) result(k)
    class(schema_t), intent(inout) :: s
    character(len=*), intent(in) :: name, unit, doc
    integer, intent(in) :: type, n
    integer :: k
    if (s%nk == size(s%keys)) error stop 'schema: more than max_keys keys'
    s%nk = s%nk + 1
    k = s%nk
    s%keys(k)%group = s%groups(s%ng)%name
    s%keys(k)%name = name
    s%keys(k)%type = type
    s%keys(k)%size = n
    s%keys(k)%unit = unit
    s%keys(k)%doc = doc
    s%keys(k)%choices = ''
    allocate(s%keys(k)%given(n))
    s%keys(k)%given = .false.
  end function new_key

  !> A key bound to scalar `v` (real(dp), integer, integer(i8), logical or character).
  !> lo, hi: the range (of v's type; reals open at an end with lo_open/hi_open); choices:
  !> 'a|b|c' for a string key (otherwise free text).
  subroutine key_scalar(s, name, v, unit, doc, lo, hi, lo_open, hi_open, choices)
    class(schema_t), intent(inout) :: s
    character(len=*), intent(in) :: name, unit, doc
    class(*), intent(inout), target :: v
    class(*), intent(in), optional :: lo, hi
    logical, intent(in), optional :: lo_open, hi_open
    character(len=*), intent(in), optional :: choices
    integer :: k
    select type (v)
    type is (real(dp))
      k = new_key(s, name, t_real, 1, unit, doc)
      call c_f_pointer(c_loc(v), s%keys(k)%r, [1])
    type is (integer(i8))
      k = new_key(s, name, t_int8, 1, unit, doc)
      call c_f_pointer(c_loc(v), s%keys(k)%i8v, [1])
    type is (integer)
      k = new_key(s, name, t_int4, 1, unit, doc)
      call c_f_pointer(c_loc(v), s%keys(k)%i4v, [1])
    type is (logical)
      k = new_key(s, name, t_logical, 1, unit, doc)
      call c_f_pointer(c_loc(v), s%keys(k)%lv, [1])
    type is (character(len=*))
      k = new_key(s, name, t_str, 1, unit, doc)
      s%keys(k)%c => v
      s%keys(k)%strlen = len(v)
      if (present(choices)) s%keys(k)%choices = '|'//choices//'|'
    class default
      error stop 'schema: a key of a type the reader does not know'
    end select
    call finish_key(s%keys(k), lo, hi, lo_open, hi_open)
  end subroutine key_scalar

  !> A key bound to array `v`; size_key: the integer key of the same group holding the
  !> elements in use (scene.nml writes those).
  subroutine key_array(s, name, v, unit, doc, lo, hi, lo_open, hi_open, size_key)
    class(schema_t), intent(inout) :: s
    character(len=*), intent(in) :: name, unit, doc
    class(*), intent(inout), target, contiguous :: v(:)
    class(*), intent(in), optional :: lo, hi
    logical, intent(in), optional :: lo_open, hi_open
    character(len=*), intent(in), optional :: size_key
    integer :: k
    select type (v)
    type is (real(dp))
      k = new_key(s, name, t_real, size(v), unit, doc)
      s%keys(k)%r => v
    type is (integer(i8))
      k = new_key(s, name, t_int8, size(v), unit, doc)
      s%keys(k)%i8v => v
    type is (integer)
      k = new_key(s, name, t_int4, size(v), unit, doc)
      s%keys(k)%i4v => v
    type is (logical)
      k = new_key(s, name, t_logical, size(v), unit, doc)
      s%keys(k)%lv => v
    class default
      error stop 'schema: an array key of a type the reader does not know'
    end select
    s%keys(k)%is_array = .true.
    if (present(size_key)) s%keys(k)%size_key = size_key
    call finish_key(s%keys(k), lo, hi, lo_open, hi_open)
  end subroutine key_array

  !> The range of a new key (numbers: the whole type when not given) and its default text.
  subroutine finish_key(kk, lo, hi, lo_open, hi_open)
    type(key_t), intent(inout) :: kk
    class(*), intent(in), optional :: lo, hi
    logical, intent(in), optional :: lo_open, hi_open
    select case (kk%type)
    case (t_real)
      kk%ranged = .true.
      kk%lo = -huge(1.0_dp)
      kk%hi = huge(1.0_dp)
      if (present(lo)) kk%lo = as_real(lo)
      if (present(hi)) kk%hi = as_real(hi)
      if (present(lo_open)) kk%lo_open = lo_open
      if (present(hi_open)) kk%hi_open = hi_open
    case (t_int8, t_int4)
      kk%ranged = .true.
      kk%ihi = huge(1_i8)
      if (kk%type == t_int4) kk%ihi = int(huge(1), i8)
      kk%ilo = -kk%ihi
      if (present(lo)) kk%ilo = as_int(lo)
      if (present(hi)) kk%ihi = as_int(hi)
    end select
    kk%default = value_text(kk)
  contains
    real(dp) function as_real(x)
      class(*), intent(in) :: x
      select type (x)
      type is (real(dp)); as_real = x
      type is (integer); as_real = x
      type is (integer(i8)); as_real = real(x, dp)
      class default; error stop 'schema: a real range that is not a number'
      end select
    end function as_real
    integer(i8) function as_int(x)
      class(*), intent(in) :: x
      select type (x)
      type is (integer); as_int = x
      type is (integer(i8)); as_int = x
      class default; error stop 'schema: an integer range that is not an integer'
      end select
    end function as_int
  end subroutine finish_key

  ! ---------------------------------------------------------------- queries

  integer function find_key(s, group, name) result(k)
    class(schema_t), intent(in) :: s
    character(len=*), intent(in) :: group, name
    do k = 1, s%nk
      if (trim(s%keys(k)%group) == trim(group) .and. trim(s%keys(k)%name) == trim(name)) return
    end do
    k = 0
  end function find_key

  integer function find_group(s, name) result(g)
    class(schema_t), intent(in) :: s
    character(len=*), intent(in) :: name
    do g = 1, s%ng
      if (trim(s%groups(g)%name) == trim(name)) return
    end do
    g = 0
  end function find_group

  !> Line of group%key's assignment in the file read (0: not given).
  integer function line_of(s, group, name)
    class(schema_t), intent(in) :: s
    character(len=*), intent(in) :: group, name
    integer :: k
    k = find_key(s, group, name)
    line_of = 0
    if (k > 0) line_of = s%keys(k)%line
  end function line_of

  !> '&a &b &c' (messages).
  function group_names(s) result(r)
    class(schema_t), intent(in) :: s
    character(len=:), allocatable :: r
    integer :: g
    r = ''
    do g = 1, s%ng
      if (g > 1) r = r//' '
      r = r//'&'//trim(s%groups(g)%name)
    end do
  end function group_names

  !> Elements of key k in use (its size_key's value, within [1, size]; else all).
  integer function elements_in_use(s, k) result(n)
    class(schema_t), intent(in) :: s
    integer, intent(in) :: k
    integer :: j
    n = s%keys(k)%size
    if (len_trim(s%keys(k)%size_key) == 0) return
    j = find_key(s, s%keys(k)%group, s%keys(k)%size_key)
    if (j == 0) return
    if (associated(s%keys(j)%i8v)) n = int(max(1_i8, min(int(n, i8), s%keys(j)%i8v(1))))
    if (associated(s%keys(j)%i4v)) n = max(1, min(n, s%keys(j)%i4v(1)))
  end function elements_in_use

  ! ---------------------------------------------------------------- values as text

  !> Element e of key kk as scene text (reals with every digit, strings quoted).
  function element_text(kk, e) result(t)
    type(key_t), intent(in) :: kk
    integer, intent(in) :: e
    character(len=:), allocatable :: t
    select case (kk%type)
    case (t_real); t = real_str(kk%r(e))
    case (t_int8); t = int_str(kk%i8v(e))
    case (t_int4); t = int_str(int(kk%i4v(e), i8))
    case (t_logical); t = trim(merge('.true. ', '.false.', kk%lv(e)))
    case (t_str); t = quoted(trim(kk%c))
    case default; t = '?'
    end select
  end function element_text

  function value_text(kk, n) result(t)
    type(key_t), intent(in) :: kk
    integer, intent(in), optional :: n
    character(len=:), allocatable :: t
    integer :: e, m
    m = kk%size
    if (present(n)) m = n
    t = ''
    do e = 1, m
      if (e > 1) t = t//', '
      t = t//element_text(kk, e)
    end do
  end function value_text

  !> Allowed values of key kk, as messages and tables state them.
  function allowed_text(kk) result(t)
    type(key_t), intent(in) :: kk
    character(len=:), allocatable :: t
    character(len=1) :: b1, b2
    integer :: p, q
    t = ''
    select case (kk%type)
    case (t_real)
      if (.not. kk%ranged) return
      b1 = merge('(', '[', kk%lo_open)
      b2 = merge(')', ']', kk%hi_open)
      if (kk%lo <= -huge(1.0_dp) .and. kk%hi >= huge(1.0_dp)) then
        t = 'finite'
      else if (kk%hi >= huge(1.0_dp)) then
        t = b1//real_str(kk%lo)//', inf)'
      else if (kk%lo <= -huge(1.0_dp)) then
        t = '(-inf, '//real_str(kk%hi)//b2
      else
        t = b1//real_str(kk%lo)//', '//real_str(kk%hi)//b2
      end if
    case (t_int8, t_int4)
      if (kk%ranged) t = '['//int_str(kk%ilo)//', '//int_str(kk%ihi)//']'
    case (t_logical)
      t = '.true. | .false.'
    case (t_str)
      if (len(kk%choices) == 0) then
        t = 'text of at most '//int_str(int(kk%strlen, i8))//' characters'
        return
      end if
      p = 2
      do
        q = index(kk%choices(p:), '|')
        if (q == 0) exit
        if (len(t) > 0) t = t//' | '
        t = t//quoted(kk%choices(p:p + q - 2))
        p = p + q
      end do
    end select
  end function allowed_text

  ! ---------------------------------------------------------------- resolved scene

  !> The resolved scene: '! resolved scene: HEADER', then every group and key
  !> ('  key = value  ! [unit] doc'), lines ending in achar(10).
  function schema_text(s) result(text)
    class(schema_t), intent(in) :: s
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = achar(10)
    integer :: g, k
    character(len=:), allocatable :: note
    text = '! resolved scene: '//s%header//nl
    do g = 1, s%ng
      text = text//'&'//trim(s%groups(g)%name)//'  ! '//s%groups(g)%doc//nl
      do k = 1, s%nk
        if (trim(s%keys(k)%group) /= trim(s%groups(g)%name)) cycle
        note = s%keys(k)%doc
        if (len(s%keys(k)%unit) > 0) note = '['//s%keys(k)%unit//'] '//note
        text = text//'  '//trim(s%keys(k)%name)//' = '// &
             value_text(s%keys(k), elements_in_use(s, k))//'  ! '//note//nl
      end do
      text = text//'/'//nl
    end do
  end function schema_text

  !> A table of every key: group, key, type, default, allowed, unit, doc (Markdown).
  function schema_describe(s) result(text)
    class(schema_t), intent(in) :: s
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = achar(10)
    integer :: g, k
    character(len=:), allocatable :: ty
    text = '# '//s%header//nl//nl// &
         '| group | key | type | default | allowed | unit | meaning |'//nl// &
         '|---|---|---|---|---|---|---|'//nl
    do g = 1, s%ng
      do k = 1, s%nk
        if (trim(s%keys(k)%group) /= trim(s%groups(g)%name)) cycle
        ty = trim(type_names(s%keys(k)%type))
        if (s%keys(k)%is_array) ty = ty//'('//int_str(int(s%keys(k)%size, i8))//')'
        text = text//'| &'//trim(s%groups(g)%name)//' | `'//trim(s%keys(k)%name)//'` | '// &
             ty//' | `'//md(s%keys(k)%default)//'` | '//md(allowed_text(s%keys(k)))//' | '// &
             md(s%keys(k)%unit)//' | '//md(s%keys(k)%doc)//' |'//nl
      end do
    end do
  contains
    function md(x) result(y)
      character(len=*), intent(in) :: x
      character(len=:), allocatable :: y
      integer :: i
      y = ''
      do i = 1, len(x)
        if (x(i:i) == '|') then
          y = y//'\|'
        else
          y = y//x(i:i)
        end if
      end do
    end function md
  end function schema_describe

  !> The declaration as JSON (pyorch checks --set and sweep keys with it).
  function schema_json(s) result(text)
    class(schema_t), intent(in) :: s
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = achar(10)
    integer :: g, k, p, q
    logical :: first
    type(key_t) :: kk
    text = '{"kind": '//js(s%kind)//', "header": '//js(s%header)//', "groups": ['//nl
    do g = 1, s%ng
      text = text//merge(',', ' ', g > 1)//' {"name": '//js(trim(s%groups(g)%name))// &
           ', "doc": '//js(s%groups(g)%doc)//', "keys": ['//nl
      first = .true.
      do k = 1, s%nk
        kk = s%keys(k)
        if (trim(kk%group) /= trim(s%groups(g)%name)) cycle
        text = text//merge('  ', ' ,', first)//'{"name": '//js(trim(kk%name))//', "type": '// &
             js(trim(type_names(kk%type)))//', "size": '//int_str(int(kk%size, i8))// &
             ', "array": '//trim(merge('true ', 'false', kk%is_array))
        first = .false.
        select case (kk%type)
        case (t_real)
          if (kk%ranged) then
            if (kk%lo > -huge(1.0_dp)) text = text//', "lo": '//real_str(kk%lo)
            if (kk%hi < huge(1.0_dp)) text = text//', "hi": '//real_str(kk%hi)
            text = text//', "lo_open": '//trim(merge('true ', 'false', kk%lo_open))// &
                 ', "hi_open": '//trim(merge('true ', 'false', kk%hi_open))
          end if
        case (t_int8, t_int4)
          text = text//', "lo": '//int_str(kk%ilo)//', "hi": '//int_str(kk%ihi)
        case (t_str)
          text = text//', "strlen": '//int_str(int(kk%strlen, i8))
          if (len(kk%choices) > 0) then
            text = text//', "choices": ['
            p = 2
            do
              q = index(kk%choices(p:), '|')
              if (q == 0) exit
              if (p > 2) text = text//', '
              text = text//js(kk%choices(p:p + q - 2))
              p = p + q
            end do
            text = text//']'
          end if
        end select
        if (kk%type == t_str) then
          text = text//', "default": '//js(trim(kk%c))
        else
          text = text//', "default": '//jlist(kk)
        end if
        if (len_trim(kk%size_key) > 0) text = text//', "size_key": '//js(trim(kk%size_key))
        text = text//', "unit": '//js(kk%unit)//', "doc": '//js(kk%doc)//'}'//nl
      end do
      text = text//' ]}'//nl
    end do
    text = text//']}'//nl
  contains
    function jlist(kk) result(y)
      type(key_t), intent(in) :: kk
      character(len=:), allocatable :: y
      integer :: e
      y = ''
      do e = 1, kk%size
        if (e > 1) y = y//', '
        select case (kk%type)
        case (t_real); y = y//real_str(kk%r(e))
        case (t_int8); y = y//int_str(kk%i8v(e))
        case (t_int4); y = y//int_str(int(kk%i4v(e), i8))
        case (t_logical); y = y//trim(merge('true ', 'false', kk%lv(e)))
        end select
      end do
      if (kk%is_array) y = '['//y//']'
    end function jlist
    function js(x) result(y)
      character(len=*), intent(in) :: x
      character(len=:), allocatable :: y
      integer :: i
      y = '"'
      do i = 1, len(x)
        select case (x(i:i))
        case ('"'); y = y//'\"'
        case ('\'); y = y//'\\'
        case default
          if (iachar(x(i:i)) < 32) then
            y = y//' '
          else
            y = y//x(i:i)
          end if
        end select
      end do
      y = y//'"'
    end function js
  end function schema_json

  ! ---------------------------------------------------------------- validation

  !> Every key's range or choices, in declaration order (the first failure is reported).
  subroutine schema_validate(s, path, st)
    class(schema_t), intent(in) :: s
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: k, e, n
    logical :: ok
    type(key_t) :: kk
    character(len=:), allocatable :: where, name
    do k = 1, s%nk
      if (st%code /= 0) return
      kk = s%keys(k)
      n = kk%size
      do e = 1, n
        ok = .true.
        select case (kk%type)
        case (t_real)
          ok = ieee_is_finite(kk%r(e))
          if (ok .and. kk%ranged) ok = in_rrange(kk, kk%r(e))
        case (t_int8)
          if (kk%ranged) ok = kk%i8v(e) >= kk%ilo .and. kk%i8v(e) <= kk%ihi
        case (t_int4)
          if (kk%ranged) ok = kk%i4v(e) >= kk%ilo .and. kk%i4v(e) <= kk%ihi
        case (t_str)
          if (len(kk%choices) > 0) ok = index(kk%choices, '|'//trim(kk%c)//'|') > 0 .and. &
               len_trim(kk%c) > 0
        end select
        if (ok) cycle
        name = trim(kk%name)
        if (kk%is_array) name = name//'('//int_str(int(e, i8))//')'
        where = trim(path)//': '
        if (kk%line > 0) where = where//'line '//int_str(int(kk%line, i8))//': '
        if (kk%type == t_str) then
          call set_error(st, exit_bad_input, where//'&'//trim(kk%group)//' '//name//' = '// &
               element_text(kk, e)//': allowed values '//allowed_text(kk))
        else
          call set_error(st, exit_bad_input, where//'&'//trim(kk%group)//' '//name//' = '// &
               element_text(kk, e)//': allowed range '//allowed_text(kk)//unit_note(kk))
        end if
        return
      end do
    end do
  end subroutine schema_validate

  function unit_note(kk) result(t)
    type(key_t), intent(in) :: kk
    character(len=:), allocatable :: t
    t = ''
    if (len(kk%unit) > 0 .and. kk%type /= t_str .and. kk%type /= t_logical) t = ' ['//kk%unit//']'
  end function unit_note

  logical function in_rrange(kk, v) result(ok)
    type(key_t), intent(in) :: kk
    real(dp), intent(in) :: v
    if (kk%lo_open) then
      ok = v > kk%lo
    else
      ok = v >= kk%lo
    end if
    if (kk%hi_open) then
      ok = ok .and. v < kk%hi
    else
      ok = ok .and. v <= kk%hi
    end if
  end function in_rrange

  ! ---------------------------------------------------------------- reading

  !> Read the scene file at `path` into the bound variables (types and syntax
  !> checked, ranges not: see validate). Absent groups and keys keep their defaults.
  subroutine schema_read(s, path, st)
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

  function istr(v) result(s)
    integer, intent(in) :: v
    character(len=:), allocatable :: s
    s = int_str(int(v, i8))
  end function istr

end module schema
