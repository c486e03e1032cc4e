!> Event-driven dynamics of hard disks in a closed rectangular box
!> [0, lx] x [0, ly], with an aggregate of static disks (infinite mass) that
!> free disks stick to (or bounce off).
!>
!> State: each disk i stores its position x(:,i) at its own time tl(i) and its
!> velocity v(:,i); it moves ballistically, x(t) = x(:,i) + v(:,i) (t - tl(i)),
!> until its next event. The stored states are only touched by events, so
!> every prediction is a pure function of the stored states (the calendar
!> rebuilt from them after a restore predicts bit-identical times).
!>
!> Events: disk-disk collision (time from |dr + dv t| = r_i + r_j in the
!> stable form dt = c / (-b + sqrt(b^2 - a c)), b = dr.dv < 0, c = |dr|^2 -
!> sigma^2; c <= 0 while approaching = in contact now, dt = 0), disk-wall
!> collision, and cell crossing (the box is cut into cells of side >= the
!> largest diameter; a disk only looks at the 3 x 3 cells around its own;
!> it keeps its best pair candidate across crossings and scans only the 3
!> cells that became adjacent, unless that candidate's partner changed).
!>
!> Calendar ('heap'): one entry per free disk (its earliest event) in an
!> indexed binary heap (edmd_heap); an entry naming a partner whose collision
!> counter changed since the prediction is stale and is re-predicted when it
!> reaches the top. O(log N) per event. Calendar 'rescan': the seed's
!> algorithm, every pair and wall re-examined at every event (O(N^2)); it
!> yields the same physical events in the same order (tests, benchmarks).
!>
!> Sticking is the rule of a collision with a static disk: the free disk stops
!> at contact and becomes static, recording its time, event and the member it
!> hit (its parent: the aggregate is a tree rooted at the seed); its free
!> neighbours are told. With `last_bounces` the last free disk bounces
!> elastically off the aggregate instead (the seed's option).
module edmd_core
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_numerical, exit_bad_input
  use edmd_heap, only: heap_t, heap_init, heap_set, heap_remove, heap_top
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  private

  public :: ed_t, ed_setup, ed_place_random, ed_place_lattice, ed_velocities, ed_start, &
       ed_run_until, ed_position, ed_kinetic, ed_momentum, ed_check_overlaps, ed_rebuild_cells, ed_put, ed_sort_by_cell, &
       rng_t, rng_uniform, rng_normal, ev_pair, ev_wall, ev_cell, ev_stick, ev_bounce
  public :: state_free, state_stuck, state_seed

  integer, parameter :: ev_none = 0, ev_pair = 1, ev_wall = 2, ev_cell = 3
  integer, parameter :: ev_stick = 4, ev_bounce = 5   !< logged types of pair events
  integer, parameter :: state_free = 0, state_stuck = 1, state_seed = 2
  real(dp), parameter :: never = huge(1.0_dp)

  !> splitmix64: a small, portable, seeded generator (initial state only).
  type :: rng_t
    integer(i8) :: s = 0
  end type rng_t

  type :: ed_t
    integer :: n = 0                        !< disks (free, stuck and the seed)
    real(dp) :: lx = 1, ly = 1              !< box [L]
    real(dp), allocatable :: x(:,:), v(:,:) !< position [L] at tl, velocity [L/tau]
    real(dp), allocatable :: tl(:)          !< time of the stored position [tau]
    real(dp), allocatable :: r(:), m(:)     !< radius [L], mass [M]
    integer, allocatable :: state(:)        !< state_free | state_stuck | state_seed
    integer(i8), allocatable :: coll(:)     !< per-disk counter of velocity changes
    ! the prediction of each free disk
    real(dp), allocatable :: ev_t(:)
    integer, allocatable :: ev_kind(:), ev_partner(:)
    integer(i8), allocatable :: ev_count(:)
    ! the best pair candidate of each free disk's last scan (kept across its cell crossings)
    real(dp), allocatable :: pb_t(:)
    integer, allocatable :: pb_j(:)
    integer(i8), allocatable :: pb_count(:)
    ! cells
    integer :: ncx = 1, ncy = 1
    real(dp) :: wx = 1, wy = 1
    integer, allocatable :: cell(:), head(:), next(:), prev(:)
    ! calendar
    logical :: use_heap = .true.
    type(heap_t) :: heap
    ! rules
    logical :: sticking = .true.
    logical :: last_bounces = .false.
    real(dp) :: guard_tol = 1.0e-9_dp       !< allowed overlap / (r_i + r_j) (round-off)
    ! clock and counters
    real(dp) :: t = 0                       !< time of the last event [tau]
    integer(i8) :: n_events = 0             !< physical events (pair, wall, stick, bounce)
    integer(i8) :: n_pair = 0, n_wall = 0, n_stick = 0, n_bounce = 0, n_cross = 0
    integer(i8) :: n_stale = 0              !< stale calendar entries re-predicted (not state)
    integer :: n_free = 0
    integer(i8) :: n_same = 0               !< consecutive events at the same time (guard)
    integer(i8) :: max_same = 0             !< guard: allowed zero-time cascade length
    real(dp) :: virial = 0                  !< sum of r_ij . dp_i over free-free collisions [M L^2/tau]
    real(dp) :: wall_impulse = 0            !< sum of |dp| over wall hits [M L/tau]
    ! aggregate
    integer, allocatable :: parent(:)       !< disk it stuck to (0: seed or free)
    real(dp), allocatable :: t_stick(:)
    integer(i8), allocatable :: ev_stuck(:)
    integer :: n_new = 0                    !< disks stuck since the caller last looked
    integer, allocatable :: new_stuck(:)
    ! event log (optional, small systems)
    logical :: logging = .false.
    integer :: n_log = 0
    real(dp), allocatable :: log_t(:)
    integer, allocatable :: log_kind(:), log_i(:), log_j(:)
    integer(i8), allocatable :: log_no(:)
  end type ed_t

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
  !> the box; cells of side >= the largest diameter.
  subroutine ed_setup(s, lx, ly, r, m, use_heap, sticking, last_bounces, logging)
    type(ed_t), intent(out) :: s
    real(dp), intent(in) :: lx, ly, r(:), m(:)
    logical, intent(in) :: use_heap, sticking, last_bounces, logging
    integer :: n
    real(dp) :: dmax
    n = size(r)
    s%n = n
    s%lx = lx
    s%ly = ly
    s%r = r
    s%m = m
    allocate(s%x(2, n), s%v(2, n), s%tl(n), s%state(n), s%coll(n), s%ev_t(n), s%ev_kind(n), &
         s%ev_partner(n), s%ev_count(n), s%cell(n), s%next(n), s%prev(n), s%parent(n), &
         s%t_stick(n), s%ev_stuck(n), s%new_stuck(n), s%pb_t(n), s%pb_j(n), s%pb_count(n))
    s%pb_t = never; s%pb_j = 0; s%pb_count = 0
    s%x = 0; s%v = 0; s%tl = 0
    s%state = state_free
    s%coll = 0
    s%ev_t = never; s%ev_kind = ev_none; s%ev_partner = 0; s%ev_count = 0
    s%parent = 0; s%t_stick = 0; s%ev_stuck = 0
    s%use_heap = use_heap
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
    allocate(s%head(0:s%ncx*s%ncy - 1))
    s%head = 0
    s%cell = -1
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
    cell_of = cx + s%ncx*cy
  end function cell_of

  subroutine cell_insert(s, i, c)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, c
    s%cell(i) = c
    s%prev(i) = 0
    s%next(i) = s%head(c)
    if (s%head(c) /= 0) s%prev(s%head(c)) = i
    s%head(c) = i
  end subroutine cell_insert

  subroutine cell_delete(s, i)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    if (s%prev(i) /= 0) then
      s%next(s%prev(i)) = s%next(i)
    else
      s%head(s%cell(i)) = s%next(i)
    end if
    if (s%next(i) /= 0) s%prev(s%next(i)) = s%prev(i)
    s%cell(i) = -1
  end subroutine cell_delete

  !> Cell lists from s%cell (restore), or from positions where s%cell < 0.
  subroutine ed_rebuild_cells(s)
    type(ed_t), intent(inout) :: s
    integer :: i, c
    s%head = 0
    do i = 1, s%n
      c = s%cell(i)
      if (c < 0) c = cell_of(s, s%x(1, i), s%x(2, i))
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
    nc = s%ncx*s%ncy
    allocate(cnt(0:nc), perm(first:s%n))
    cnt = 0
    do i = first, s%n
      cnt(s%cell(i) + 1) = cnt(s%cell(i) + 1) + 1
    end do
    do k = 1, nc
      cnt(k) = cnt(k) + cnt(k - 1)
    end do
    do i = first, s%n
      cnt(s%cell(i)) = cnt(s%cell(i)) + 1
      perm(first - 1 + cnt(s%cell(i))) = i
    end do
    s%x(:, first:) = s%x(:, perm)
    s%r(first:) = s%r(perm)
    s%m(first:) = s%m(perm)
    s%cell(first:) = s%cell(perm)
    call ed_rebuild_cells(s)
  end subroutine ed_sort_by_cell

  !> Put disk i at (x, y) [L] into the cells (placement of static disks).
  subroutine ed_put(s, i, x, y)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    real(dp), intent(in) :: x, y
    s%x(:, i) = [x, y]
    call cell_insert(s, i, cell_of(s, x, y))
  end subroutine ed_put

  !> .true. if a disk of radius ri at (x, y) overlaps a placed disk (cells).
  logical function overlaps_placed(s, x, y, ri, margin)
    type(ed_t), intent(in) :: s
    real(dp), intent(in) :: x, y, ri, margin
    integer :: c, cx, cy, ix, iy, j
    real(dp) :: d2, sg
    overlaps_placed = .false.
    c = cell_of(s, x, y)
    cx = mod(c, s%ncx)
    cy = c/s%ncx
    do iy = max(0, cy - 1), min(s%ncy - 1, cy + 1)
      do ix = max(0, cx - 1), min(s%ncx - 1, cx + 1)
        j = s%head(ix + s%ncx*iy)
        do while (j /= 0)
          sg = (ri + s%r(j))*(1.0_dp + margin)
          d2 = (x - s%x(1, j))**2 + (y - s%x(2, j))**2
          if (d2 < sg*sg) then
            overlaps_placed = .true.
            return
          end if
          j = s%next(j)
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
    real(dp) :: x, y
    character(len=200) :: buf
    integer, parameter :: max_tries = 100000
    do i = first, s%n
      do tries = 1, max_tries
        x = s%r(i) + rng_uniform(g)*(s%lx - 2.0_dp*s%r(i))
        y = s%r(i) + rng_uniform(g)*(s%ly - 2.0_dp*s%r(i))
        if (.not. overlaps_placed(s, x, y, s%r(i), 0.0_dp)) exit
      end do
      if (tries > max_tries) then
        write(buf, '(a,i0,a,i0,a)') 'random placement: no room for disk ', i, ' after ', &
             max_tries, ' tries (packing too dense for random sequential addition: '// &
             'lower &disks count or use placement = ''lattice'')'
        call set_error(st, exit_bad_input, trim(buf))
        return
      end if
      s%x(:, i) = [x, y]
      call cell_insert(s, i, cell_of(s, x, y))
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
    rm = maxval(s%r(first:))
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
        s%x(:, i) = [x, y]
        call cell_insert(s, i, cell_of(s, x, y))
        i = i + 1
      end do
    end do outer
    if (i <= s%n) call set_error(st, exit_bad_input, &
         'lattice placement: the box holds fewer sites than &disks count (pitch 2 r_max)')
  end subroutine ed_place_lattice

  !> Velocities of the free disks: 'fixed_speed' |v| = sqrt(2 kT/m) in a random
  !> direction (the seed's), or 'maxwell' (each component normal, variance kT/m).
  subroutine ed_velocities(s, g, rule, kt)
    type(ed_t), intent(inout) :: s
    type(rng_t), intent(inout) :: g
    character(len=*), intent(in) :: rule
    real(dp), intent(in) :: kt
    integer :: i
    real(dp) :: a, sp
    do i = 1, s%n
      if (s%state(i) /= state_free) cycle
      if (rule == 'maxwell') then
        s%v(1, i) = sqrt(kt/s%m(i))*rng_normal(g)
        s%v(2, i) = sqrt(kt/s%m(i))*rng_normal(g)
      else
        a = 6.283185307179586476925286766559_dp*rng_uniform(g)
        sp = sqrt(2.0_dp*kt/s%m(i))
        s%v(:, i) = sp*[cos(a), sin(a)]
      end if
    end do
  end subroutine ed_velocities

  !> Build the calendar from the stored states (start and restore).
  subroutine ed_start(s)
    type(ed_t), intent(inout) :: s
    integer :: i
    s%n_free = count(s%state == state_free)
    s%n_same = 0
    s%max_same = max(1000000_i8, 1000_i8*s%n)
    if (.not. s%use_heap) return
    call heap_init(s%heap, s%n)
    do i = 1, s%n
      if (s%state(i) == state_free) call predict(s, i)
    end do
  end subroutine ed_start

  ! ---------------------------------------------------------------- prediction
  !> Time of the collision of i and j [tau] (never if they do not collide);
  !> a pure function of the two stored states, symmetric in i and j.
  pure real(dp) function pair_time(s, i, j) result(tc)
    type(ed_t), intent(in) :: s
    integer, intent(in) :: i, j
    real(dp) :: tr, dx, dy, dvx, dvy, a, b, c, disc, sg
    tc = never
    tr = max(s%tl(i), s%tl(j))
    dvx = s%v(1, i) - s%v(1, j)
    dvy = s%v(2, i) - s%v(2, j)
    dx = (s%x(1, i) + s%v(1, i)*(tr - s%tl(i))) - (s%x(1, j) + s%v(1, j)*(tr - s%tl(j)))
    dy = (s%x(2, i) + s%v(2, i)*(tr - s%tl(i))) - (s%x(2, j) + s%v(2, j)*(tr - s%tl(j)))
    b = dx*dvx + dy*dvy
    if (b >= 0.0_dp) return                    ! separating (or at rest relative)
    sg = s%r(i) + s%r(j)
    c = dx*dx + dy*dy - sg*sg
    if (c <= 0.0_dp) then                      ! in contact (round-off) and approaching: now
      tc = tr
      return
    end if
    a = dvx*dvx + dvy*dvy
    disc = b*b - a*c
    if (disc <= 0.0_dp) return                 ! miss
    tc = tr + c/(-b + sqrt(disc))              ! stable root: no cancellation for small c
  end function pair_time

  !> Candidate (t, kind, partner) before (t0, k0, p0)? Lexicographic: order-free.
  pure logical function earlier(t, k, p, t0, k0, p0)
    real(dp), intent(in) :: t, t0
    integer, intent(in) :: k, p, k0, p0
    earlier = t < t0
    if (t == t0) earlier = k < k0 .or. (k == k0 .and. p < p0)
  end function earlier

  !> Wall time and wall (1 x-, 2 x+, 3 y-, 4 y+) of free disk i.
  pure subroutine wall_time(s, i, tw, w)
    type(ed_t), intent(in) :: s
    integer, intent(in) :: i
    real(dp), intent(out) :: tw
    integer, intent(out) :: w
    real(dp) :: t1
    tw = never
    w = 0
    if (s%v(1, i) > 0.0_dp) then
      tw = s%tl(i) + max(0.0_dp, (s%lx - s%r(i) - s%x(1, i))/s%v(1, i)); w = 2
    else if (s%v(1, i) < 0.0_dp) then
      tw = s%tl(i) + max(0.0_dp, (s%r(i) - s%x(1, i))/s%v(1, i)); w = 1
    end if
    t1 = never
    if (s%v(2, i) > 0.0_dp) then
      t1 = s%tl(i) + max(0.0_dp, (s%ly - s%r(i) - s%x(2, i))/s%v(2, i))
      if (t1 < tw) then
        tw = t1; w = 4
      end if
    else if (s%v(2, i) < 0.0_dp) then
      t1 = s%tl(i) + max(0.0_dp, (s%r(i) - s%x(2, i))/s%v(2, i))
      if (t1 < tw) then
        tw = t1; w = 3
      end if
    end if
  end subroutine wall_time

  !> Earliest cell-crossing time and direction (1 x-, 2 x+, 3 y-, 4 y+).
  pure subroutine cross_time(s, i, tx, d)
    type(ed_t), intent(in) :: s
    integer, intent(in) :: i
    real(dp), intent(out) :: tx
    integer, intent(out) :: d
    integer :: cx, cy
    real(dp) :: t1
    cx = mod(s%cell(i), s%ncx)
    cy = s%cell(i)/s%ncx
    tx = never
    d = 0
    if (s%v(1, i) > 0.0_dp .and. cx < s%ncx - 1) then
      tx = s%tl(i) + max(0.0_dp, ((cx + 1)*s%wx - s%x(1, i))/s%v(1, i)); d = 2
    else if (s%v(1, i) < 0.0_dp .and. cx > 0) then
      tx = s%tl(i) + max(0.0_dp, (cx*s%wx - s%x(1, i))/s%v(1, i)); d = 1
    end if
    if (s%v(2, i) > 0.0_dp .and. cy < s%ncy - 1) then
      t1 = s%tl(i) + max(0.0_dp, ((cy + 1)*s%wy - s%x(2, i))/s%v(2, i))
      if (t1 < tx) then
        tx = t1; d = 4
      end if
    else if (s%v(2, i) < 0.0_dp .and. cy > 0) then
      t1 = s%tl(i) + max(0.0_dp, (cy*s%wy - s%x(2, i))/s%v(2, i))
      if (t1 < tx) then
        tx = t1; d = 3
      end if
    end if
  end subroutine cross_time

  !> Best pair candidate of free disk i over the cells cx0..cx1 x cy0..cy1, into pb_*
  !> (only if earlier than the one held).
  subroutine scan_cells(s, i, cx0, cx1, cy0, cy1)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, cx0, cx1, cy0, cy1
    integer :: ix, iy, j
    real(dp) :: tc
    do iy = max(0, cy0), min(s%ncy - 1, cy1)
      do ix = max(0, cx0), min(s%ncx - 1, cx1)
        j = s%head(ix + s%ncx*iy)
        do while (j /= 0)
          if (j /= i) then
            tc = pair_time(s, i, j)
            if (tc < never) then
              if (earlier(tc, ev_pair, j, s%pb_t(i), ev_pair, s%pb_j(i))) then
                s%pb_t(i) = tc
                s%pb_j(i) = j
                s%pb_count(i) = s%coll(j)
              end if
            end if
          end if
          j = s%next(j)
        end do
      end do
    end do
  end subroutine scan_cells

  !> Earliest event of free disk i over walls, its cell edges and the disks
  !> of the 3 x 3 cells around it; into the calendar.
  subroutine predict(s, i)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    integer :: cx, cy
    s%pb_t(i) = never
    s%pb_j(i) = 0
    cx = mod(s%cell(i), s%ncx)
    cy = s%cell(i)/s%ncx
    call scan_cells(s, i, cx - 1, cx + 1, cy - 1, cy + 1)
    call choose(s, i)
  end subroutine predict

  !> After disk i crossed into a new cell in direction d: its best pair candidate still holds
  !> if the partner has not changed since (the old 3 x 3 cells were scanned with the same
  !> trajectories), so only the row or column of cells that became adjacent is scanned.
  !> Otherwise a full prediction. The same events result (tests: heap = rescan), at a third of
  !> the cell scans per crossing.
  subroutine predict_after_cross(s, i, d)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, d
    integer :: cx, cy
    if (s%pb_j(i) /= 0) then
      if (s%coll(s%pb_j(i)) /= s%pb_count(i)) then
        call predict(s, i)
        return
      end if
    end if
    cx = mod(s%cell(i), s%ncx)
    cy = s%cell(i)/s%ncx
    select case (d)
    case (1); call scan_cells(s, i, cx - 1, cx - 1, cy - 1, cy + 1)
    case (2); call scan_cells(s, i, cx + 1, cx + 1, cy - 1, cy + 1)
    case (3); call scan_cells(s, i, cx - 1, cx + 1, cy - 1, cy - 1)
    case (4); call scan_cells(s, i, cx - 1, cx + 1, cy + 1, cy + 1)
    end select
    call choose(s, i)
  end subroutine predict_after_cross

  !> The calendar entry of disk i: the earliest of its wall, cell crossing and best pair.
  subroutine choose(s, i)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    real(dp) :: tb, tc
    integer :: kb, pb, w
    call wall_time(s, i, tb, w)
    kb = ev_wall; pb = w
    call cross_time(s, i, tc, w)
    if (earlier(tc, ev_cell, w, tb, kb, pb)) then
      tb = tc; kb = ev_cell; pb = w
    end if
    if (s%pb_j(i) /= 0) then
      if (earlier(s%pb_t(i), ev_pair, s%pb_j(i), tb, kb, pb)) then
        tb = s%pb_t(i); kb = ev_pair; pb = s%pb_j(i)
      end if
    end if
    call set_event(s, i, tb, kb, pb)
  end subroutine choose

  subroutine set_event(s, i, t, k, p)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, k, p
    real(dp), intent(in) :: t
    s%ev_t(i) = t
    s%ev_kind(i) = k
    s%ev_partner(i) = p
    s%ev_count(i) = 0
    if (k == ev_pair) s%ev_count(i) = s%coll(p)
    call heap_set(s%heap, i, t)
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
      call wall_time(s, i, tc, w)
      if (tc < tb .or. (tc == tb .and. i < ib)) then
        tb = tc; kb = ev_wall; ib = i; pb = w
      end if
    end do
    do i = 1, s%n - 1
      do j = i + 1, s%n
        if (s%state(i) /= state_free .and. s%state(j) /= state_free) cycle
        tc = pair_time(s, i, j)
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
      if (s%use_heap) then
        i = heap_top(s%heap)
        if (i == 0) exit
        te = s%ev_t(i)
        if (te >= t_target) exit
        k = s%ev_kind(i)
        p = s%ev_partner(i)
        if (k == ev_pair) then
          if (s%coll(p) /= s%ev_count(i)) then      ! partner changed since: stale entry
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
    c = s%cell(i)
    select case (d)
    case (1); c = c - 1
    case (2); c = c + 1
    case (3); c = c - s%ncx
    case (4); c = c + s%ncx
    end select
    call cell_delete(s, i)
    call cell_insert(s, i, c)
  end subroutine cross

  subroutine move_to(s, i, te)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i
    real(dp), intent(in) :: te
    s%x(:, i) = s%x(:, i) + s%v(:, i)*(te - s%tl(i))
    s%tl(i) = te
  end subroutine move_to

  subroutine wall_hit(s, i, w, te)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, w
    real(dp), intent(in) :: te
    integer :: ax
    call move_to(s, i, te)
    ax = (w + 1)/2
    select case (w)                          ! exactly at contact with the wall
    case (1, 3); s%x(ax, i) = s%r(i)
    case (2); s%x(ax, i) = s%lx - s%r(i)
    case (4); s%x(ax, i) = s%ly - s%r(i)
    end select
    s%wall_impulse = s%wall_impulse + 2.0_dp*s%m(i)*abs(s%v(ax, i))
    s%v(ax, i) = -s%v(ax, i)
    s%coll(i) = s%coll(i) + 1
    s%n_wall = s%n_wall + 1
    s%n_events = s%n_events + 1
    call log_event(s, ev_wall, i, -w)
    if (s%use_heap) call predict(s, i)
  end subroutine wall_hit

  !> Collision of free disk i with disk j at te: elastic (j free), or with a
  !> static j: stick (the rule) or bounce (sticking off / the last free disk).
  subroutine pair_hit(s, i, j, te, st)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, j
    real(dp), intent(in) :: te
    type(status_t), intent(inout) :: st
    real(dp) :: nx, ny, d, sg, vn, mu, jx, jy
    call move_to(s, i, te)
    if (s%state(j) == state_free) call move_to(s, j, te)
    nx = s%x(1, i) - s%x(1, j)
    ny = s%x(2, i) - s%x(2, j)
    d = sqrt(nx*nx + ny*ny)
    sg = s%r(i) + s%r(j)
    if (d < sg*(1.0_dp - s%guard_tol) .or. .not. ieee_is_finite(d)) then
      call guard_fail(s, st, 'overlap at contact', i, j, sg - d)
      return
    end if
    nx = nx/d
    ny = ny/d
    vn = (s%v(1, i) - s%v(1, j))*nx + (s%v(2, i) - s%v(2, j))*ny   ! < 0: approaching
    s%n_events = s%n_events + 1
    if (s%state(j) /= state_free) then
      if (s%sticking .and. .not. (s%last_bounces .and. s%n_free == 1)) then
        call stick(s, i, j, te)
        return
      end if
      s%v(1, i) = s%v(1, i) - 2.0_dp*vn*nx                          ! mirror off the static disk
      s%v(2, i) = s%v(2, i) - 2.0_dp*vn*ny
      s%coll(i) = s%coll(i) + 1
      s%n_bounce = s%n_bounce + 1
      call log_event(s, ev_bounce, i, j)
      if (s%use_heap) call predict(s, i)
      return
    end if
    mu = s%m(i)*s%m(j)/(s%m(i) + s%m(j))
    jx = 2.0_dp*mu*vn*nx                                            ! impulse on j (= -dp_i)
    jy = 2.0_dp*mu*vn*ny
    s%v(1, i) = s%v(1, i) - jx/s%m(i)
    s%v(2, i) = s%v(2, i) - jy/s%m(i)
    s%v(1, j) = s%v(1, j) + jx/s%m(j)
    s%v(2, j) = s%v(2, j) + jy/s%m(j)
    s%virial = s%virial - 2.0_dp*mu*vn*d                            ! r_ij . dp_i > 0
    s%coll(i) = s%coll(i) + 1
    s%coll(j) = s%coll(j) + 1
    s%n_pair = s%n_pair + 1
    call log_event(s, ev_pair, min(i, j), max(i, j))
    if (s%use_heap) then
      call predict(s, i)
      call predict(s, j)
    end if
  end subroutine pair_hit

  !> Free disk i (at contact with static j) joins the aggregate.
  subroutine stick(s, i, j, te)
    type(ed_t), intent(inout) :: s
    integer, intent(in) :: i, j
    real(dp), intent(in) :: te
    integer :: cx, cy, ix, iy, k
    real(dp) :: tc
    s%v(:, i) = 0.0_dp
    s%state(i) = state_stuck
    s%parent(i) = j
    s%t_stick(i) = te
    s%ev_stuck(i) = s%n_events
    s%coll(i) = s%coll(i) + 1
    s%n_free = s%n_free - 1
    s%n_stick = s%n_stick + 1
    s%n_new = s%n_new + 1
    s%new_stuck(s%n_new) = i
    call log_event(s, ev_stick, i, j)
    if (.not. s%use_heap) return
    call heap_remove(s%heap, i)
    ! A static disk predicts nothing: its free neighbours must learn of it now.
    cx = mod(s%cell(i), s%ncx)
    cy = s%cell(i)/s%ncx
    do iy = max(0, cy - 1), min(s%ncy - 1, cy + 1)
      do ix = max(0, cx - 1), min(s%ncx - 1, cx + 1)
        k = s%head(ix + s%ncx*iy)
        do while (k /= 0)
          if (s%state(k) == state_free) then
            tc = pair_time(s, k, i)
            if (tc < never) then
              ! against k's best pair (kept across its crossings), not only its entry
              if (earlier(tc, ev_pair, i, s%pb_t(k), ev_pair, s%pb_j(k))) then
                s%pb_t(k) = tc
                s%pb_j(k) = i
                s%pb_count(k) = s%coll(i)
                if (earlier(tc, ev_pair, i, s%ev_t(k), s%ev_kind(k), s%ev_partner(k))) &
                     call set_event(s, k, tc, ev_pair, i)
              end if
            end if
          end if
          k = s%next(k)
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
    p = s%x(:, i) + s%v(:, i)*(t - s%tl(i))
  end function ed_position

  pure real(dp) function ed_kinetic(s) result(e)
    type(ed_t), intent(in) :: s
    integer :: i
    e = 0
    do i = 1, s%n
      if (s%state(i) == state_free) e = e + 0.5_dp*s%m(i)*(s%v(1, i)**2 + s%v(2, i)**2)
    end do
  end function ed_kinetic

  pure function ed_momentum(s) result(p)
    type(ed_t), intent(in) :: s
    real(dp) :: p(2)
    integer :: i
    p = 0
    do i = 1, s%n
      if (s%state(i) == state_free) p = p + s%m(i)*s%v(:, i)
    end do
  end function ed_momentum

  !> Guard at time t: every pair of the cell neighbourhoods and every wall
  !> (positions interpolated); st = exit_numerical naming the worst overlap.
  subroutine ed_check_overlaps(s, t, st)
    type(ed_t), intent(in) :: s
    real(dp), intent(in) :: t
    type(status_t), intent(inout) :: st
    integer :: i, j, c, cx, cy, ix, iy, wi, wj
    real(dp) :: pi_(2), pj(2), d, sg, worst, ov
    character(len=400) :: buf
    worst = 0; wi = 0; wj = 0
    do i = 1, s%n
      pi_ = ed_position(s, i, t)
      ov = max(s%r(i) - pi_(1), pi_(1) + s%r(i) - s%lx, s%r(i) - pi_(2), pi_(2) + s%r(i) - s%ly)
      if (ov > s%guard_tol*s%r(i) .and. ov > worst) then
        worst = ov; wi = i; wj = 0
      end if
      c = cell_of(s, pi_(1), pi_(2))
      cx = mod(c, s%ncx)
      cy = c/s%ncx
      do iy = max(0, cy - 1), min(s%ncy - 1, cy + 1)
        do ix = max(0, cx - 1), min(s%ncx - 1, cx + 1)
          j = s%head(ix + s%ncx*iy)
          do while (j /= 0)
            if (j > i) then
              pj = ed_position(s, j, t)
              d = sqrt(sum((pi_ - pj)**2))
              sg = s%r(i) + s%r(j)
              if (sg - d > s%guard_tol*sg .and. sg - d > worst) then
                worst = sg - d; wi = i; wj = j
              end if
            end if
            j = s%next(j)
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
