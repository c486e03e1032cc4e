!> Kind 'dla': hard disks in a closed box, event-driven (module edmd_core),
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
  use errors, only: status_t, set_error, exit_bad_input, exit_io, msg_len
  use method, only: method_t, fname_len, max_out_files, add_output
  use tables, only: table_t, table_open, table_line, table_flush, table_close, rfmt
  use frames, only: frames_t, frames_open, frames_begin, frames_put, frames_end, frames_flush, &
       frames_close, json_real
  use ckpt, only: ckpt_writer_t, ckpt_put
  use, intrinsic :: iso_fortran_env, only: int8
  use scene_input, only: open_scene, group_status, kind_len, check_real, check_int, check_choice, put_real, put_int, &
       put_str, put_logical, int_str, real_str
  use edmd_core, only: ed_t, ed_setup, ed_place_random, ed_place_lattice, ed_velocities, &
       ed_start, ed_run_until, ed_position, ed_kinetic, ed_momentum, ed_check_overlaps, &
       ed_put, ed_sort_by_cell, ed_cells, ed_load_cells, rng_t, state_free, state_seed
  implicit none
  private

  public :: dla_t

  integer, parameter :: name_len = 32, max_species = 4
  integer, parameter :: max_explicit = 16          !< disks of placement = 'explicit'
  integer(i8), parameter :: max_ticks = 1000000000000_i8

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
    ! state
    type(ed_t) :: s
    integer(i8) :: step = 0                           !< ticks done
    integer(i8) :: n_ticks = 0
    real(dp) :: t_hist = 0                            !< time of the last history row [tau]
    integer :: n_members = 0                          !< aggregate rows written
    real(dp) :: seconds = 0                           !< CPU time in the event loop [s] (not state)
    type(table_t) :: frames, history, aggregate, events
    type(frames_t) :: frames_bin
  contains
    procedure :: load, read => read_file, scene_text, open_outputs, advance, finish, close_outputs, output_files
    procedure :: save_state, restore_state, counters, progress_text, json_fields
  end type dla_t

  !> columns of frames.dat and frames.bin after tick and t
  character(len=*), parameter :: frame_cols(8) = [character(len=5) :: 'id', 'x', 'y', 'vx', &
       'vy', 'r', 'm', 'state']
  character(len=*), parameter :: frame_units(8) = [character(len=5) :: '', 'L', 'L', 'L/tau', &
       'L/tau', 'L', 'M', '1']
  character(len=*), parameter :: units = 'Units: length L (box unit), mass M, energy E (kT), '// &
       'time tau = L sqrt(M/E).'

