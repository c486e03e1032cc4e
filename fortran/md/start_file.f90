!> Start files: one frame of particles a run starts from (`&particles start_file` of the
!> kinds magnet_bed and lj_box), in a plain text format the engine reads without any GSD
!> library (pyorch converts a GSD frame into it: `pyorch scene start-file`, `pyorch run
!> --start-from`). The format, version 1 ('#' starts a comment anywhere; blank lines are
!> skipped; words are separated by blanks or tabs):
!>
!>     partsim_start 1                 the format and its version
!>     kind magnet_bed                 the scene's kind
!>     units D1 D1/T                   the kind's length and speed units (lj_box: a a/T)
!>     n 368                           the number of particles: the scene's n
!>     box 60 75                       the scene's cell (bed: &cell width height; lj_box: l l)
!>     columns x y vx vy species       x, y required; vx vy together or not at all;
!>                                     species (the bed: 1 .. n_species) optional
!>     then n rows, one a particle (its id is its row: 1, 2, ...), one value a column
!>
!> Positions are from the lower-left corner of the cell (the engine's frame, not HOOMD's
!> centred box). Everything is checked before the run starts, and a refusal names the line:
!> the header, the number of values, finite numbers, species in range, the count; the kind
!> then checks the region the centres may occupy (start_check_region) and the closest
!> approach (start_check_distances). The CRC-64 of the file is kept (start_t%crc): the
!> kinds record it in run.json and in their checkpoints, so a resume refuses a start file
!> that changed since the run began.
module start_file
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, exit_io, msg_len
  use scene_input, only: int_str, real_str, printable
  use text_table, only: next_values, word, ints, real_literal
  use ckpt, only: file_crc64
  use run_meta, only: json_escape
  implicit none
  private

  public :: start_t, start_read, start_check_region, start_check_distances, start_json, &
       check_start_crc, start_release

  integer, parameter :: format_version = 1
  integer, parameter :: c_x = 1, c_y = 2, c_vx = 3, c_vy = 4, c_species = 5
  character(len=*), parameter :: col_names(5) = [character(len=7) :: 'x', 'y', 'vx', 'vy', &
       'species']

  !> A start file as read: rows in id order.
  type :: start_t
    character(len=:), allocatable :: path    !< as the scene names it
    character(len=:), allocatable :: where   !< message prefix naming the scene and the key
    integer :: n = 0
    real(dp), allocatable :: x(:), y(:)      !< positions [length unit], from the cell's corner
    real(dp), allocatable :: vx(:), vy(:)    !< velocities [speed unit] (has_velocity)
    integer, allocatable :: species(:)       !< 1-based species (has_species; else 1)
    integer, allocatable :: line(:)          !< the file's line of each row (messages)
    logical :: has_velocity = .false., has_species = .false.
    integer(i8) :: crc = 0                   !< CRC-64 of the whole file
  end type start_t

