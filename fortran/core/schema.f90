!> One scene reader for every kind, driven by the kind's declaration of its keys.
!>
!> A kind declares each namelist group and key once (name, type, shape, range or choices,
!> unit, one-line doc), binding the key to the variable that holds it (its default is that
!> variable's value at declaration):
!>
!>   call s%group('oscillator', 'the oscillators and their integration')
!>   call s%key('omega', self%omega, 'rad/tau', 'natural angular frequency', lo=0.0_dp, lo_open=.true.)
!>
!> The same declaration drives reading (`read`, the submodule schema_read: every refusal names
!> the file, the line and what is allowed), validation (`validate`: every key's range or
!> choices; rules across keys stay a few lines in the kind), the resolved scene (`text`: every
!> key with its value, unit and doc, reals with every digit, strings that round-trip) and the
!> documentation (`describe`: a table; `json`: for pyorch's checks).
!>
!> The bindings are pointers to the kind's variables: a schema is built, used and dropped
!> inside one call on a TARGET object (never kept).
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

  interface
    !> Read the scene file at `path` into the bound variables (schema_read.f90).
    module subroutine schema_read(s, path, st)
      class(schema_t), intent(inout) :: s
      character(len=*), intent(in) :: path
      type(status_t), intent(inout) :: st
    end subroutine schema_read
    !> Index of group%key in s%keys (0: none); separate, the reader needs it (schema_read.f90)
    module function find_key(s, group, name) result(k)
      class(schema_t), intent(in) :: s
      character(len=*), intent(in) :: group, name
      integer :: k
    end function find_key
    !> Line of group%key's assignment in the file read (0: not given).
    module integer function line_of(s, group, name)
      class(schema_t), intent(in) :: s
      character(len=*), intent(in) :: group, name
    end function line_of
  end interface

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


end module schema