contains

  !> Read (read_file), validate, build the initial state.
  subroutine load(self, path, st)
    class(dla_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    call self%read(path, st)
    if (st%code /= 0) return
    if (self%seed_x < 0) self%seed_x = 0.5_dp*self%lx   ! < 0: the box centre
    if (self%seed_y < 0) self%seed_y = 0.5_dp*self%ly
    call validate(self, path, st)
    if (st%code /= 0) return
    self%n_ticks = nint(self%t_end/self%tick, i8)
    call initial_state(self, st)
  end subroutine load

  !> The scene file's groups (absent groups keep their defaults; no range checks).
  subroutine read_file(self, path, st)
    class(dla_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    character(len=kind_len) :: kind
    character(len=128) :: title
    real(dp) :: lx, ly, radius(max_species), density(max_species), kt, seed_radius, seed_x, &
         seed_y, tick, t_end, guard_tol, x0(max_explicit), y0(max_explicit), &
         vx0(max_explicit), vy0(max_explicit)
    integer(i8) :: n_species, count(max_species), seed, frame_every, history_every, check_every, &
         checkpoint_every
    character(len=name_len) :: mass_rule, velocities, placement, calendar, frames_format
    logical :: sticking, last_bounces, stop_when_done, log_events, sticky(max_species)
    integer :: u, ios
    character(len=msg_len) :: iom
    namelist /scene/ kind, title
    namelist /box/ lx, ly
    namelist /disks/ n_species, count, radius, density, mass_rule, sticky, kt, velocities, &
         placement, seed, x0, y0, vx0, vy0
    namelist /aggregate/ sticking, seed_radius, seed_x, seed_y, last_bounces, stop_when_done
    namelist /run/ calendar, tick, t_end, guard_tol
    namelist /output/ frame_every, history_every, check_every, checkpoint_every, log_events, &
         frames_format
    kind = self%kind; title = self%title; lx = self%lx; ly = self%ly
    n_species = self%n_species; count = self%count; radius = self%radius
    density = self%density; mass_rule = self%mass_rule; sticky = self%sticky; kt = self%kt
    velocities = self%velocities; placement = self%placement; seed = self%seed
    x0 = self%x0; y0 = self%y0; vx0 = self%vx0; vy0 = self%vy0
    sticking = self%sticking; seed_radius = self%seed_radius; seed_x = self%seed_x
    seed_y = self%seed_y; last_bounces = self%last_bounces; stop_when_done = self%stop_when_done
    calendar = self%calendar; tick = self%tick; t_end = self%t_end; guard_tol = self%guard_tol
    frame_every = self%frame_every; history_every = self%history_every
    check_every = self%check_every; checkpoint_every = self%checkpoint_every
    log_events = self%log_events; frames_format = self%frames_format
    call open_scene(path, u, st)
    if (st%code /= 0) return
    read(u, nml=scene, iostat=ios, iomsg=iom)
    call group_status(path, 'scene', ios, iom, .false., st)
    rewind(u); read(u, nml=box, iostat=ios, iomsg=iom)
    call group_status(path, 'box', ios, iom, .false., st)
    rewind(u); read(u, nml=disks, iostat=ios, iomsg=iom)
    call group_status(path, 'disks', ios, iom, .false., st)
    rewind(u); read(u, nml=aggregate, iostat=ios, iomsg=iom)
    call group_status(path, 'aggregate', ios, iom, .false., st)
    rewind(u); read(u, nml=run, iostat=ios, iomsg=iom)
    call group_status(path, 'run', ios, iom, .false., st)
    rewind(u); read(u, nml=output, iostat=ios, iomsg=iom)
    call group_status(path, 'output', ios, iom, .false., st)
    close(u)
    if (st%code /= 0) return
    self%kind = kind; self%title = title; self%lx = lx; self%ly = ly
    self%n_species = n_species; self%count = count; self%radius = radius
    self%density = density; self%mass_rule = mass_rule; self%sticky = sticky; self%kt = kt
    self%velocities = velocities; self%placement = placement; self%seed = seed
    self%x0 = x0; self%y0 = y0; self%vx0 = vx0; self%vy0 = vy0
    self%sticking = sticking; self%seed_radius = seed_radius; self%seed_x = seed_x
    self%seed_y = seed_y; self%last_bounces = last_bounces; self%stop_when_done = stop_when_done
    self%calendar = calendar; self%tick = tick; self%t_end = t_end; self%guard_tol = guard_tol
    self%frame_every = frame_every; self%history_every = history_every
    self%check_every = check_every; self%checkpoint_every = checkpoint_every
    self%log_events = log_events; self%frames_format = frames_format
  end subroutine read_file

  subroutine validate(self, path, st)
    class(dla_t), intent(in) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: k
    real(dp) :: rmax_box, eta
    character(len=3) :: ks
    call check_choice(path, 'scene', 'kind', self%kind, ['dla'], st)
    call check_real(path, 'box', 'lx', self%lx, 0.0_dp, 1.0e9_dp, .false., st)
    call check_real(path, 'box', 'ly', self%ly, 0.0_dp, 1.0e9_dp, .false., st)
    call check_int(path, 'disks', 'n_species', self%n_species, 1_i8, int(max_species, i8), st)
    if (st%code /= 0) return
    rmax_box = 0.5_dp*min(self%lx, self%ly)
    do k = 1, int(self%n_species)
      write(ks, '(a,i0,a)') '(', k, ')'
      call check_int(path, 'disks', 'count'//trim(ks), self%count(k), 0_i8, 10000000_i8, st)
      call check_real(path, 'disks', 'radius'//trim(ks), self%radius(k), 0.0_dp, rmax_box, &
           .false., st)
      call check_real(path, 'disks', 'density'//trim(ks), self%density(k), 0.0_dp, 1.0e12_dp, &
           .false., st)
    end do
    if (st%code /= 0) return
    call check_int(path, 'disks', 'count (sum over species)', &
         sum(self%count(1:self%n_species)), 1_i8, 10000000_i8, st)
    call check_choice(path, 'disks', 'mass_rule', self%mass_rule, [character(len=name_len) :: &
         'area', 'perimeter'], st)
    call validate_sticky(self, path, st)
    call check_real(path, 'disks', 'kt', self%kt, 0.0_dp, 1.0e12_dp, .false., st)
    call check_choice(path, 'disks', 'velocities', self%velocities, [character(len=name_len) :: &
         'fixed_speed', 'maxwell'], st)
    call check_choice(path, 'disks', 'placement', self%placement, [character(len=name_len) :: &
         'random', 'lattice', 'explicit'], st)
    call check_int(path, 'disks', 'seed', self%seed, 0_i8, huge(1_i8), st)
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
    eta = (sum(pi*self%radius(1:self%n_species)**2*real(self%count(1:self%n_species), dp)) + &
         pi*self%seed_radius**2)/(self%lx*self%ly)
    if (eta > 0.9_dp) call set_error(st, exit_bad_input, trim(path)//': &disks count = '// &
         int_str(sum(self%count(1:self%n_species)))//': packing fraction '//real_str(eta)// &
         ' of the box: allowed < 0.9 (close packing of disks: 0.9069)')
    call check_choice(path, 'run', 'calendar', self%calendar, [character(len=name_len) :: &
         'buckets', 'heap', 'rescan'], st)
    call check_real(path, 'run', 't_end', self%t_end, 0.0_dp, 1.0e12_dp, .false., st)
    if (st%code /= 0) return
    call check_real(path, 'run', 'tick', self%tick, self%t_end/real(max_ticks, dp), self%t_end, &
         .true., st)
    call check_real(path, 'run', 'guard_tol', self%guard_tol, 0.0_dp, 1.0e-3_dp, .false., st)
    call check_int(path, 'output', 'frame_every', self%frame_every, 0_i8, max_ticks, st)
    call check_int(path, 'output', 'history_every', self%history_every, 0_i8, max_ticks, st)
    call check_int(path, 'output', 'check_every', self%check_every, 0_i8, max_ticks, st)
    call check_int(path, 'output', 'checkpoint_every', self%checkpoint_every, 0_i8, max_ticks, st)
    call check_choice(path, 'output', 'frames_format', self%frames_format, &
         [character(len=name_len) :: 'text', 'binary', 'both'], st)
  end subroutine validate

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

  function scene_text(self) result(text)
    class(dla_t), intent(in) :: self
    character(len=:), allocatable :: text
    integer :: k
    character(len=4) :: ks
    text = ''
    text = text//'! resolved scene: kind dla (every key). '//units//achar(10)
    text = text//'&scene'//achar(10)
    call put_str(text, 'kind', self%kind, '')
    call put_str(text, 'title', self%title, '')
    text = text//'/'//achar(10)
    text = text//'&box'//achar(10)
    call put_real(text, 'lx', self%lx, 'L')
    call put_real(text, 'ly', self%ly, 'L')
    text = text//'/'//achar(10)
    text = text//'&disks'//achar(10)
    call put_int(text, 'n_species', self%n_species, '')
    do k = 1, max_species
      write(ks, '(a,i0,a)') '(', k, ')'
      call put_int(text, 'count'//trim(ks), self%count(k), 'free disks')
      call put_real(text, 'radius'//trim(ks), self%radius(k), 'L')
      call put_real(text, 'density'//trim(ks), self%density(k), &
           merge('M/L^2', 'M/L  ', self%mass_rule == 'area'))
      call put_logical(text, 'sticky'//trim(ks), self%sticky(k), &
           'sticks to the aggregate (.false.: a carrier, bounces off it)')
    end do
    call put_str(text, 'mass_rule', self%mass_rule, 'area: m = density pi r^2; perimeter: '// &
         'm = density pi r (the seed''s)')
    call put_real(text, 'kt', self%kt, 'E')
    call put_str(text, 'velocities', self%velocities, '')
    call put_str(text, 'placement', self%placement, '')
    do k = 1, max_explicit      ! every key, also when placement is not 'explicit'
      write(ks, '(a,i0,a)') '(', k, ')'
      call put_real(text, 'x0'//trim(ks), self%x0(k), 'L (placement = explicit)')
      call put_real(text, 'y0'//trim(ks), self%y0(k), 'L')
      call put_real(text, 'vx0'//trim(ks), self%vx0(k), 'L/tau')
      call put_real(text, 'vy0'//trim(ks), self%vy0(k), 'L/tau')
    end do
    call put_int(text, 'seed', self%seed, 'RNG of the initial state')
    text = text//'/'//achar(10)
    text = text//'&aggregate'//achar(10)
    call put_logical(text, 'sticking', self%sticking, '')
    call put_real(text, 'seed_radius', self%seed_radius, 'L (0 = no seed disk)')
    call put_real(text, 'seed_x', self%seed_x, 'L')
    call put_real(text, 'seed_y', self%seed_y, 'L')
    call put_logical(text, 'last_bounces', self%last_bounces, &
         'the last free sticky disk bounces')
    call put_logical(text, 'stop_when_done', self%stop_when_done, &
         'end when every sticky disk is stuck')
    text = text//'/'//achar(10)
    text = text//'&run'//achar(10)
    call put_str(text, 'calendar', self%calendar, 'buckets: O(1); heap: O(log N); rescan: '// &
         'the seed''s O(N^2); same events')
    call put_real(text, 'tick', self%tick, 'tau (unit of work)')
    call put_real(text, 't_end', self%t_end, 'tau')
    call put_real(text, 'guard_tol', self%guard_tol, 'overlap allowed / (r_i + r_j)')
    text = text//'/'//achar(10)
    text = text//'&output'//achar(10)
    call put_int(text, 'frame_every', self%frame_every, 'ticks (0 = off)')
    call put_int(text, 'history_every', self%history_every, 'ticks (0 = off)')
    call put_int(text, 'check_every', self%check_every, 'ticks: all-pairs overlap guard (0 = off)')
    call put_int(text, 'checkpoint_every', self%checkpoint_every, 'ticks (0 = none)')
    call put_logical(text, 'log_events', self%log_events, 'events.dat (small systems)')
    call put_str(text, 'frames_format', self%frames_format, &
         'text: frames.dat, binary: frames.bin, both')
    text = text//'/'//achar(10)
  end function scene_text

  subroutine open_outputs(self, dir, append, st)
    class(dla_t), intent(inout) :: self
    character(len=*), intent(in) :: dir
    logical, intent(in) :: append
    type(status_t), intent(inout) :: st
    if (binary_frames(self)) call frames_open(self%frames_bin, trim(dir)//'/frames.bin', &
         self%s%n, frame_cols, frame_units, ['i4', 'f8', 'f8', 'f8', 'f8', 'f8', 'f8', 'i4'], &
         'tick', 'tau', '"kind": "dla", "box": ['//json_real(self%lx)//', '// &
         json_real(self%ly)//']', append, st)
    if (text_frames(self)) call table_open(self%frames, dir, 'frames.dat', &
         '# frames.dat: disks at fixed times (exact interpolation between events); state 0 '// &
         'free, 1 stuck, 2 seed; m = 0 for the seed (static). '//units, &
         '# tick t[tau] id x[L] y[L] vx[L/tau] vy[L/tau] r[L] m[M] state[1]', append, st)
    if (self%history_every > 0) call table_open(self%history, dir, 'history.dat', &
         '# history.dat: cumulative event counts, free disks (all; free_sticky: those of '// &
         'sticky species), kinetic energy, momentum of the '// &
         'free disks; pressures over the interval since the previous row (0 on the first): '// &
         'P_virial = (E_kin + sum r_ij.dp_i / (2 dt)) / A, P_wall = sum of each wall hit''s '// &
         '|dp| / (2 (lx + ly - 4 r_i) dt) (the perimeter its centre reaches). '//units, &
         '# tick t[tau] events[1] pair[1] wall[1] stick[1] bounce[1] cross[1] free[1] '// &
         'E_kin[E] px[M*L/tau] py[M*L/tau] P_virial[E/L^2] P_wall[E/L^2] free_sticky[1]', &
         append, st)
    if (self%sticking) call table_open(self%aggregate, dir, 'aggregate.dat', &
         '# aggregate.dat: members in the order they stuck (member 0 = seed); parent = the '// &
         'disk id it stuck to (a tree); event = physical event number; vx, vy = its velocity '// &
         'when it stuck (0 for the seed). '//units, &
         '# member[1] id[1] x[L] y[L] r[L] t_stick[tau] event[1] parent[1] vx[L/tau] '// &
         'vy[L/tau]', append, st)
    if (self%log_events) call table_open(self%events, dir, 'events.dat', &
         '# events.dat: every physical event; type 1 pair, 2 wall (j = -wall: 1 x-, 2 x+, '// &
         '3 y-, 4 y+), 4 stick, 5 bounce off the aggregate. '//units, &
         '# event[1] t[tau] type[1] i[1] j[1]', append, st)
    self%writing = st%code == 0
    if (st%code /= 0 .or. append) return
    if (self%sticking .and. self%s%state(1) == state_seed) then
      call member_row(self, 1, st)
    end if
  end subroutine open_outputs

  subroutine output_files(self, names, n)
    class(dla_t), intent(in) :: self
    character(len=fname_len), intent(out) :: names(max_out_files)
    integer, intent(out) :: n
    n = 0
    names = ''
    call add_output(names, n, text_frames(self), 'frames.dat')
    call add_output(names, n, self%history_every > 0, 'history.dat')
    call add_output(names, n, self%sticking, 'aggregate.dat')
    call add_output(names, n, self%log_events, 'events.dat')
    call add_output(names, n, binary_frames(self), 'frames.bin')
  end subroutine output_files

  !> Frames as text (frames.dat) / binary (frames.bin): &output frames_format.
  logical function text_frames(self)
    class(dla_t), intent(in) :: self
    text_frames = self%frame_every > 0 .and. trim(self%frames_format) /= 'binary'
  end function text_frames

  logical function binary_frames(self)
    class(dla_t), intent(in) :: self
    binary_frames = self%frame_every > 0 .and. trim(self%frames_format) /= 'text'
  end function binary_frames

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
    if (binary_frames(self)) then
      call frames_begin(self%frames_bin, self%step, t, st)
      call frames_put(self%frames_bin, [(i, i = 1, self%s%n)], st)
      call frames_put(self%frames_bin, p(1, :), st)
      call frames_put(self%frames_bin, p(2, :), st)
      ! copies of the record components (a component section given to transfer reads whole
      ! records with gfortran 12)
      c = self%s%d%vx
      call frames_put(self%frames_bin, c, st)
      c = self%s%d%vy
      call frames_put(self%frames_bin, c, st)
      c = self%s%d%r
      call frames_put(self%frames_bin, c, st)
      call frames_put(self%frames_bin, self%s%m, st)
      call frames_put(self%frames_bin, self%s%state, st)
      call frames_end(self%frames_bin, st)
    end if
    if (.not. text_frames(self)) return
    do i = 1, self%s%n
      write(line, '(i0,1x,'//rfmt//',1x,i0,6(1x,'//rfmt//'),1x,i0)') &
           self%step, t, i, p(:, i), self%s%d(i)%vx, self%s%d(i)%vy, self%s%d(i)%r, self%s%m(i), &
           self%s%state(i)
      call table_line(self%frames, trim(line), st)
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
    call table_line(self%aggregate, trim(line), st)
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
        call table_line(self%events, trim(line), st)
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
    if (due(self%check_every)) call ed_check_overlaps(self%s, t, st)
    if (st%code /= 0 .or. .not. self%writing) return
    if (due(self%frame_every)) call frame_rows(self, t, st)
    if (due(self%history_every)) then
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
      call table_line(self%history, trim(line), st)
      self%s%virial = 0
      self%s%wall_impulse = 0
      self%t_hist = t
    end if
  contains
    logical function due(every)
      integer(i8), intent(in) :: every
      due = every > 0
      if (due) due = last .or. mod(self%step, every) == 0
    end function due
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
         self%s%n_free_sticky == 0) self%n_ticks = self%step     ! every sticky disk is stuck
  end subroutine advance

  subroutine finish(self, st)
    class(dla_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call write_rows(self, .true., st)
  end subroutine finish

  subroutine close_outputs(self, flush_only, st)
    class(dla_t), intent(inout) :: self
    logical, intent(in) :: flush_only
    type(status_t), intent(inout) :: st
    call table_flush(self%frames, st)
    call frames_flush(self%frames_bin, st)
    call table_flush(self%history, st)
    call table_flush(self%aggregate, st)
    call table_flush(self%events, st)
    if (flush_only) return
    call table_close(self%frames, st)
    call frames_close(self%frames_bin, st)
    call table_close(self%history, st)
    call table_close(self%aggregate, st)
    call table_close(self%events, st)
    self%writing = .false.
  end subroutine close_outputs

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
      call ckpt_put(w, [transfer(s%n, b), transfer(self%step, b), transfer(self%n_ticks, b), &
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
      if (ios == 0) read(u, iostat=ios) self%step, self%n_ticks, self%t_hist, self%n_members, &
           s%t, s%n_events, s%n_pair, s%n_wall, s%n_stick, s%n_bounce, s%n_cross, s%n_stale, &
           s%virial, s%wall_impulse, x, v, tl, s%state, coll, cell, s%parent, &
           s%t_stick, s%ev_stuck
      if (ios == 0 .and. (self%step < 0 .or. self%step > self%n_ticks)) ios = 1
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

  subroutine counters(self, done, total, t)
    class(dla_t), intent(in) :: self
    integer(i8), intent(out) :: done, total
    real(dp), intent(out) :: t
    done = self%step
    total = self%n_ticks
    t = real(self%step, dp)*self%tick
  end subroutine counters

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