contains

  !> Read and check start file `path` against the scene: kind, units (length, speed),
  !> n, box (Lx, Ly) [length unit], species 1..n_species (n_species = 0: no species
  !> column allowed), speeds |v| <= vmax [speed unit] (vkey: the scene key whose range that
  !> is). `where` begins every message (e.g. "SCENE: &particles start_file = 'PATH'");
  !> box_keys names the scene's keys of the box. Nothing but sf is changed.
  subroutine start_read(where, path, kind, length_unit, speed_unit, n, box, box_keys, &
       n_species, vmax, vkey, sf, st)
    character(len=*), intent(in) :: where, path, kind, length_unit, speed_unit, box_keys, vkey
    integer, intent(in) :: n, n_species
    real(dp), intent(in) :: box(2), vmax
    type(start_t), intent(out) :: sf
    type(status_t), intent(inout) :: st
    integer :: u, ios, ln, nv, stage, got, k, iv(1)
    integer :: cols(5), ncol
    real(dp) :: v(2)
    character(len=:), allocatable :: line, w
    character(len=msg_len) :: iom
    logical :: ok
    sf%path = path
    sf%where = where
    iom = ''
    open(newunit=u, file=path, status='old', action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call fail('cannot open the start file: '//trim(iom))
      return
    end if
    stage = 0; got = 0; ln = 0; ncol = 0; cols = 0
    do
      call next_values(u, line, ln, nv, ios)
      if (ios /= 0) exit
      stage = stage + 1
      select case (stage)
      case (1)
        ok = nv == 2 .and. word(line, 1) == 'partsim_start'
        if (ok) call ints(word(line, 2), iv, ok)
        if (.not. ok) then
          call fail(at()//'expected "partsim_start '//int_str(int(format_version, i8))// &
               '" (the format and its version) as the first line that is not a comment'// &
               found())
        else if (iv(1) /= format_version) then
          call fail(at()//'format version '//int_str(int(iv(1), i8))//': this engine '// &
               'reads version '//int_str(int(format_version, i8)))
        end if
      case (2)
        if (nv /= 2 .or. word(line, 1) /= 'kind') then
          call fail(at()//'expected "kind '//kind//'"'//found())
        else if (word(line, 2) /= kind) then
          call fail(at()//'kind '//printable(word(line, 2))//': the scene is of kind '//kind)
        end if
      case (3)
        if (nv /= 3 .or. word(line, 1) /= 'units' .or. word(line, 2) /= length_unit .or. &
             word(line, 3) /= speed_unit) call fail(at()//'expected "units '//length_unit// &
             ' '//speed_unit//'" (the kind''s length and speed units)'//found())
      case (4)
        ok = nv == 2 .and. word(line, 1) == 'n'
        if (ok) call ints(word(line, 2), iv, ok)
        if (.not. ok) then
          call fail(at()//'expected "n N": the number of particles'//found())
        else if (iv(1) /= n) then
          call fail(at()//'n '//int_str(int(iv(1), i8))//': the scene has &particles n = '// &
               int_str(int(n, i8))//' (the counts must agree)')
        end if
        if (st%code == 0) then
          sf%n = n
          allocate(sf%x(n), sf%y(n), sf%vx(n), sf%vy(n), sf%species(n), sf%line(n))
          sf%vx = 0; sf%vy = 0; sf%species = 1
        end if
      case (5)
        ok = nv == 3 .and. word(line, 1) == 'box'
        if (ok) call real_word(word(line, 2), v(1), ok)
        if (ok) call real_word(word(line, 3), v(2), ok)
        if (.not. ok) then
          call fail(at()//'expected "box Lx Ly" ['//length_unit//']'//found())
        else if (any(abs(v - box) > 1.0e-9_dp*box)) then
          call fail(at()//'box '//real_str(v(1))//' x '//real_str(v(2))//' '//length_unit// &
               ': the scene''s is '//real_str(box(1))//' x '//real_str(box(2))//' '// &
               length_unit//' ('//box_keys//')')
        end if
      case (6)
        call read_columns()
      case default
        got = got + 1
        if (got > n) then
          call fail(at()//'more than n = '//int_str(int(n, i8))//' particle rows')
        else if (nv /= ncol) then
          call fail(at()//'expected '//int_str(int(ncol, i8))//' values (columns'// &
               column_list()//')'//found())
        else
          call read_row(got)
        end if
      end select
      if (st%code /= 0) exit
    end do
    close(u)
    if (st%code /= 0) return
    if (stage < 6) then
      call fail('incomplete header: expected the lines "partsim_start 1", "kind", "units", '// &
           '"n", "box", "columns" before the rows')
    else if (got < n) then
      call fail('only '//int_str(int(got, i8))//' particle rows, n = '//int_str(int(n, i8))// &
           ' needed')
    end if
    if (st%code /= 0) return
    call file_crc64(path, sf%crc, st)
  contains
    !> "columns NAME ...": each known, at most once, x and y present, vx with vy.
    subroutine read_columns()
      integer :: j, m
      character(len=:), allocatable :: allowed
      allowed = 'x y vx vy'
      if (n_species > 0) allowed = allowed//' species'
      if (word(line, 1) /= 'columns' .or. nv < 3) then
        call fail(at()//'expected "columns NAME ..." (from: '//allowed//'; x and y '// &
             'required)'//found())
        return
      end if
      ncol = nv - 1
      if (ncol > 5) then
        call fail(at()//'more than 5 columns'//found())
        return
      end if
      do j = 1, ncol
        w = word(line, j + 1)
        m = 0
        do k = 1, size(col_names)
          if (w == trim(col_names(k))) m = k
        end do
        if (m == c_species .and. n_species == 0) m = 0
        if (m == 0) then
          call fail(at()//'column '''//printable(w)//''': allowed '//allowed)
          return
        end if
        if (any(cols(1:j - 1) == m)) then
          call fail(at()//'column '''//w//''' given twice')
          return
        end if
        cols(j) = m
      end do
      if (.not. (any(cols(1:ncol) == c_x) .and. any(cols(1:ncol) == c_y))) then
        call fail(at()//'columns x and y are required'//found())
      else if (any(cols(1:ncol) == c_vx) .neqv. any(cols(1:ncol) == c_vy)) then
        call fail(at()//'columns vx and vy go together (both or neither)'//found())
      end if
      sf%has_velocity = any(cols(1:ncol) == c_vx)
      sf%has_species = any(cols(1:ncol) == c_species)
    end subroutine read_columns

    !> Row i (particle i): every word checked (a plain number; species an integer in
    !> range), then the row read in one statement, every value finite before it is stored.
    subroutine read_row(i)
      integer, intent(in) :: i
      integer :: j, ios, m
      real(dp) :: vals(5)
      sf%line(i) = ln
      do j = 1, ncol
        w = word(line, j)
        if (cols(j) == c_species) then
          m = 1
          if (index('+-', w(1:1)) > 0) m = 2
          if (len(w) < m .or. len(w) - m >= 9 .or. verify(w(m:), '0123456789') /= 0) then
            call fail(at()//'species '''//printable(w)//''': must be an integer')
            return
          end if
        else if (.not. real_literal(w)) then
          call fail(at()//trim(col_names(cols(j)))//' = '''//printable(w)//''': must be a '// &
               'finite number')
          return
        end if
      end do
      read(line, *, iostat=ios) vals(1:ncol)
      do j = 1, ncol
        if (ios /= 0 .or. .not. abs(vals(j)) <= huge(1.0_dp)) then
          call fail(at()//trim(col_names(cols(j)))//' = '''//printable(word(line, j))// &
               ''': must be a finite number')
          return
        end if
        select case (cols(j))
        case (c_x); sf%x(i) = vals(j)
        case (c_y); sf%y(i) = vals(j)
        case (c_vx); sf%vx(i) = vals(j)
        case (c_vy); sf%vy(i) = vals(j)
        case (c_species)
          sf%species(i) = nint(vals(j))
          if (sf%species(i) < 1 .or. sf%species(i) > n_species) then
            call fail(at()//'species '//int_str(int(sf%species(i), i8))//': allowed [1, '// &
                 int_str(int(n_species, i8))//'] (&particles n_species = '// &
                 int_str(int(n_species, i8))//')')
            return
          end if
        end select
      end do
      if (hypot(sf%vx(i), sf%vy(i)) > vmax) call fail(at()//'speed '// &
           real_str(hypot(sf%vx(i), sf%vy(i)))//' '//speed_unit//': allowed [0, '// &
           real_str(vmax)//'] '//speed_unit//' (the range of '//vkey//')')
    end subroutine read_row

    function column_list() result(s)
      character(len=:), allocatable :: s
      integer :: j
      s = ''
      do j = 1, ncol
        s = s//' '//trim(col_names(cols(j)))
      end do
    end function column_list

    function at() result(s)
      character(len=:), allocatable :: s
      s = 'line '//int_str(int(ln, i8))//': '
    end function at

    !> ", found: 'the line'" (the line cut at 60 characters).
    function found() result(s)
      character(len=:), allocatable :: s
      character(len=:), allocatable :: shown
      shown = trim(adjustl(line))
      if (len(shown) > 60) shown = shown(:57)//'...'
      s = ', found '''//printable(shown)//''''
    end function found

    subroutine fail(msg)
      character(len=*), intent(in) :: msg
      call set_error(st, exit_bad_input, where//': '//msg)
    end subroutine fail
  end subroutine start_read

  !> One word as a finite real (real_literal: no repeat counts, NaN or Infinity).
  subroutine real_word(t, v, ok)
    character(len=*), intent(in) :: t
    real(dp), intent(out) :: v
    logical, intent(out) :: ok
    integer :: ios
    v = 0
    ok = real_literal(t)
    if (.not. ok) return
    read(t, *, iostat=ios) v
    ok = ios == 0
    if (ok) ok = abs(v) <= huge(1.0_dp)
  end subroutine real_word

  !> Every centre within [lo(1), hi(1)] x [lo(2), hi(2)] (what: the region and why, for
  !> the message); the first one outside is refused naming its line, and how many are.
  subroutine start_check_region(sf, lo, hi, unit, what, st)
    type(start_t), intent(in) :: sf
    real(dp), intent(in) :: lo(2), hi(2)
    character(len=*), intent(in) :: unit, what
    type(status_t), intent(inout) :: st
    integer :: i, first, nout
    logical :: out
    first = 0
    nout = 0
    do i = 1, sf%n
      out = sf%x(i) < lo(1) .or. sf%x(i) > hi(1) .or. sf%y(i) < lo(2) .or. sf%y(i) > hi(2)
      if (out) then
        nout = nout + 1
        if (first == 0) first = i
      end if
    end do
    if (first == 0) return
    i = first
    call set_error(st, exit_bad_input, sf%where//': line '//int_str(int(sf%line(i), i8))// &
         ': particle '//int_str(int(i, i8))//' at ('//real_str(sf%x(i))//', '// &
         real_str(sf%y(i))//') '//unit//' is outside '//what//': allowed x in ['// &
         real_str(lo(1))//', '//real_str(hi(1))//'], y in ['//real_str(lo(2))//', '// &
         real_str(hi(2))//'] '//unit//' ('//int_str(int(nout, i8))//' of '// &
         int_str(int(sf%n, i8))//' particles outside)')
  end subroutine start_check_region

  !> No two centres closer than dmin (nor coincident when dmin = 0): a cell grid of side
  !> >= dmin, O(n). The first particle (in row order) with a neighbour too close is refused
  !> with its closest such neighbour, both lines, their distance and the key (`key`, e.g.
  !> "&physics min_distance") that sets dmin.
  subroutine start_check_distances(sf, dmin, unit, key, st)
    type(start_t), intent(in) :: sf
    real(dp), intent(in) :: dmin
    character(len=*), intent(in) :: unit, key
    type(status_t), intent(inout) :: st
    integer :: nx, ny, i, j, cx, cy, jx, jy, best
    integer, allocatable :: head(:), next(:)
    real(dp) :: x0, y0, cs, d2, lim, bd2
    if (sf%n < 2) return
    x0 = minval(sf%x); y0 = minval(sf%y)
    cs = max(dmin, (maxval(sf%x) - x0)/sqrt(real(sf%n, dp)), &
         (maxval(sf%y) - y0)/sqrt(real(sf%n, dp)), tiny(1.0_dp))
    nx = min(int((maxval(sf%x) - x0)/cs) + 1, 100000)
    ny = min(int((maxval(sf%y) - y0)/cs) + 1, 100000)
    allocate(head(nx*ny), next(sf%n))
    head = 0
    do i = sf%n, 1, -1
      call cell_of(i, cx, cy)
      next(i) = head(1 + cx + nx*cy)
      head(1 + cx + nx*cy) = i
    end do
    lim = dmin**2
    do i = 1, sf%n
      call cell_of(i, cx, cy)
      best = 0
      bd2 = huge(1.0_dp)
      do jy = max(0, cy - 1), min(ny - 1, cy + 1)
        do jx = max(0, cx - 1), min(nx - 1, cx + 1)
          j = head(1 + jx + nx*jy)
          do while (j > 0)
            if (j /= i) then
              d2 = (sf%x(j) - sf%x(i))**2 + (sf%y(j) - sf%y(i))**2
              if ((d2 < lim .or. d2 == 0) .and. d2 < bd2) then
                bd2 = d2
                best = j
              end if
            end if
            j = next(j)
          end do
        end do
      end do
      if (best > 0) then
        call set_error(st, exit_bad_input, sf%where//': lines '// &
             int_str(int(sf%line(i), i8))//' and '//int_str(int(sf%line(best), i8))// &
             ': particles '//int_str(int(i, i8))//' and '//int_str(int(best, i8))//' are '// &
             real_str(sqrt(bd2))//' '//unit//' apart, closer than '//key//' = '// &
             real_str(dmin)//' '//unit//' (the closest approach allowed at the start)')
        return
      end if
    end do
  contains
    subroutine cell_of(k, ix, iy)
      integer, intent(in) :: k
      integer, intent(out) :: ix, iy
      ix = min(nx - 1, int((sf%x(k) - x0)/cs))
      iy = min(ny - 1, int((sf%y(k) - y0)/cs))
    end subroutine cell_of
  end subroutine start_check_distances

  !> Free the rows once the state holds them (path, crc and flags stay).
  subroutine start_release(sf)
    type(start_t), intent(inout) :: sf
    if (allocated(sf%x)) deallocate(sf%x, sf%y, sf%vx, sf%vy, sf%species, sf%line)
  end subroutine start_release

  !> run.json member of a run started from a file: its path, the CRC-64 of its bytes (16
  !> hex digits, CRC-64/XZ as the checkpoints') and where the velocities came from.
  function start_json(sf) result(text)
    type(start_t), intent(in) :: sf
    character(len=:), allocatable :: text
    character(len=16) :: hex
    text = ''
    if (.not. allocated(sf%path)) return
    write(hex, '(z16.16)') sf%crc
    text = '  "start_file": {"path": "'//json_escape(sf%path)//'", "crc64": "'//hex// &
         '", "n": '//int_str(int(sf%n, i8))//', "velocities": "'// &
         trim(merge('file ', 'scene', sf%has_velocity))//'"},'//achar(10)
  end function start_json

  !> On resume: the CRC-64 a checkpoint recorded for the start file (next on stream unit u;
  !> 0: the run had none) must be that of the file the scene names now.
  subroutine check_start_crc(u, sf, st)
    integer, intent(in) :: u
    type(start_t), intent(in) :: sf
    type(status_t), intent(inout) :: st
    integer(i8) :: crc
    integer :: ios
    read(u, iostat=ios) crc
    if (ios /= 0) then
      call set_error(st, exit_io, 'checkpoint: payload does not match the scene')
    else if (crc /= sf%crc .and. .not. allocated(sf%path)) then
      call set_error(st, exit_io, 'checkpoint: refused: the run started from a start file, '// &
           'the scene names none')
    else if (crc /= sf%crc) then
      call set_error(st, exit_io, 'checkpoint: refused: the start file '''//sf%path// &
           ''' changed since the run began (its CRC-64 differs from the one the checkpoint '// &
           'recorded): restore the file the run started from')
    end if
  end subroutine check_start_crc

end module start_file
