!> Kind 'dla': hard disks in a closed box, event-driven (module edmd_core),
!> Longer than 600 lines because the kind is one type: its key declarations, the rules
!> across keys that keep the event arithmetic exact (validate_radii: ~90 lines), the initial
!> state, the rows and the checkpoint; the event machinery is edmd_core.
!> aggregating on a static seed disk at the centre (diffusion-limited or
!> ballistic aggregation, depending on the mean free path; seed 004).
!>
!> Units: length L (the box unit: lx, ly and the radii are in L), mass M,
!> energy E (kT in E), time tau = L sqrt(M/E). Masses: mass_rule = 'area'
!> m = density pi r^2 (density in M/L^2, the default), or 'perimeter'
!> m = density pi r (the seed's formula, density in M/L).
!>
!> A unit of work (advance) is one tick of `tick` tau: the events before the
!> next tick are processed, then the rows due at the tick are written (frames
!> with positions interpolated exactly between events, history, aggregate).
module edmd_dla
  use kinds, only: dp, i8, pi
  use errors, only: status_t, set_error, exit_bad_input, exit_io
  use method, only: method_t, open_default
  use memory, only: check_memory_need
  use tables, only: rfmt
  use scene_input, only: json_real
  use output_set, only: due, frames_as
  use ckpt, only: ckpt_writer_t, ckpt_put
  use, intrinsic :: iso_fortran_env, only: int8
  use scene_input, only: kind_len, check_real, check_int, int_str, real_str
  use schema, only: schema_t, max_steps_all
  use edmd_core, only: ed_t, ed_setup, ed_place_random, ed_place_lattice, ed_velocities, &
       ed_start, ed_run_until, ed_position, ed_kinetic, ed_momentum, ed_check_overlaps, &
       ed_put, ed_sort_by_cell, ed_cells, ed_load_cells, rng_t, state_free, state_seed
  implicit none
  private

  public :: dla_t

  integer, parameter :: name_len = 32, max_species = 4
  integer, parameter :: max_explicit = 16          !< disks of placement = 'explicit'

  type, extends(method_t) :: dla_t
    ! &scene
    character(len=kind_len) :: kind = 'dla'
    character(len=128) :: title = 'untitled'
    ! &box
    real(dp) :: lx = 100, ly = 100                    !< [L]
    ! &disks
    integer(i8) :: n_species = 1
    integer(i8) :: count(max_species) = [1000_i8, 0_i8, 0_i8, 0_i8]
    real(dp) :: radius(max_species) = 0.5_dp          !< [L]
    real(dp) :: density(max_species) = 1.0_dp         !< [M/L^2] ('area') or [M/L] ('perimeter')
    character(len=name_len) :: mass_rule = 'area'
    logical :: sticky(max_species) = .true.           !< species k sticks (else: a carrier)
    real(dp) :: kt = 1.0_dp                           !< [E]
    character(len=name_len) :: velocities = 'fixed_speed'
    character(len=name_len) :: placement = 'random'
    real(dp) :: x0(max_explicit) = 0, y0(max_explicit) = 0     !< 'explicit' positions [L]
    real(dp) :: vx0(max_explicit) = 0, vy0(max_explicit) = 0   !< 'explicit' velocities [L/tau]
    integer(i8) :: seed = 1
    ! &aggregate
    logical :: sticking = .true.
    real(dp) :: seed_radius = 0.5_dp                  !< [L], 0 = no seed disk
    real(dp) :: seed_x = -1, seed_y = -1              !< [L], -1 = box centre
    logical :: last_bounces = .false.
    logical :: stop_when_done = .true.
    ! &run
    character(len=name_len) :: calendar = 'buckets'
    real(dp) :: tick = 0.02_dp                        !< [tau] (the seed's frame dt)
    real(dp) :: t_end = 100.0_dp                      !< [tau]
    real(dp) :: guard_tol = 1.0e-9_dp                 !< overlap allowed / (r_i + r_j)
    ! &output (cadences in ticks, 0 = off)
    integer(i8) :: frame_every = 50
    integer(i8) :: history_every = 5
    integer(i8) :: check_every = 1
    logical :: log_events = .false.
    character(len=name_len) :: frames_format = 'text'   !< frames.dat | 'binary': frames.bin | 'both'
    ! state (step, n_steps: ticks done and in the run, method_t's)
    type(ed_t) :: s
    real(dp) :: t_hist = 0                            !< time of the last history row [tau]
    integer :: n_members = 0                          !< aggregate rows written
    real(dp) :: seconds = 0                           !< CPU time in the event loop [s] (not state)
    integer :: frames = 0, history = 0, aggregate = 0, events = 0, frames_bin = 0  !< output ids
  contains
    procedure :: keys, resolve, setup, open_outputs, advance, finish
    procedure :: rules => validate
    procedure :: save_state, restore_state, progress_text, json_fields
  end type dla_t

  !> columns of frames.dat and frames.bin after tick and t
  character(len=*), parameter :: frame_cols(8) = [character(len=5) :: 'id', 'x', 'y', 'vx', &
       'vy', 'r', 'm', 'state']
  character(len=*), parameter :: frame_units(8) = [character(len=5) :: '', 'L', 'L', 'L/tau', &
       'L/tau', 'L', 'M', '1']
  character(len=*), parameter :: units = 'Units: length L (box unit), mass M, energy E (kT), '// &
       'time tau = L sqrt(M/E).'

contains

  !> The scene of this kind, declared once (module schema): reading,
  !> validation, scene.nml and `partsim --describe dla` come from it.
  subroutine keys(self, s)
    class(dla_t), intent(inout), target :: self
    type(schema_t), intent(inout) :: s
    call s%init('dla', 'kind dla (every key). '//units)
    call s%scene_group(self%kind, self%title)
    call s%group('box', 'the closed box [0, lx] x [0, ly]')
    call s%key('lx', self%lx, 'L', 'box side along x', lo=0.0_dp, lo_open=.true., hi=1.0e9_dp)
    call s%key('ly', self%ly, 'L', 'box side along y', lo=0.0_dp, lo_open=.true., hi=1.0e9_dp)
    call s%group('disks', 'the free disks, by species')
    call s%key('n_species', self%n_species, '', 'species in use (the arrays below hold one '// &
         'value per species)', lo=1_i8, hi=int(max_species, i8))
    call s%key('count', self%count, '', 'free disks of each species (sum in [1, 1e7])', &
         lo=0_i8, hi=10000000_i8, size_key='n_species')
    call s%key('radius', self%radius, 'L', 'radius of each species (<= min(lx, ly)/2; '// &
         'smallest: README, Smallest radius)', lo=0.0_dp, lo_open=.true., hi=5.0e8_dp, &
         size_key='n_species')
    call s%key('density', self%density, 'M/L^2 | M/L', 'mass density of each species: '// &
         'm = density pi r^2 (mass_rule area, M/L^2) or density pi r (perimeter, M/L)', &
         lo=0.0_dp, lo_open=.true., hi=1.0e12_dp, size_key='n_species')
    call s%key('sticky', self%sticky, '', 'species sticks to the aggregate (.false.: a '// &
         'carrier, bounces off it)', size_key='n_species')
    call s%key('mass_rule', self%mass_rule, '', 'area: m = density pi r^2; perimeter: '// &
         'm = density pi r (the seed''s)', choices='area|perimeter')
    call s%key('kt', self%kt, 'E', 'temperature of the initial velocities', lo=0.0_dp, &
         lo_open=.true., hi=1.0e12_dp)
    call s%key('velocities', self%velocities, '', 'fixed_speed: |v| = sqrt(2 kT/m) in '// &
         'random directions (the seed''s); maxwell: normal components of variance kT/m', &
         choices='fixed_speed|maxwell')
    call s%key('placement', self%placement, '', 'random (sequential addition), lattice '// &
         '(square, in contact) or explicit (x0, y0, vx0, vy0)', choices='random|lattice|explicit')
    call s%key('x0', self%x0, 'L', 'placement = explicit: x of the free disks, in species order')
    call s%key('y0', self%y0, 'L', 'placement = explicit: y of the free disks')
    call s%key('vx0', self%vx0, 'L/tau', 'placement = explicit: vx of the free disks', &
         lo=-1.0e12_dp, hi=1.0e12_dp)
    call s%key('vy0', self%vy0, 'L/tau', 'placement = explicit: vy of the free disks', &
         lo=-1.0e12_dp, hi=1.0e12_dp)
    call s%key('seed', self%seed, '', 'RNG seed of the initial state', lo=0_i8)
    call s%group('aggregate', 'the static seed disk and the sticking rule')
    call s%key('sticking', self%sticking, '', 'free sticky disks stick to the aggregate '// &
         '(.false.: a hard-disk gas)')
    call s%key('seed_radius', self%seed_radius, 'L', 'radius of the static seed disk (0 = '// &
         'none; > 0 with sticking; <= min(lx, ly)/2)', lo=0.0_dp, hi=5.0e8_dp)
    call s%key('seed_x', self%seed_x, 'L', 'seed centre x (< 0: the box centre; resolved)')
    call s%key('seed_y', self%seed_y, 'L', 'seed centre y (< 0: the box centre; resolved)')
    call s%key('last_bounces', self%last_bounces, '', 'the last free sticky disk bounces '// &
         '(the seed''s option)')
    call s%key('stop_when_done', self%stop_when_done, '', 'end when every sticky disk is stuck')
    call s%group('run', 'the event loop')
    call s%key('calendar', self%calendar, '', 'buckets: O(1); heap: O(log N); rescan: the '// &
         'seed''s O(N^2); same events', choices='buckets|heap|rescan')
    call s%key('tick', self%tick, 'tau', 'unit of work (rows are written at ticks; in '// &
         '[t_end/1e12, t_end])', lo=0.0_dp, lo_open=.true., hi=1.0e12_dp)
    call s%key('t_end', self%t_end, 'tau', 'run length', lo=0.0_dp, lo_open=.true., &
         hi=1.0e12_dp)
    call s%key('guard_tol', self%guard_tol, '1', 'overlap allowed at a contact / (r_i + r_j) '// &
         '(round-off)', lo=0.0_dp, hi=1.0e-3_dp)
    call s%group('output', 'cadences in ticks (0 = off)')
    call s%key('frame_every', self%frame_every, 'ticks', 'frames (0 = off)', lo=0_i8, &
         hi=max_steps_all)
    call s%key('history_every', self%history_every, 'ticks', 'history.dat rows (0 = off)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('check_every', self%check_every, 'ticks', 'all-pairs overlap guard (0 = off)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('checkpoint_every', self%checkpoint_every, 'ticks', 'checkpoints (0 = none)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('log_events', self%log_events, '', 'events.dat (small systems)')
    call s%key('frames_format', self%frames_format, '', 'text: frames.dat, binary: '// &
         'frames.bin, both', choices='text|binary|both')
  end subroutine keys

  !> seed_x, seed_y < 0: the box centre.
  subroutine resolve(self)
    class(dla_t), intent(inout) :: self
    if (self%seed_x < 0) self%seed_x = 0.5_dp*self%lx
    if (self%seed_y < 0) self%seed_y = 0.5_dp*self%ly
  end subroutine resolve

  !> The tick count, the initial state and the outputs.
  subroutine setup(self, path, st)
    class(dla_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    self%n_steps = nint(self%t_end/self%tick, i8)
    self%time_unit = self%tick
    call initial_state(self, st)
    if (st%code /= 0) return
    call self%out%table(self%frames, 'frames.dat', &
         '# frames.dat: disks at fixed times (exact interpolation between events); state 0 '// &
         'free, 1 stuck, 2 seed; m = 0 for the seed (static). '//units, &
         '# tick t[tau] id x[L] y[L] vx[L/tau] vy[L/tau] r[L] m[M] state[1]', &
         on=frames_as(self%frame_every, self%frames_format, 'text'))
    call self%out%table(self%history, 'history.dat', &
         '# history.dat: cumulative event counts, free disks (all; free_sticky: those of '// &
         'sticky species), kinetic energy, momentum of the '// &
         'free disks; pressures over the interval since the previous row (0 on the first): '// &
         'P_virial = (E_kin + sum r_ij.dp_i / (2 dt)) / A, P_wall = sum of each wall hit''s '// &
         '|dp| / (2 (lx + ly - 4 r_i) dt) (the perimeter its centre reaches). '//units, &
         '# tick t[tau] events[1] pair[1] wall[1] stick[1] bounce[1] cross[1] free[1] '// &
         'E_kin[E] px[M*L/tau] py[M*L/tau] P_virial[E/L^2] P_wall[E/L^2] free_sticky[1]', &
         on=self%history_every > 0)
    call self%out%table(self%aggregate, 'aggregate.dat', &
         '# aggregate.dat: members in the order they stuck (member 0 = seed); parent = the '// &
         'disk id it stuck to (a tree); event = physical event number; vx, vy = its velocity '// &
         'when it stuck (0 for the seed). '//units, &
         '# member[1] id[1] x[L] y[L] r[L] t_stick[tau] event[1] parent[1] vx[L/tau] '// &
         'vy[L/tau]', on=self%sticking)
    call self%out%table(self%events, 'events.dat', &
         '# events.dat: every physical event; type 1 pair, 2 wall (j = -wall: 1 x-, 2 x+, '// &
         '3 y-, 4 y+), 4 stick, 5 bounce off the aggregate. '//units, &
         '# event[1] t[tau] type[1] i[1] j[1]', on=self%log_events)
    call self%out%frames(self%frames_bin, 'frames.bin', self%s%n, frame_cols, frame_units, &
         ['i4', 'f8', 'f8', 'f8', 'f8', 'f8', 'f8', 'i4'], 'tick', 'tau', '"kind": "dla", '// &
         '"box": ['//json_real(self%lx)//', '//json_real(self%ly)//']', &
         on=frames_as(self%frame_every, self%frames_format, 'binary'))
  end subroutine setup

  !> Rules across keys (each key's own range is the declaration's, checked before).
  subroutine validate(self, s, path, st)
    class(dla_t), intent(inout) :: self
    type(schema_t), intent(in) :: s
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: ns
    real(dp) :: rmax_box, eta
    ns = int(self%n_species)
    rmax_box = 0.5_dp*min(self%lx, self%ly)
    call check_int(path, 'disks', 'count (sum over species)', sum(self%count(1:ns)), 1_i8, &
         10000000_i8, st)
    call validate_radii(self, path, st)
    call validate_sticky(self, path, st)
    if (st%code /= 0) return
    call check_real(path, 'aggregate', 'seed_radius', self%seed_radius, 0.0_dp, rmax_box, &
         .not. self%sticking, st)
    if (st%code /= 0) return
    if (self%seed_radius > 0) then
      call check_real(path, 'aggregate', 'seed_x', self%seed_x, self%seed_radius, &
           self%lx - self%seed_radius, .true., st)
      call check_real(path, 'aggregate', 'seed_y', self%seed_y, self%seed_radius, &
           self%ly - self%seed_radius, .true., st)
    end if
    if (self%placement == 'explicit') call validate_explicit(self, path, st)
    if (st%code /= 0) return
    ! peak memory: disk records, calendar, cells and a frame's buffer, measured 285 B a disk
    ! at 1e6 disks (RSS), with a margin: refused before anything is allocated
    call check_memory_need(320.0_dp*real(sum(self%count(1:ns)), dp) + 32.0_dp*2.0_dp**20, &
         trim(path)//': &disks count = '//int_str(sum(self%count(1:ns))), 'reduce count', st)
    if (st%code /= 0) return
    eta = (sum(pi*self%radius(1:ns)**2*real(self%count(1:ns), dp)) + pi*self%seed_radius**2)/ &
         (self%lx*self%ly)
    if (eta > 0.9_dp) call set_error(st, exit_bad_input, trim(path)//': &disks count = '// &
         int_str(sum(self%count(1:ns)))//': packing fraction '//real_str(eta)// &
         ' of the box: allowed < 0.9 (close packing of disks: 0.9069)')
    if (st%code /= 0) return
    if (self%tick > self%t_end .or. self%t_end/self%tick > real(max_steps_all, dp)) &
         call set_error(st, exit_bad_input, trim(path)//': &run tick = '// &
         real_str(self%tick)//': allowed [t_end/'//int_str(max_steps_all)//', t_end] = ['// &
         real_str(self%t_end/real(max_steps_all, dp))//', '//real_str(self%t_end)// &
         '] tau (at most '//int_str(max_steps_all)//' ticks)')
  end subroutine validate

  !> The radii the event arithmetic resolves (issue 29). A collision time is the
  !> root of |dr + dv t|^2 = (r_i + r_j)^2 from the two disks' stored states, which
  !> are D apart: the constant term |dr|^2 - (r_i + r_j)^2 carries eps D^2 of round-off,
  !> i.e. a contact misplaced by ~ eps (D/(r_i + r_j))^2 of r_i + r_j (measured: 1000
  !> disks of r = 1e-4, 1.5e-4 and 2e-4 L in a unit box overlap by 1.1e-9 (r_i + r_j)
  !> within 1500 events). D is at most the box diagonal, and in a gas that stays (sticking
  !> off, or carriers) about the longest flight: 30 mean free paths (the longest of 1e12
  !> exponential flights is ln(1e12) = 28 of them), lambda = A / (2 sqrt(2) N r).
  !> Event times are absolute: a disk moves v eps t_end in one rounding of the clock at
  !> t_end. Both must stay within tol = max(guard_tol, 1e-9) of a contact:
  !>   eps (D / (2 r))^2 <= tol,   v eps t_end <= tol r   (v = sqrt(2 kT/m), or the
  !>   largest explicit speed),
  !> and the mass m = density pi r^2 (or pi r) >= 1e-150 M (mass products in the impulse).
  !> The cell grid (side >= the largest diameter) holds at most 2^26 cells.
  subroutine validate_radii(self, path, st)
    class(dla_t), intent(in) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp), parameter :: eps = epsilon(1.0_dp), tol_floor = 1.0e-9_dp, m_min = 1.0e-150_dp
    real(dp), parameter :: max_cells = 67108864.0_dp   ! 2^26 cells (256 MiB of list heads)
    real(dp), parameter :: flights = 30.0_dp           ! longest flight / mean free path
    real(dp) :: tol, diag, span, r_space, r_time, r_mass, r_min, rmax_box, p, v, rmax, cells
    real(dp) :: n_gas, d
    integer :: k, ns, n, hi
    character(len=:), allocatable :: name, why, fix, empty
    if (st%code /= 0) return
    ns = int(self%n_species)
    tol = max(self%guard_tol, tol_floor)
    span = sqrt(tol/eps)                      ! D/(2 r) allowed
    diag = hypot(self%lx, self%ly)
    rmax_box = 0.5_dp*min(self%lx, self%ly)
    p = merge(1.0_dp, 2.0_dp, self%mass_rule == 'perimeter')
    n_gas = real(sum(self%count(1:ns)), dp)   ! disks that stay free (sticking off, carriers)
    if (self%sticking) n_gas = real(sum(self%count(1:ns), mask=.not. self%sticky(1:ns)), dp)
    n = 0
    do k = 1, ns
      name = 'radius('//int_str(int(k, i8))//')'
      if (self%radius(k) > rmax_box) then
        call set_error(st, exit_bad_input, trim(path)//': &disks '//name//' = '// &
             real_str(self%radius(k))//': allowed (0, min(lx, ly)/2 = '//real_str(rmax_box)// &
             '] L')
        return
      end if
      if (self%count(k) == 0) cycle
      ! D = min(diag, flights lambda(r)): eps (D/(2 r))^2 <= tol holds from the smaller of
      ! r = diag/(2 span) and r = sqrt(flights A / (4 sqrt(2) N span))
      r_space = 0.5_dp*diag/span
      if (n_gas > 0) r_space = min(r_space, sqrt(flights*self%lx*self%ly/ &
           (4.0_dp*sqrt(2.0_dp)*n_gas*span)))
      r_mass = exp((log(m_min) - log(self%density(k)*pi))/p)
      if (self%placement == 'explicit') then    ! (more than max_explicit: validate_explicit)
        hi = int(min(n + self%count(k), int(max_explicit, i8)))
        v = 0
        if (hi > n) v = maxval(hypot(self%vx0(n + 1:hi), self%vy0(n + 1:hi)))
        r_time = v*eps*self%t_end/tol
        why = 'the largest explicit speed, '//real_str(v)//' L/tau'
      else       ! v = sqrt(2 kT/(density pi r^p)): v eps t_end <= tol r solved for r (logs)
        r_time = exp((0.5_dp*(log(2.0_dp*self%kt) - log(self%density(k)*pi)) + &
             log(eps*self%t_end/tol))/(1.0_dp + 0.5_dp*p))
        why = 'sqrt(2 kT/m) = '//real_str(sqrt(2.0_dp*self%kt/(self%density(k)*pi* &
             self%radius(k)**p)))//' L/tau'
      end if
      n = n + int(self%count(k))
      r_min = max(r_space, r_time, r_mass)
      if (self%radius(k) >= r_min) cycle
      if (r_min == r_space) then
        d = diag
        if (n_gas > 0) d = min(diag, flights*self%lx*self%ly/(2.0_dp*sqrt(2.0_dp)*n_gas* &
             self%radius(k)))
        why = 'a contact computed from states D = '//real_str(d)//' L apart (the box '// &
             'diagonal, or 30 mean free paths in a gas) is misplaced by eps (D/(2 r))^2 of '// &
             'r_i + r_j (eps = 2.2e-16), which must stay <= tol'
        fix = 'a smaller box, or a larger guard_tol'
      else if (r_min == r_time) then
        why = 'a disk moves v eps t_end in one rounding of the clock at t_end = '// &
             real_str(self%t_end)//' tau (v = '//why//'), which must stay <= tol r'
        fix = 'a shorter t_end, a lower kt or a larger density'
      else
        why = 'the mass density pi r^'//trim(merge('1', '2', p == 1.0_dp))//' must be >= '// &
             '1e-150 M'
        fix = 'a larger density'
      end if
      empty = ''
      if (r_min > rmax_box) empty = ' (empty: '//fix//')'
      call set_error(st, exit_bad_input, trim(path)//': &disks '//name//' = '// &
           real_str(self%radius(k))//': allowed ['//real_str(r_min)//', '//real_str(rmax_box)// &
           '] L here'//empty//': below '//real_str(r_min)//', '//why// &
           ' (tol = max(&run guard_tol, 1e-9) = '//real_str(tol)//')')
      return
    end do
    rmax = max(maxval(self%radius(1:ns), mask=self%count(1:ns) > 0), self%seed_radius)
    cells = (self%lx/(2.0_dp*rmax))*(self%ly/(2.0_dp*rmax))
    if (cells > max_cells) call set_error(st, exit_bad_input, trim(path)//': &disks radius = '// &
         real_str(rmax)//' (the largest): allowed >= '// &
         real_str(0.5_dp*sqrt(self%lx*self%ly/max_cells))//' L here: the cell grid of side '// &
         '>= the largest diameter would hold '//real_str(cells)//' cells, at most 2^26')
  end subroutine validate_radii

  !> With sticking on, some species with disks must stick (carriers alone grow nothing: a gas
  !> is sticking = .false.).
  subroutine validate_sticky(self, path, st)
    class(dla_t), intent(in) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: ns
    if (st%code /= 0 .or. .not. self%sticking) return
    ns = int(self%n_species)
    if (any(self%sticky(1:ns) .and. self%count(1:ns) > 0)) return
    call set_error(st, exit_bad_input, trim(path)//': &disks sticky: no species with disks '// &
         'sticks (sticky = .false. for every species with count > 0) while &aggregate '// &
         'sticking = .true.: make one species sticky, or set sticking = .false. for a gas')
  end subroutine validate_sticky

  !> placement = 'explicit': at most max_explicit disks, inside the box, no overlap (contact
  !> allowed), finite velocities.
  subroutine validate_explicit(self, path, st)
    class(dla_t), intent(in) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: r(max_explicit + 1), x(max_explicit + 1), y(max_explicit + 1)
    integer :: n, i, j, k, i0
    character(len=8) :: is
    n = int(sum(self%count(1:self%n_species)))
    call check_int(path, 'disks', 'count (sum, placement = ''explicit'')', int(n, i8), 1_i8, &
         int(max_explicit, i8), st)
    if (st%code /= 0) return
    i0 = 0
    do k = 1, int(self%n_species)
      r(i0 + 1:i0 + self%count(k)) = self%radius(k)
      i0 = i0 + int(self%count(k))
    end do
    do i = 1, n
      write(is, '(a,i0,a)') '(', i, ')'
      call check_real(path, 'disks', 'x0'//trim(is), self%x0(i), r(i), self%lx - r(i), .true., st)
      call check_real(path, 'disks', 'y0'//trim(is), self%y0(i), r(i), self%ly - r(i), .true., st)
      call check_real(path, 'disks', 'vx0'//trim(is), self%vx0(i), -1.0e12_dp, 1.0e12_dp, .true., &
           st)
      call check_real(path, 'disks', 'vy0'//trim(is), self%vy0(i), -1.0e12_dp, 1.0e12_dp, .true., &
           st)
    end do
    if (st%code /= 0) return
    x(1:n) = self%x0(1:n); y(1:n) = self%y0(1:n)
    if (self%seed_radius > 0) then
      n = n + 1
      x(n) = self%seed_x; y(n) = self%seed_y; r(n) = self%seed_radius
    end if
    do i = 1, n
      do j = i + 1, n
        if ((x(i) - x(j))**2 + (y(i) - y(j))**2 < (r(i) + r(j))**2*(1.0_dp - 1.0e-12_dp)) then
          k = merge(i, j, j == n .and. self%seed_radius > 0)
          write(is, '(i0)') k
          call set_error(st, exit_bad_input, trim(path)//': &disks x0('//trim(is)//'), y0('// &
               trim(is)//'): disk '//trim(is)//' overlaps '//merge('the seed disk      ', &
               'disk '//int_str(int(i, i8))//repeat(' ', 14 - len(int_str(int(i, i8)))), &
               k == i)//': allowed distances >= r_i + r_j')
          return
        end if
      end do
    end do
  end subroutine validate_explicit

  !> Disk 1 is the seed (static, at seed_x, seed_y) when seed_radius > 0; the
  !> free disks follow, species by species for 'lattice' and 'explicit'; random
  !> placements are renumbered in cell order (memory locality).
  subroutine initial_state(self, st)
    class(dla_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    real(dp), allocatable :: r(:), m(:)
    logical, allocatable :: sticky(:)
    integer :: n, k, first, i0
    type(rng_t) :: g
    first = merge(2, 1, self%seed_radius > 0)
    n = int(sum(self%count(1:self%n_species))) + first - 1
    allocate(r(n), m(n), sticky(n))
    if (first == 2) then
      r(1) = self%seed_radius
      m(1) = 0
      sticky(1) = .true.
    end if
    i0 = first
    do k = 1, int(self%n_species)
      r(i0:i0 + self%count(k) - 1) = self%radius(k)
      sticky(i0:i0 + self%count(k) - 1) = self%sticky(k)
      if (self%mass_rule == 'perimeter') then
        m(i0:i0 + self%count(k) - 1) = self%density(k)*pi*self%radius(k)
      else
        m(i0:i0 + self%count(k) - 1) = self%density(k)*pi*self%radius(k)**2
      end if
      i0 = i0 + int(self%count(k))
    end do
    call ed_setup(self%s, self%lx, self%ly, r, m, trim(self%calendar), self%sticking, &
         self%last_bounces, self%log_events, sticky)
    self%s%guard_tol = self%guard_tol
    if (first == 2) then
      self%s%state(1) = state_seed
      call ed_put(self%s, 1, self%seed_x, self%seed_y)
    end if
    g%s = self%seed
    if (self%placement == 'lattice') then
      call ed_place_lattice(self%s, first, st)
    else if (self%placement == 'explicit') then
      do i0 = first, n
        call ed_put(self%s, i0, self%x0(i0 - first + 1), self%y0(i0 - first + 1))
      end do
    else
      call ed_place_random(self%s, g, first, st)
      if (st%code == 0) call ed_sort_by_cell(self%s, first)
    end if
    if (st%code /= 0) return
    if (self%placement == 'explicit') then
      self%s%d(first:)%vx = self%vx0(1:n - first + 1)
      self%s%d(first:)%vy = self%vy0(1:n - first + 1)
    else
      call ed_velocities(self%s, g, trim(self%velocities), self%kt)
    end if
    call ed_start(self%s)
    self%step = 0
    self%t_hist = 0
    self%n_members = 0
  end subroutine initial_state

  !> The outputs (method_t's default), then on a fresh start the seed's aggregate row.
  subroutine open_outputs(self, dir, append, st)
    class(dla_t), intent(inout) :: self
    character(len=*), intent(in) :: dir
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    call open_default(self, dir, append, st)
    if (st%code /= 0 .or. append) return
    if (self%sticking .and. self%s%state(1) == state_seed) then
      call member_row(self, 1, st)
    end if
  end subroutine open_outputs

  !> One frame at time t [tau] (positions interpolated exactly between events).
  subroutine frame_rows(self, t, st)
    class(dla_t), intent(inout) :: self
    real(dp), intent(in) :: t
    type(status_t), intent(inout) :: st
    integer :: i
    real(dp), allocatable :: p(:, :), c(:)
    character(len=400) :: line
    allocate(p(2, self%s%n))
    do i = 1, self%s%n
      p(:, i) = ed_position(self%s, i, t)
    end do
    if (self%frames_bin > 0) then
      associate (o => self%out, b => self%frames_bin)
        call o%frame_begin(b, self%step, t, st)
        call o%frame_put(b, [(i, i = 1, self%s%n)], st)
        call o%frame_put(b, p(1, :), st)
        call o%frame_put(b, p(2, :), st)
        ! copies of the record components (a component section given to transfer reads whole
        ! records with gfortran 12)
        c = self%s%d%vx
        call o%frame_put(b, c, st)
        c = self%s%d%vy
        call o%frame_put(b, c, st)
        c = self%s%d%r
        call o%frame_put(b, c, st)
        call o%frame_put(b, self%s%m, st)
        call o%frame_put(b, self%s%state, st)
        call o%frame_end(b, st)
      end associate
    end if
    if (self%frames == 0) return
    do i = 1, self%s%n
      write(line, '(i0,1x,'//rfmt//',1x,i0,6(1x,'//rfmt//'),1x,i0)') &
           self%step, t, i, p(:, i), self%s%d(i)%vx, self%s%d(i)%vy, self%s%d(i)%r, self%s%m(i), &
           self%s%state(i)
      call self%out%line(self%frames, trim(line), st)
    end do
  end subroutine frame_rows

  subroutine member_row(self, i, st)
    class(dla_t), intent(inout) :: self
    integer, intent(in) :: i
    type(status_t), intent(inout) :: st
    character(len=300) :: line
    write(line, '(i0,1x,i0,4(1x,'//rfmt//'),1x,i0,1x,i0,2(1x,'//rfmt//'))') &
         self%n_members, i, self%s%d(i)%x, self%s%d(i)%y, self%s%d(i)%r, self%s%t_stick(i), &
         self%s%ev_stuck(i), self%s%parent(i), self%s%v_hit(:, i)
    call self%out%line(self%aggregate, trim(line), st)
    self%n_members = self%n_members + 1
  end subroutine member_row

  !> Rows of the events of the last tick (aggregate members, event log).
  subroutine event_rows(self, st)
    class(dla_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    integer :: k
    character(len=200) :: line
    if (self%writing .and. self%sticking) then
      do k = 1, self%s%n_new
        call member_row(self, self%s%new_stuck(k), st)
      end do
    end if
    self%s%n_new = 0
    if (self%writing .and. self%log_events) then
      do k = 1, self%s%n_log
        write(line, '(i0,1x,'//rfmt//',3(1x,i0))') &
             self%s%log_no(k), self%s%log_t(k), self%s%log_kind(k), self%s%log_i(k), &
             self%s%log_j(k)
        call self%out%line(self%events, trim(line), st)
      end do
    end if
    self%s%n_log = 0
  end subroutine event_rows

  !> Guard and rows due at the current tick (every `every` ticks, and at the last).
  subroutine write_rows(self, last, st)
    class(dla_t), intent(inout) :: self
    logical, intent(in) :: last
    type(status_t), intent(inout) :: st
    real(dp) :: t, dt, area, pv, pw, ek, mom(2)
    character(len=400) :: line
    t = real(self%step, dp)*self%tick
    if (due(self%check_every, self%step, last)) call ed_check_overlaps(self%s, t, st)
    if (st%code /= 0 .or. .not. self%writing) return
    if (due(self%frame_every, self%step, last)) call frame_rows(self, t, st)
    if (due(self%history_every, self%step, last)) then
      dt = t - self%t_hist
      area = self%lx*self%ly
      ek = ed_kinetic(self%s)
      mom = ed_momentum(self%s)
      pv = 0
      pw = 0
      if (dt > 0) then
        pv = (ek + self%s%virial/(2.0_dp*dt))/area
        pw = self%s%wall_impulse/dt          ! each hit over the perimeter its centre reaches
      end if
      write(line, '(i0,1x,'//rfmt//',7(1x,i0),5(1x,'//rfmt//'),1x,i0)') &
           self%step, t, self%s%n_events, self%s%n_pair, self%s%n_wall, &
           self%s%n_stick, self%s%n_bounce, self%s%n_cross, self%s%n_free, ek, mom, pv, pw, &
           self%s%n_free_sticky
      call self%out%line(self%history, trim(line), st)
      self%s%virial = 0
      self%s%wall_impulse = 0
      self%t_hist = t
    end if
  end subroutine write_rows

  subroutine advance(self, st)
    class(dla_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    real(dp) :: c0, c1
    call write_rows(self, .false., st)
    if (st%code /= 0) return
    call cpu_time(c0)
    call ed_run_until(self%s, real(self%step + 1, dp)*self%tick, st)
    call cpu_time(c1)
    self%seconds = self%seconds + (c1 - c0)
    call event_rows(self, st)
    if (st%code /= 0) return
    self%step = self%step + 1
    if (self%stop_when_done .and. self%sticking .and. .not. self%last_bounces .and. &
         self%s%n_free_sticky == 0) self%n_steps = self%step     ! every sticky disk is stuck
  end subroutine advance

  subroutine finish(self, st)
    class(dla_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call write_rows(self, .true., st)
  end subroutine finish

  !> Payload: the stored disk states (positions at their own last-event times),
  !> counters, aggregate and accumulators; the calendar is rebuilt on restore
  !> (predictions are pure functions of the stored states: same event order).
  subroutine save_state(self, w)
    class(dla_t), intent(in) :: self
    type(ckpt_writer_t), intent(inout) :: w
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    real(dp), allocatable :: xy(:, :), tl(:)     ! heap, not stack: N up to 1e7
    integer(i8), allocatable :: coll(:)
    integer, allocatable :: cell(:)
    associate (s => self%s)
      call ckpt_put(w, [transfer(s%n, b), transfer(self%step, b), transfer(self%n_steps, b), &
           transfer(self%t_hist, b), transfer(self%n_members, b), transfer(s%t, b), &
           transfer(s%n_events, b), transfer(s%n_pair, b), transfer(s%n_wall, b), &
           transfer(s%n_stick, b), transfer(s%n_bounce, b), transfer(s%n_cross, b), &
           transfer(s%n_stale, b), transfer(s%virial, b), transfer(s%wall_impulse, b)])
      ! copies: transfer of a component section (s%d%tl) reads the whole records (gfortran 12)
      xy = pairs(s%d%x, s%d%y)
      call ckpt_put(w, transfer(xy, b))
      xy = pairs(s%d%vx, s%d%vy)
      call ckpt_put(w, transfer(xy, b))
      tl = s%d%tl
      call ckpt_put(w, transfer(tl, b)); call ckpt_put(w, transfer(s%state, b))
      coll = s%d%coll
      cell = ed_cells(s)
      call ckpt_put(w, transfer(coll, b)); call ckpt_put(w, transfer(cell, b))
      call ckpt_put(w, transfer(s%parent, b)); call ckpt_put(w, transfer(s%t_stick, b))
      call ckpt_put(w, transfer(s%ev_stuck, b))
    end associate
  end subroutine save_state

  !> The (2, n) array of (a(i), b(i)) (the checkpoint's layout of positions and velocities).
  pure function pairs(a, b) result(ab)
    real(dp), intent(in) :: a(:), b(:)
    real(dp) :: ab(2, size(a))
    ab(1, :) = a
    ab(2, :) = b
  end function pairs

  subroutine restore_state(self, u, st)
    class(dla_t), intent(inout) :: self
    integer, intent(in) :: u
    type(status_t), intent(inout) :: st
    integer :: ios, n
    real(dp), allocatable :: x(:, :), v(:, :), tl(:)
    integer(i8), allocatable :: coll(:)
    integer, allocatable :: cell(:)
    read(u, iostat=ios) n
    if (ios == 0 .and. n /= self%s%n) ios = 1
    if (ios == 0) allocate(x(2, n), v(2, n), tl(n), coll(n), cell(n))
    associate (s => self%s)
      if (ios == 0) read(u, iostat=ios) self%step, self%n_steps, self%t_hist, self%n_members, &
           s%t, s%n_events, s%n_pair, s%n_wall, s%n_stick, s%n_bounce, s%n_cross, s%n_stale, &
           s%virial, s%wall_impulse, x, v, tl, s%state, coll, cell, s%parent, &
           s%t_stick, s%ev_stuck
      if (ios == 0 .and. (self%step < 0 .or. self%step > self%n_steps)) ios = 1
      if (ios == 0) then
        if (.not. ed_load_cells(s, cell)) ios = 1
      end if
      if (ios /= 0) then
        call set_error(st, exit_io, 'checkpoint payload does not match the scene')
        return
      end if
      s%d%x = x(1, :); s%d%y = x(2, :)
      s%d%vx = v(1, :); s%d%vy = v(2, :)
      s%d%tl = tl
      s%d%coll = coll
      s%n_new = 0
      s%n_log = 0
      call ed_start(s)
    end associate
  end subroutine restore_state

  function progress_text(self) result(s)
    class(dla_t), intent(in) :: self
    character(len=:), allocatable :: s
    if (self%sticking) then
      s = 'grow '//int_str(int(self%s%n_free_sticky, i8))
    else
      s = 'gas '//int_str(self%s%n_events)
    end if
  end function progress_text

  function json_fields(self) result(text)
    class(dla_t), intent(in) :: self
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = achar(10)
    text = '  "n_disks": '//int_str(int(self%s%n, i8))//','//nl// &
         '  "n_free": '//int_str(int(self%s%n_free, i8))//','//nl// &
         '  "n_free_sticky": '//int_str(int(self%s%n_free_sticky, i8))//','//nl// &
         '  "n_members": '//int_str(int(self%n_members, i8))//','//nl// &
         '  "events": '//int_str(int(self%s%n_events, i8))//','//nl// &
         '  "events_pair": '//int_str(int(self%s%n_pair, i8))//','//nl// &
         '  "events_wall": '//int_str(int(self%s%n_wall, i8))//','//nl// &
         '  "events_stick": '//int_str(int(self%s%n_stick, i8))//','//nl// &
         '  "events_bounce": '//int_str(int(self%s%n_bounce, i8))//','//nl// &
         '  "cell_crossings": '//int_str(int(self%s%n_cross, i8))//','//nl// &
         '  "stale_predictions": '//int_str(int(self%s%n_stale, i8))//','//nl// &
         '  "cells": ['//int_str(int(self%s%ncx, i8))//', '//int_str(int(self%s%ncy, i8))// &
         '],'//nl// &
         '  "event_loop_cpu_seconds": '//real_str(self%seconds)//','//nl// &
         '  "units": {"length": "L", "mass": "M", "energy": "E", "time": "tau = L sqrt(M/E)"},'//nl
  end function json_fields

end module edmd_dla
