!> Event-driven dynamics of hard disks in a closed rectangular box
!> Longer than 600 lines because the event loop, the predictions and the cell crossings it
!> calls per event are one compilation unit: gfortran inlines them only within a file (no
!> LTO in this build), and the per-event cost is the method's speed (bench/RESULTS.md s. 32).
!> [0, lx] x [0, ly], with an aggregate of static disks (infinite mass) that
!> free disks stick to (or bounce off).
!>
!> State: each disk i stores its position (x, y) at its own time tl and its
!> velocity (vx, vy); it moves ballistically, x(t) = x + vx (t - tl), until its
!> next event. The stored states are only touched by events, so every
!> prediction is a pure function of the stored states (the calendar rebuilt
!> from them after a restore predicts bit-identical times). Memory layout: one
!> 64-byte record per disk (disk_t: position, velocity, tl, radius, collision
!> counter, cell link) and one per disk's calendar entry, prediction and mass
!> (edmd_buckets' bq_entry_t), so that a neighbour, a pop, an update or a hit
!> costs one cache line, not one per array (bench/RESULTS.md s. 18, 32.1).
!>
!> Events: disk-disk collision (time from |dr + dv t| = r_i + r_j in the
!> stable form dt = c / (-b + sqrt(b^2 - a c)), b = dr.dv < 0, c = |dr|^2 -
!> sigma^2; c <= 0 while approaching = in contact now, dt = 0), disk-wall
!> collision, and cell crossing (the box is cut into cells of side >= the
!> largest diameter; a disk only looks at the 3 x 3 cells around its own;
!> it keeps its best pair candidate across crossings and scans only the 3
!> cells that became adjacent, unless that candidate's partner changed).
!>
!> Calendar: one entry per free disk (its earliest event); an entry naming a
!> partner whose collision counter changed since the prediction is stale and is
!> re-predicted when it reaches the top. 'buckets': a bucketed calendar queue
!> (edmd_buckets), O(1) per event; 'heap': an indexed binary heap (edmd_heap),
!> O(log N); both order ties by the disk id and pop the same sequence. From
!> prefetch_min_n disks on, the disk of the queue's likely next event is
!> prefetched while the current one is processed (loads only, never the order).
!> 'rescan': the seed's algorithm, every pair and wall re-examined at every
!> event (O(N^2)); it yields the same physical events in the same order
!> (tests, benchmarks).
!>
!> Sticking is the rule of a collision with a static disk: the free disk stops
!> at contact and becomes static, recording its time, event and the member it
!> hit (its parent: the aggregate is a tree rooted at the seed); its free
!> neighbours are told. A disk of a species that does not stick (sticky = .false.:
!> a carrier of the gas) bounces elastically off the aggregate instead, as does the
!> last free sticky disk with `last_bounces` (the seed's option).
module edmd_core
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_numerical, exit_bad_input
  use edmd_heap, only: heap_t, heap_init, heap_set, heap_remove, heap_top
  use edmd_buckets, only: bq_t, bq_entry_t, bq_init, bq_set, bq_remove, bq_top
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use, intrinsic :: iso_c_binding, only: c_int, c_int64_t
  implicit none
  private

  public :: ed_t, disk_t, ed_setup, ed_place_random, ed_place_lattice, ed_velocities, ed_start, &
       ed_run_until, ed_position, ed_kinetic, ed_momentum, ed_check_overlaps, ed_rebuild_cells, ed_put, ed_sort_by_cell, &
       ed_cells, ed_load_cells, &
       rng_t, rng_uniform, rng_normal, ev_pair, ev_wall, ev_cell, ev_stick, ev_bounce
  public :: state_free, state_stuck, state_seed

  integer, parameter :: ev_none = 0, ev_pair = 1, ev_wall = 2, ev_cell = 3
  integer, parameter :: ev_stick = 4, ev_bounce = 5   !< logged types of pair events
  integer, parameter :: state_free = 0, state_stuck = 1, state_seed = 2
  integer, parameter :: cal_rescan = 0, cal_heap = 1, cal_buckets = 2
  real(dp), parameter :: never = huge(1.0_dp)
  !> Prefetch the next event's disk from this many disks on: below, the records fit in the
  !> L2 cache and the prefetch costs more than it hides (bench/RESULTS.md s. 22).
  integer, parameter :: prefetch_min_n = 30000

  !> splitmix64: a small, portable, seeded generator (initial state only).
  type :: rng_t
    integer(i8) :: s = 0
  end type rng_t

  !> One disk: everything a neighbour's pair test reads, in 64 bytes.
  type :: disk_t
    real(dp) :: x = 0, y = 0                !< position at tl [L]
    real(dp) :: vx = 0, vy = 0              !< velocity [L/tau]
    real(dp) :: tl = 0                      !< time of the stored position [tau]
    real(dp) :: r = 0                       !< radius [L]
    integer(i8) :: coll = 0                 !< counter of velocity changes
    integer :: next = 0                     !< next disk of the same cell (0: none)
    integer :: cell = -1                    !< cell (-1: not placed)
  end type disk_t

  type :: ed_t
    integer :: n = 0                        !< disks (free, stuck and the seed)
    real(dp) :: lx = 1, ly = 1              !< box [L]
    type(disk_t), allocatable :: d(:)
    real(dp), allocatable :: m(:)           !< mass [M]
    integer, allocatable :: state(:)        !< state_free | state_stuck | state_seed
    type(bq_entry_t), allocatable :: p(:)   !< calendar entry and prediction of each disk
    ! cells: ncx x ncy of side wx x wy, in a ring of empty cells (no bounds checks in the
    ! 3 x 3 scans); cell (cx, cy) has the index (cx + 1) + sx (cy + 1), cx = 0..ncx - 1
    integer :: ncx = 1, ncy = 1, sx = 3
    real(dp) :: wx = 1, wy = 1
    integer, allocatable :: head(:)
    ! calendar
    integer :: calendar = cal_buckets
    type(heap_t) :: heap
    type(bq_t) :: bq
    ! rules
    logical :: sticking = .true.
    logical :: last_bounces = .false.
    logical, allocatable :: sticky(:)       !< disk i sticks to the aggregate (else bounces off)
    real(dp) :: guard_tol = 1.0e-9_dp       !< allowed overlap / (r_i + r_j) (round-off)
    ! clock and counters
    real(dp) :: t = 0                       !< time of the last event [tau]
    integer(i8) :: n_events = 0             !< physical events (pair, wall, stick, bounce)
    integer(i8) :: n_pair = 0, n_wall = 0, n_stick = 0, n_bounce = 0, n_cross = 0
    integer(i8) :: n_stale = 0              !< stale calendar entries re-predicted (not state)
    integer :: n_free = 0
    integer :: n_free_sticky = 0            !< free disks that stick (stop when none is left)
    integer(i8) :: n_same = 0               !< consecutive events at the same time (guard)
    integer(i8) :: max_same = 0             !< guard: allowed zero-time cascade length
    real(dp) :: virial = 0                  !< sum of r_ij . dp_i over free-free collisions [M L^2/tau]
    !> sum over wall hits of |dp| / (2 (lx + ly - 4 r_i)) [M/tau]: each hit divided by the
    !> perimeter that the centres of disk i reach (lx - 2 r_i, ly - 2 r_i per side), so
    !> wall_impulse / dt is the wall pressure [E/L^2], the sum of the species' partial ones
    real(dp) :: wall_impulse = 0
    ! aggregate
    integer, allocatable :: parent(:)       !< disk it stuck to (0: seed or free)
    real(dp), allocatable :: t_stick(:)
    integer(i8), allocatable :: ev_stuck(:)
    integer :: n_new = 0                    !< disks stuck since the caller last looked
    integer, allocatable :: new_stuck(:)
    real(dp), allocatable :: v_hit(:, :)    !< (2, n) velocity of disk i when it stuck [L/tau]
                                            !< (read for the rows of new_stuck; not state)
    ! event log (optional, small systems)
    logical :: logging = .false.
    integer :: n_log = 0
    real(dp), allocatable :: log_t(:)
    integer, allocatable :: log_kind(:), log_i(:), log_j(:)
    integer(i8), allocatable :: log_no(:)
  end type ed_t

  interface
    !> Prefetch the cache line holding x (edmd_prefetch.c: __builtin_prefetch).
    subroutine prefetch(x) bind(c, name='edmd_prefetch')
      import :: c_int
      integer(c_int), intent(in) :: x
    end subroutine prefetch
    !> Transparent huge pages for the bytes from x on (edmd_prefetch.c: madvise; a hint).
    subroutine huge_pages(x, bytes) bind(c, name='edmd_huge_pages')
      import :: c_int, c_int64_t
      integer(c_int), intent(in) :: x
      integer(c_int64_t), intent(in) :: bytes
    end subroutine huge_pages
  end interface

contains

  ! ---------------------------------------------------------------- RNG
  function rng_next(g) result(z)
    type(rng_t), intent(inout) :: g
    integer(i8) :: z
    g%s = g%s + (-7046029254386353131_i8)        ! 0x9E3779B97F4A7C15
    z = g%s
    z = ieor(z, shiftr(z, 30))*(-4658895280553007687_i8)   ! 0xBF58476D1CE4E5B9
    z = ieor(z, shiftr(z, 27))*(-7723592293110705685_i8)   ! 0x94D049BB133111EB
    z = ieor(z, shiftr(z, 31))
  end function rng_next

  !> Uniform in [0, 1) with 53 random bits.
  function rng_uniform(g) result(u)
    type(rng_t), intent(inout) :: g
    real(dp) :: u
    u = real(shiftr(rng_next(g), 11), dp)*2.0_dp**(-53)
  end function rng_uniform

  !> Standard normal (Box-Muller).
  function rng_normal(g) result(z)
    type(rng_t), intent(inout) :: g
    real(dp) :: z, u1, u2
    u1 = 1.0_dp - rng_uniform(g)
    u2 = rng_uniform(g)
    z = sqrt(-2.0_dp*log(u1))*cos(6.283185307179586476925286766559_dp*u2)
  end function rng_normal

  ! ---------------------------------------------------------------- set-up
  !> Allocate n disks with radii r [L] and masses m [M] (m = huge: static) in
  !> the box; cells of side >= the largest diameter. calendar: 'buckets', 'heap'
  !> or 'rescan'. sticky(i): disk i sticks to the aggregate (default: every disk).
  subroutine ed_setup(s, lx, ly, r, m, calendar, sticking, last_bounces, logging, sticky)
    type(ed_t), intent(out) :: s
    real(dp), intent(in) :: lx, ly, r(:), m(:)
    character(len=*), intent(in) :: calendar
    logical, intent(in) :: sticking, last_bounces, logging
    logical, intent(in), optional :: sticky(:)
    integer :: n
    real(dp) :: dmax
    n = size(r)
    s%n = n
    s%lx = lx
    s%ly = ly
    allocate(s%d(n), s%p(n), s%state(n), s%parent(n), s%t_stick(n), s%ev_stuck(n), &
         s%new_stuck(n), s%sticky(n), s%v_hit(2, n))
    s%sticky = .true.
    if (present(sticky)) s%sticky = sticky
    s%v_hit = 0
    s%d(:)%r = r
    s%m = m
    s%state = state_free
    s%parent = 0; s%t_stick = 0; s%ev_stuck = 0
    select case (calendar)
    case ('heap'); s%calendar = cal_heap
    case ('rescan'); s%calendar = cal_rescan
    case default; s%calendar = cal_buckets
    end select
    s%sticking = sticking
    s%last_bounces = last_bounces
    s%logging = logging
    ! Free disks need only look at the 3 x 3 cells: side > largest diameter (plus a margin for
    ! the round-off of positions near a cell edge).
    dmax = 2.0_dp*maxval(r)*(1.0_dp + 1.0e-9_dp)
    s%ncx = max(1, int(lx/dmax))
    s%ncy = max(1, int(ly/dmax))
    s%wx = lx/s%ncx
    s%wy = ly/s%ncy
    s%sx = s%ncx + 2
    allocate(s%head(0:s%sx*(s%ncy + 2) - 1))
    s%head = 0
    if (logging) then
      allocate(s%log_t(1024), s%log_kind(1024), s%log_i(1024), s%log_j(1024), s%log_no(1024))
    end if
  end subroutine ed_setup

  pure integer function cell_of(s, x, y)
    type(ed_t), intent(in) :: s
    real(dp), intent(in) :: x, y
    integer :: cx, cy
    cx = min(s%ncx - 1, max(0, int(x/s%wx)))
    cy = min(s%ncy - 1, max(0, int(y/s%wy)))
    cell_of = (cx + 1) + s%sx*(cy + 1)
  end function cell_of

  !> Column and row (from 0) of cell c.
  pure subroutine cell_xy(s, c, cx, cy)
    type(ed_t), intent(in) :: s
    integer, intent(in) :: c
    integer, intent(out) :: cx, cy
    cy = c/s%sx
    cx = c - s%sx*cy - 1
    cy = cy - 1
  end subroutine cell_xy

  !> Cells of the disks in row-major numbering cx + ncx cy (-1: not placed): the checkpoint's.
  pure function ed_cells(s) result(cells)
    type(ed_t), intent(in) :: s
    integer :: cells(s%n)
    integer :: i, cx, cy
    do i = 1, s%n
      cells(i) = -1
      if (s%d(i)%cell < 0) cycle
      call cell_xy(s, s%d(i)%cell, cx, cy)
      cells(i) = cx + s%ncx*cy
    end do
  end function ed_cells

  !> Cells of the disks from row-major numbers (ed_cells), and the cell lists. .false. if a
  !> number is out of range (nothing changed).
  logical function ed_load_cells(s, cells) result(ok)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: cells(:)
    integer :: i
    ok = size(cells) == s%n
    if (ok) ok = all(cells >= 0 .and. cells < s%ncx*s%ncy)
    if (.not. ok) return
    do i = 1, s%n
      s%d(i)%cell = (mod(cells(i), s%ncx) + 1) + s%sx*(cells(i)/s%ncx + 1)
    end do
    call ed_rebuild_cells(s)
  end function ed_load_cells

  !> Disk i to the front of cell c's list.
  subroutine cell_insert(s, i, c)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, c
    s%d(i)%cell = c
    s%d(i)%next = s%head(c)
    s%head(c) = i
  end subroutine cell_insert

  !> Disk i out of its cell's list (singly linked: the lists hold a few disks).
  subroutine cell_delete(s, i)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    integer :: j
    j = s%head(s%d(i)%cell)
    if (j == i) then
      s%head(s%d(i)%cell) = s%d(i)%next
    else
      do while (s%d(j)%next /= i)
        j = s%d(j)%next
      end do
      s%d(j)%next = s%d(i)%next
    end if
    s%d(i)%cell = -1
  end subroutine cell_delete

  !> Cell lists from the disks' cells (restore), or from positions where cell < 0.
  subroutine ed_rebuild_cells(s)
    type(ed_t), intent(inout) :: s
    integer :: i, c
    s%head = 0
    do i = 1, s%n
      c = s%d(i)%cell
      if (c < 0) c = cell_of(s, s%d(i)%x, s%d(i)%y)
      call cell_insert(s, i, c)
    end do
  end subroutine ed_rebuild_cells

  !> Renumber disks first..n in cell order (row by row; stable): neighbours in space are
  !> neighbours in memory, which keeps the event loop in cache at large N (bench/RESULTS.md).
  !> Call after placement, before velocities are drawn.
  subroutine ed_sort_by_cell(s, first)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: first
    integer :: i, k, nc
    integer, allocatable :: cnt(:), perm(:)
    nc = size(s%head)
    allocate(cnt(0:nc), perm(first:s%n))
    cnt = 0
    do i = first, s%n
      cnt(s%d(i)%cell + 1) = cnt(s%d(i)%cell + 1) + 1
    end do
    do k = 1, nc
      cnt(k) = cnt(k) + cnt(k - 1)
    end do
    do i = first, s%n
      cnt(s%d(i)%cell) = cnt(s%d(i)%cell) + 1
      perm(first - 1 + cnt(s%d(i)%cell)) = i
    end do
    s%d(first:) = s%d(perm)
    s%m(first:) = s%m(perm)
    s%state(first:) = s%state(perm)
    s%sticky(first:) = s%sticky(perm)
    call ed_rebuild_cells(s)
  end subroutine ed_sort_by_cell

  !> Put disk i at (x, y) [L] into the cells (placement).
  subroutine ed_put(s, i, x, y)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    real(dp), intent(in) :: x, y
    s%d(i)%x = x
    s%d(i)%y = y
    call cell_insert(s, i, cell_of(s, x, y))
  end subroutine ed_put

  !> .true. if a disk of radius ri at (x, y) overlaps a placed disk (cells).
  logical function overlaps_placed(s, x, y, ri, margin)
    type(ed_t), intent(in) :: s
    real(dp), intent(in) :: x, y, ri, margin
    integer :: c, ix, iy, j
    real(dp) :: d2, sg
    overlaps_placed = .false.
    c = cell_of(s, x, y)
    do iy = -1, 1
      do ix = -1, 1
        j = s%head(c + ix + s%sx*iy)
        do while (j /= 0)
          sg = (ri + s%d(j)%r)*(1.0_dp + margin)
          d2 = (x - s%d(j)%x)**2 + (y - s%d(j)%y)**2
          if (d2 < sg*sg) then
            overlaps_placed = .true.
            return
          end if
          j = s%d(j)%next
        end do
      end do
    end do
  end function overlaps_placed

  !> Place disk i (already-placed disks are in the cells) uniformly at random
  !> without overlap; disks flagged static (seed) are placed by the caller first.
  subroutine ed_place_random(s, g, first, st)
    type(ed_t), intent(inout) :: s
    type(rng_t), intent(inout) :: g
    integer, intent(in) :: first
    type(status_t), intent(inout) :: st
    integer :: i, tries
    real(dp) :: x, y, ri
    character(len=200) :: buf
    integer, parameter :: max_tries = 100000
    do i = first, s%n
      ri = s%d(i)%r
      do tries = 1, max_tries
        x = ri + rng_uniform(g)*(s%lx - 2.0_dp*ri)
        y = ri + rng_uniform(g)*(s%ly - 2.0_dp*ri)
        if (.not. overlaps_placed(s, x, y, ri, 0.0_dp)) exit
      end do
      if (tries > max_tries) then
        write(buf, '(a,i0,a,i0,a)') 'random placement: no room for disk ', i, ' after ', &
             max_tries, ' tries (packing too dense for random sequential addition: '// &
             'lower &disks count or use placement = ''lattice'')'
        call set_error(st, exit_bad_input, trim(buf))
        return
      end if
      call ed_put(s, i, x, y)
    end do
  end subroutine ed_place_random

  !> Place disks first..n on a square lattice of pitch exactly 2 r_max starting
  !> at (r_max, r_max): neighbours in exact (grazing) contact; sites overlapping
  !> a placed disk (the seed) are skipped.
  subroutine ed_place_lattice(s, first, st)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: first
    type(status_t), intent(inout) :: st
    integer :: i, kx, ky, nx, ny
    real(dp) :: rm, x, y
    rm = maxval(s%d(first:)%r)
    ! Strictly fewer sites than fit: a row spanning wall to wall in exact contact is rigid
    ! (a zero-time collision cascade that never ends), so every row keeps some slack.
    nx = ceiling(s%lx/(2.0_dp*rm)) - 1
    ny = ceiling(s%ly/(2.0_dp*rm)) - 1
    i = first
    outer: do ky = 0, ny - 1
      do kx = 0, nx - 1
        if (i > s%n) exit outer
        x = rm + 2.0_dp*rm*kx
        y = rm + 2.0_dp*rm*ky
        if (x + rm > s%lx .or. y + rm > s%ly) cycle
        if (overlaps_placed(s, x, y, rm, -1.0e-12_dp)) cycle
        call ed_put(s, i, x, y)
        i = i + 1
      end do
    end do outer
    if (i <= s%n) call set_error(st, exit_bad_input, &
         'lattice placement: the box holds fewer sites than &disks count (pitch 2 r_max)')
  end subroutine ed_place_lattice

  !> Velocities of the free disks: 'fixed_speed' |v| = sqrt(2 kT/m) in a random
  !> direction (the seed's), or 'maxwell' (each component normal, variance kT/m), the
  !> draw then scaled by one factor so that E_kin = N_free kT exactly (2D, no conserved
  !> momentum in the closed box): the gas starts at the scene's kT, not at a draw of it
  !> (1/sqrt(N) off; 'fixed_speed' has E_kin = N_free kT by construction).
  subroutine ed_velocities(s, g, rule, kt)
    type(ed_t), intent(inout) :: s
    type(rng_t), intent(inout) :: g
    character(len=*), intent(in) :: rule
    real(dp), intent(in) :: kt
    integer :: i, n_free
    real(dp) :: a, sp, e, f
    do i = 1, s%n
      if (s%state(i) /= state_free) cycle
      if (rule == 'maxwell') then
        s%d(i)%vx = sqrt(kt/s%m(i))*rng_normal(g)
        s%d(i)%vy = sqrt(kt/s%m(i))*rng_normal(g)
      else
        a = 6.283185307179586476925286766559_dp*rng_uniform(g)
        sp = sqrt(2.0_dp*kt/s%m(i))
        s%d(i)%vx = sp*cos(a)
        s%d(i)%vy = sp*sin(a)
      end if
    end do
    if (rule /= 'maxwell') return
    n_free = count(s%state(1:s%n) == state_free)
    e = ed_kinetic(s)
    if (n_free == 0 .or. .not. e > 0.0_dp) return
    f = sqrt(real(n_free, dp)*kt/e)
    do i = 1, s%n
      if (s%state(i) /= state_free) cycle
      s%d(i)%vx = f*s%d(i)%vx
      s%d(i)%vy = f*s%d(i)%vy
    end do
  end subroutine ed_velocities

  !> Build the calendar from the stored states (start and restore).
  subroutine ed_start(s)
    type(ed_t), intent(inout) :: s
    integer :: i
    s%n_free = count(s%state == state_free)
    s%n_free_sticky = count(s%state == state_free .and. s%sticky)
    s%n_same = 0
    s%max_same = max(1000000_i8, 1000_i8*s%n)
    s%p = bq_entry_t()                      ! no entries, no predictions
    s%p(:)%m = s%m                          ! masses beside the entries (s. 32.1)
    select case (s%calendar)
    case (cal_heap); call heap_init(s%heap, s%n)
    case (cal_buckets)
      call bq_init(s%bq, s%n)
      s%bq%hints = s%n >= prefetch_min_n
    case default; return
    end select
    call advise_huge_pages(s)
    do i = 1, s%n
      if (s%state(i) == state_free) call predict(s, i)
    end do
  end subroutine ed_start

  !> Huge pages for the arrays the event loop reads at random places (records, entries, cell
  !> and bucket heads; arrays under 2 MiB are left alone): fewer TLB misses at large N, the
  !> same events (bench/RESULTS.md s. 32).
  subroutine advise_huge_pages(s)
    type(ed_t), intent(inout) :: s
    if (s%n == 0) return
    call huge_pages(s%d(1)%next, int(storage_size(s%d)/8, c_int64_t)*s%n)
    call huge_pages(s%p(1)%next, int(storage_size(s%p)/8, c_int64_t)*s%n)
    call huge_pages(s%head(0), int(storage_size(s%head)/8, c_int64_t)*size(s%head))
    if (s%calendar == cal_buckets) call huge_pages(s%bq%head(0), &
         int(storage_size(s%bq%head)/8, c_int64_t)*size(s%bq%head))
  end subroutine advise_huge_pages

  ! ---------------------------------------------------------------- calendar
  !> Entry of disk i at time t [tau] (s%p(i)%key = t).
  subroutine cal_set(s, i, t)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    if (s%calendar == cal_buckets) then
      call bq_set(s%bq, s%p, i, t)
    else
      s%p(i)%key = t
      call heap_set(s%heap, i, t)
    end if
  end subroutine cal_set

  subroutine cal_remove(s, i)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    if (s%calendar == cal_buckets) then
      call bq_remove(s%bq, s%p, i)
    else
      call heap_remove(s%heap, i)
    end if
  end subroutine cal_remove

  integer function cal_top(s)
    type(ed_t), intent(inout) :: s
    if (s%calendar == cal_buckets) then
      cal_top = bq_top(s%bq, s%p)
    else
      cal_top = heap_top(s%heap)
    end if
  end function cal_top

  ! ---------------------------------------------------------------- prediction
  !> Time of the collision of disks a and b [tau] (never if they do not collide);
  !> a pure function of the two stored states, symmetric in a and b.
  pure real(dp) function pair_time(a, b) result(tc)
    type(disk_t), intent(in) :: a, b
    real(dp) :: tr, dx, dy, dvx, dvy, qa, qb, qc, disc, sg
    tc = never
    tr = max(a%tl, b%tl)
    dvx = a%vx - b%vx
    dvy = a%vy - b%vy
    dx = (a%x + a%vx*(tr - a%tl)) - (b%x + b%vx*(tr - b%tl))
    dy = (a%y + a%vy*(tr - a%tl)) - (b%y + b%vy*(tr - b%tl))
    qb = dx*dvx + dy*dvy
    if (qb >= 0.0_dp) return                   ! separating (or at rest relative)
    sg = a%r + b%r
    qc = dx*dx + dy*dy - sg*sg
    if (qc <= 0.0_dp) then                     ! in contact (round-off) and approaching: now
      tc = tr
      return
    end if
    qa = dvx*dvx + dvy*dvy
    disc = qb*qb - qa*qc
    if (disc <= 0.0_dp) return                 ! miss
    tc = tr + qc/(-qb + sqrt(disc))            ! stable root: no cancellation for small c
  end function pair_time

  !> Candidate (t, kind, partner) before (t0, k0, p0)? Lexicographic: order-free.
  pure logical function earlier(t, k, p, t0, k0, p0)
    real(dp), intent(in) :: t, t0
    integer, intent(in) :: k, p, k0, p0
    earlier = t < t0
    if (t == t0) earlier = k < k0 .or. (k == k0 .and. p < p0)
  end function earlier

  !> Time to reach the coordinate b from x at speed v [tau] (v /= 0; never negative).
  pure real(dp) function reach(b, x, v)
    real(dp), intent(in) :: b, x, v
    reach = max(0.0_dp, (b - x)/v)
  end function reach

  !> Wall time and wall (1 x-, 2 x+, 3 y-, 4 y+) of free disk a in the box lx x ly.
  pure subroutine wall_time(a, lx, ly, tw, w)
    type(disk_t), intent(in) :: a
    real(dp), intent(in) :: lx, ly
    real(dp), intent(out) :: tw
    integer, intent(out) :: w
    real(dp) :: t1
    tw = never
    w = 0
    if (a%vx > 0.0_dp) then
      tw = a%tl + reach(lx - a%r, a%x, a%vx); w = 2
    else if (a%vx < 0.0_dp) then
      tw = a%tl + reach(a%r, a%x, a%vx); w = 1
    end if
    t1 = never
    if (a%vy > 0.0_dp) then
      t1 = a%tl + reach(ly - a%r, a%y, a%vy)
      if (t1 < tw) then
        tw = t1; w = 4
      end if
    else if (a%vy < 0.0_dp) then
      t1 = a%tl + reach(a%r, a%y, a%vy)
      if (t1 < tw) then
        tw = t1; w = 3
      end if
    end if
  end subroutine wall_time

  !> Earliest cell-crossing time and direction (1 x-, 2 x+, 3 y-, 4 y+) of free disk i in
  !> cell (cx, cy), and whether it moves towards a wall its cell touches (no crossing that
  !> way: the border cell's edge is the wall's side).
  pure subroutine cross_time(s, i, cx, cy, tx, d, towards_wall)
    type(ed_t), intent(in) :: s
    integer, intent(in) :: i, cx, cy
    real(dp), intent(out) :: tx
    integer, intent(out) :: d
    logical, intent(out) :: towards_wall
    real(dp) :: t1
    associate (a => s%d(i))
      tx = never
      d = 0
      towards_wall = .false.
      if (a%vx > 0.0_dp) then
        if (cx < s%ncx - 1) then
          tx = a%tl + reach((cx + 1)*s%wx, a%x, a%vx); d = 2
        else
          towards_wall = .true.
        end if
      else if (a%vx < 0.0_dp) then
        if (cx > 0) then
          tx = a%tl + reach(cx*s%wx, a%x, a%vx); d = 1
        else
          towards_wall = .true.
        end if
      end if
      if (a%vy > 0.0_dp) then
        if (cy < s%ncy - 1) then
          t1 = a%tl + reach((cy + 1)*s%wy, a%y, a%vy)
          if (t1 < tx) then
            tx = t1; d = 4
          end if
        else
          towards_wall = .true.
        end if
      else if (a%vy < 0.0_dp) then
        if (cy > 0) then
          t1 = a%tl + reach(cy*s%wy, a%y, a%vy)
          if (t1 < tx) then
            tx = t1; d = 3
          end if
        else
          towards_wall = .true.
        end if
      end if
    end associate
  end subroutine cross_time

  !> Best pair candidate of free disk i over nrows rows of 3 cells c0 + r sx + k step
  !> (k = 0..2), into its prediction record (only if earlier than the one held).
  subroutine scan_cells(s, i, c0, step, nrows)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, c0, step, nrows
    integer :: ix, iy, j, pj
    real(dp) :: tc, pt
    integer(i8) :: pc
    type(disk_t) :: a
    a = s%d(i)
    pt = s%p(i)%pt
    pj = s%p(i)%pj
    pc = s%p(i)%pcount
    do iy = 0, nrows - 1
      !GCC$ unroll 3
      do ix = 0, 2
        j = s%head(c0 + s%sx*iy + step*ix)
        do while (j /= 0)
          if (j /= i) then
            tc = pair_time(a, s%d(j))
            if (tc < never) then
              if (earlier(tc, ev_pair, j, pt, ev_pair, pj)) then
                pt = tc
                pj = j
                pc = s%d(j)%coll
              end if
            end if
          end if
          j = s%d(j)%next
        end do
      end do
    end do
    s%p(i)%pt = pt
    s%p(i)%pj = pj
    s%p(i)%pcount = pc
  end subroutine scan_cells

  !> Start loading the record and calendar entry of the disk of the likely next event (the
  !> calendar's hint, buckets only; 0: none). Only loads: the order of events does not depend
  !> on the hint.
  subroutine prefetch_next(s)
    type(ed_t), intent(in) :: s
    integer :: h
    h = s%bq%hint
    if (h == 0) return
    call prefetch(s%d(h)%next)
    call prefetch(s%p(h)%next)
  end subroutine prefetch_next

  !> Earliest event of free disk i over walls, its cell edges and the disks
  !> of the 3 x 3 cells around it; into the calendar.
  subroutine predict(s, i)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    s%p(i)%pt = never
    s%p(i)%pj = 0
    call scan_cells(s, i, s%d(i)%cell - s%sx - 1, 1, 3)
    call choose(s, i)
  end subroutine predict

  !> After disk i crossed into a new cell in direction d: its best pair candidate is kept
  !> (the old 3 x 3 cells were scanned with the same trajectories of i), so only the row or
  !> column of cells that became adjacent is scanned. A candidate whose partner changed since
  !> is kept too, without looking at the partner's record: its entry carries the partner's
  !> counter of the scan (set_event), so it pops as stale at its time at the latest and i is
  !> predicted in full then; until then the candidate time only falls, so i is re-predicted
  !> before any later candidate dropped here (a collision with a disk that changed is held
  !> by that disk's own prediction, as for every candidate). The same events result (tests:
  !> heap = rescan; bench/RESULTS.md s. 32.1), at a third of the cell scans per crossing.
  subroutine predict_after_cross(s, i, d)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, d
    integer :: c
    c = s%d(i)%cell
    select case (d)
    case (1); call scan_cells(s, i, c - s%sx - 1, s%sx, 1)      ! the column on the left
    case (2); call scan_cells(s, i, c - s%sx + 1, s%sx, 1)
    case (3); call scan_cells(s, i, c - s%sx - 1, 1, 1)         ! the row below
    case (4); call scan_cells(s, i, c + s%sx - 1, 1, 1)
    end select
    call choose(s, i)
  end subroutine predict_after_cross

  !> The calendar entry of disk i: the earliest of its wall, cell crossing and best pair.
  !> The walls are only looked at from a cell on the border the disk moves towards (or
  !> without a crossing): from any other cell, the crossing of the cell edge on the way to a
  !> wall comes strictly first (the edge is >= one cell side > r_max from the wall), so the
  !> entry is the same.
  subroutine choose(s, i)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    real(dp) :: tb, tc
    integer :: kb, pb, w, cx, cy
    logical :: walls
    call cell_xy(s, s%d(i)%cell, cx, cy)
    call cross_time(s, i, cx, cy, tb, pb, walls)
    kb = ev_cell
    if (tb >= never .or. walls) then
      call wall_time(s%d(i), s%lx, s%ly, tc, w)
      if (earlier(tc, ev_wall, w, tb, kb, pb)) then
        tb = tc; kb = ev_wall; pb = w
      end if
    end if
    if (s%p(i)%pj /= 0) then
      if (earlier(s%p(i)%pt, ev_pair, s%p(i)%pj, tb, kb, pb)) then
        tb = s%p(i)%pt; kb = ev_pair; pb = s%p(i)%pj
      end if
    end if
    call set_event(s, i, tb, kb, pb)
  end subroutine choose

  !> Entry of disk i: event k at time t with partner p. A pair event names the candidate
  !> (p = pj) and carries its counter of the scan (pcount), not the partner's current one: a
  !> candidate whose partner changed since (kept across crossings) is then stale at its pop.
  subroutine set_event(s, i, t, k, p)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, k, p
    real(dp), intent(in) :: t
    s%p(i)%kind = k
    s%p(i)%partner = p
    s%p(i)%count = 0
    if (k == ev_pair) s%p(i)%count = s%p(i)%pcount    ! p = pj: its counter at the scan
    call cal_set(s, i, t)
  end subroutine set_event

  !> The seed's algorithm: rescan every wall and pair for the earliest event.
  subroutine rescan(s, tb, kb, ib, pb)
    type(ed_t), intent(in) :: s
    real(dp), intent(out) :: tb
    integer, intent(out) :: kb, ib, pb
    integer :: i, j, w, a, b
    real(dp) :: tc
    tb = never; kb = ev_none; ib = 0; pb = 0
    do i = 1, s%n
      if (s%state(i) /= state_free) cycle
      call wall_time(s%d(i), s%lx, s%ly, tc, w)
      if (tc < tb .or. (tc == tb .and. i < ib)) then
        tb = tc; kb = ev_wall; ib = i; pb = w
      end if
    end do
    do i = 1, s%n - 1
      do j = i + 1, s%n
        if (s%state(i) /= state_free .and. s%state(j) /= state_free) cycle
        tc = pair_time(s%d(i), s%d(j))
        if (tc >= never) cycle
        a = i; b = j
        if (s%state(a) /= state_free) then
          a = j; b = i
        end if
        if (tc < tb .or. (tc == tb .and. a < ib)) then
          tb = tc; kb = ev_pair; ib = a; pb = b
        end if
      end do
    end do
  end subroutine rescan

  ! ---------------------------------------------------------------- events
  !> Process every event before t_target [tau]. Guards: st = exit_numerical on
  !> an overlap beyond guard_tol at a contact, or a non-finite time.
  subroutine ed_run_until(s, t_target, st)
    type(ed_t), intent(inout) :: s
    real(dp), intent(in) :: t_target
    type(status_t), intent(inout) :: st
    integer :: i, k, p
    real(dp) :: te
    do
      if (s%calendar /= cal_rescan) then
        i = cal_top(s)
        if (i == 0) exit
        if (s%bq%hints) call prefetch_next(s)       ! hints: buckets from prefetch_min_n on
        te = s%p(i)%key
        if (te >= t_target) exit
        k = s%p(i)%kind
        p = s%p(i)%partner
        if (k == ev_pair) then
          if (s%d(p)%coll /= s%p(i)%count) then    ! partner changed since: stale entry
            s%n_stale = s%n_stale + 1
            call predict(s, i)
            cycle
          end if
        end if
      else
        call rescan(s, te, k, i, p)
        if (k == ev_none .or. te >= t_target) exit
      end if
      if (.not. ieee_is_finite(te)) then
        call guard_fail(s, st, 'non-finite event time', i, p, 0.0_dp)
        return
      end if
      te = max(te, s%t)                              ! the clock never runs back
      if (k /= ev_cell) then
        if (te == s%t) then
          s%n_same = s%n_same + 1
          if (s%n_same > s%max_same) then
            call guard_fail(s, st, 'zero-time collision cascade (events without the clock '// &
                 'advancing; a jammed contact network?)', i, p, 0.0_dp)
            return
          end if
        else
          s%n_same = 0
        end if
      end if
      select case (k)
      case (ev_cell)
        call cross(s, i, p)
        s%n_cross = s%n_cross + 1
        call predict_after_cross(s, i, p)
        cycle
      case (ev_wall)
        s%t = te
        call wall_hit(s, i, p, te)
      case (ev_pair)
        s%t = te
        call pair_hit(s, i, p, te, st)
        if (st%code /= 0) return
      end select
    end do
  end subroutine ed_run_until

  subroutine cross(s, i, d)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, d
    integer :: c
    c = s%d(i)%cell
    select case (d)
    case (1); c = c - 1
    case (2); c = c + 1
    case (3); c = c - s%sx
    case (4); c = c + s%sx
    end select
    call cell_delete(s, i)
    call cell_insert(s, i, c)
  end subroutine cross

  subroutine move_to(a, te)
    type(disk_t), intent(inout) :: a
    real(dp), intent(in) :: te
    a%x = a%x + a%vx*(te - a%tl)
    a%y = a%y + a%vy*(te - a%tl)
    a%tl = te
  end subroutine move_to

  subroutine wall_hit(s, i, w, te)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, w
    real(dp), intent(in) :: te
    associate (a => s%d(i))
      call move_to(a, te)
      select case (w)                        ! exactly at contact with the wall
      case (1, 2)
        a%x = merge(a%r, s%lx - a%r, w == 1)
        s%wall_impulse = s%wall_impulse + 2.0_dp*s%p(i)%m*abs(a%vx)/reached_perimeter(s, a%r)
        a%vx = -a%vx
      case (3, 4)
        a%y = merge(a%r, s%ly - a%r, w == 3)
        s%wall_impulse = s%wall_impulse + 2.0_dp*s%p(i)%m*abs(a%vy)/reached_perimeter(s, a%r)
        a%vy = -a%vy
      end select
      a%coll = a%coll + 1
    end associate
    s%n_wall = s%n_wall + 1
    s%n_events = s%n_events + 1
    if (s%logging) call log_event(s, ev_wall, i, -w)
    if (s%calendar /= cal_rescan) call predict(s, i)
  end subroutine wall_hit

  !> Perimeter [L] along which the centre of a disk of radius r touches the walls: each
  !> side less r at either end (the wall pressure's length, not the box's 2 (lx + ly)).
  pure real(dp) function reached_perimeter(s, r) result(p)
    type(ed_t), intent(in) :: s
    real(dp), intent(in) :: r
    p = 2.0_dp*(s%lx + s%ly - 4.0_dp*r)
  end function reached_perimeter

  !> Collision of free disk i with disk j at te: elastic (j free), or with a
  !> static j: stick (the rule) or bounce (sticking off / the last free disk).
  subroutine pair_hit(s, i, j, te, st)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, j
    real(dp), intent(in) :: te
    type(status_t), intent(inout) :: st
    real(dp) :: nx, ny, d, sg, vn, mu, jx, jy
    call move_to(s%d(i), te)
    if (s%state(j) == state_free) call move_to(s%d(j), te)
    nx = s%d(i)%x - s%d(j)%x
    ny = s%d(i)%y - s%d(j)%y
    d = sqrt(nx*nx + ny*ny)
    sg = s%d(i)%r + s%d(j)%r
    if (d < sg*(1.0_dp - s%guard_tol) .or. .not. ieee_is_finite(d)) then
      call guard_fail(s, st, 'overlap at contact', i, j, sg - d)
      return
    end if
    nx = nx/d
    ny = ny/d
    vn = (s%d(i)%vx - s%d(j)%vx)*nx + (s%d(i)%vy - s%d(j)%vy)*ny   ! < 0: approaching
    s%n_events = s%n_events + 1
    if (s%state(j) /= state_free) then
      if (s%sticking .and. s%sticky(i) .and. .not. (s%last_bounces .and. &
           s%n_free_sticky == 1)) then
        call stick(s, i, j, te)
        return
      end if
      s%d(i)%vx = s%d(i)%vx - 2.0_dp*vn*nx                          ! mirror off the static disk
      s%d(i)%vy = s%d(i)%vy - 2.0_dp*vn*ny
      s%d(i)%coll = s%d(i)%coll + 1
      s%n_bounce = s%n_bounce + 1
      call log_event(s, ev_bounce, i, j)
      if (s%calendar /= cal_rescan) call predict(s, i)
      return
    end if
    mu = s%p(i)%m*s%p(j)%m/(s%p(i)%m + s%p(j)%m)
    jx = 2.0_dp*mu*vn*nx                                            ! impulse on j (= -dp_i)
    jy = 2.0_dp*mu*vn*ny
    s%d(i)%vx = s%d(i)%vx - jx/s%p(i)%m
    s%d(i)%vy = s%d(i)%vy - jy/s%p(i)%m
    s%d(j)%vx = s%d(j)%vx + jx/s%p(j)%m
    s%d(j)%vy = s%d(j)%vy + jy/s%p(j)%m
    s%virial = s%virial - 2.0_dp*mu*vn*d                            ! r_ij . dp_i > 0
    s%d(i)%coll = s%d(i)%coll + 1
    s%d(j)%coll = s%d(j)%coll + 1
    s%n_pair = s%n_pair + 1
    if (s%logging) call log_event(s, ev_pair, min(i, j), max(i, j))
    if (s%calendar /= cal_rescan) then
      call predict(s, i)
      call predict(s, j)
    end if
  end subroutine pair_hit

  !> Free disk i (at contact with static j) joins the aggregate.
  subroutine stick(s, i, j, te)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, j
    real(dp), intent(in) :: te
    integer :: c, ix, iy, k
    real(dp) :: tc
    s%v_hit(:, i) = [s%d(i)%vx, s%d(i)%vy]
    s%d(i)%vx = 0.0_dp
    s%d(i)%vy = 0.0_dp
    s%state(i) = state_stuck
    s%parent(i) = j
    s%t_stick(i) = te
    s%ev_stuck(i) = s%n_events
    s%d(i)%coll = s%d(i)%coll + 1
    s%n_free = s%n_free - 1
    s%n_free_sticky = s%n_free_sticky - 1
    s%n_stick = s%n_stick + 1
    s%n_new = s%n_new + 1
    s%new_stuck(s%n_new) = i
    call log_event(s, ev_stick, i, j)
    if (s%calendar == cal_rescan) return
    call cal_remove(s, i)
    ! A static disk predicts nothing: its free neighbours must learn of it now.
    c = s%d(i)%cell
    do iy = -1, 1
      do ix = -1, 1
        k = s%head(c + ix + s%sx*iy)
        do while (k /= 0)
          if (s%state(k) == state_free) then
            tc = pair_time(s%d(k), s%d(i))
            if (tc < never) then
              ! against k's best pair (kept across its crossings), not only its entry
              if (earlier(tc, ev_pair, i, s%p(k)%pt, ev_pair, s%p(k)%pj)) then
                s%p(k)%pt = tc
                s%p(k)%pj = i
                s%p(k)%pcount = s%d(i)%coll
                if (earlier(tc, ev_pair, i, s%p(k)%key, s%p(k)%kind, s%p(k)%partner)) &
                     call set_event(s, k, tc, ev_pair, i)
              end if
            end if
          end if
          k = s%d(k)%next
        end do
      end do
    end do
  end subroutine stick

  subroutine log_event(s, kind, i, j)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: kind, i, j
    if (.not. s%logging) return
    if (s%n_log == size(s%log_t)) then
      s%log_t = [s%log_t, s%log_t]
      s%log_kind = [s%log_kind, s%log_kind]
      s%log_i = [s%log_i, s%log_i]
      s%log_j = [s%log_j, s%log_j]
      s%log_no = [s%log_no, s%log_no]
    end if
    s%n_log = s%n_log + 1
    s%log_t(s%n_log) = s%t
    s%log_kind(s%n_log) = kind
    s%log_i(s%n_log) = i
    s%log_j(s%n_log) = j
    s%log_no(s%n_log) = s%n_events
  end subroutine log_event

  subroutine guard_fail(s, st, what, i, j, overlap)
    type(ed_t), intent(in) :: s
    type(status_t), intent(inout) :: st
    character(len=*), intent(in) :: what
    integer, intent(in) :: i, j
    real(dp), intent(in) :: overlap
    character(len=400) :: buf
    write(buf, '(a,a,a,i0,a,es24.16e3,a,i0,a,i0,a,es10.3e3,a,es10.3e3,a)') &
         'event-driven guard: ', what, ' at event ', s%n_events + 1, ', t = ', s%t, &
         ' tau, disks ', i, ' and ', j, &
         ': overlap ', overlap, ' L (tolerance ', s%guard_tol, ' x (r_i + r_j))'
    call set_error(st, exit_numerical, trim(buf))
  end subroutine guard_fail

  ! ---------------------------------------------------------------- observables
  !> Position of disk i at time t [L] (exact between events).
  pure function ed_position(s, i, t) result(p)
    type(ed_t), intent(in) :: s
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    real(dp) :: p(2)
    p(1) = s%d(i)%x + s%d(i)%vx*(t - s%d(i)%tl)
    p(2) = s%d(i)%y + s%d(i)%vy*(t - s%d(i)%tl)
  end function ed_position

  pure real(dp) function ed_kinetic(s) result(e)
    type(ed_t), intent(in) :: s
    integer :: i
    e = 0
    do i = 1, s%n
      if (s%state(i) == state_free) e = e + 0.5_dp*s%m(i)*(s%d(i)%vx**2 + s%d(i)%vy**2)
    end do
  end function ed_kinetic

  pure function ed_momentum(s) result(p)
    type(ed_t), intent(in) :: s
    real(dp) :: p(2)
    integer :: i
    p = 0
    do i = 1, s%n
      if (s%state(i) == state_free) p = p + s%m(i)*[s%d(i)%vx, s%d(i)%vy]
    end do
  end function ed_momentum

  !> Guard at time t: every pair of the cell neighbourhoods and every wall
  !> (positions interpolated); st = exit_numerical naming the worst overlap.
  subroutine ed_check_overlaps(s, t, st)
    type(ed_t), intent(in) :: s
    real(dp), intent(in) :: t
    type(status_t), intent(inout) :: st
    integer :: i, j, c, ix, iy, wi, wj
    real(dp) :: pi_(2), pj(2), d, sg, worst, ov, ri
    character(len=400) :: buf
    worst = 0; wi = 0; wj = 0
    do i = 1, s%n
      pi_ = ed_position(s, i, t)
      ri = s%d(i)%r
      ov = max(ri - pi_(1), pi_(1) + ri - s%lx, ri - pi_(2), pi_(2) + ri - s%ly)
      if (ov > s%guard_tol*ri .and. ov > worst) then
        worst = ov; wi = i; wj = 0
      end if
      c = cell_of(s, pi_(1), pi_(2))
      do iy = -1, 1
        do ix = -1, 1
          j = s%head(c + ix + s%sx*iy)
          do while (j /= 0)
            if (j > i) then
              pj = ed_position(s, j, t)
              d = sqrt(sum((pi_ - pj)**2))
              sg = ri + s%d(j)%r
              if (sg - d > s%guard_tol*sg .and. sg - d > worst) then
                worst = sg - d; wi = i; wj = j
              end if
            end if
            j = s%d(j)%next
          end do
        end do
      end do
    end do
    if (wi == 0) return
    write(buf, '(a,i0,a,es24.16e3,a,i0,a,i0,a,es10.3e3,a)') 'event-driven guard: overlap after '// &
         'event ', s%n_events, ' at t = ', t, ' tau: disk ', wi, ' and ', wj, &
         ' (0 = wall) overlap by ', worst, ' L'
    call set_error(st, exit_numerical, trim(buf))
  end subroutine ed_check_overlaps

end module edmd_core
