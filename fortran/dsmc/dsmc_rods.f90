!> Kind 'rods': space-homogeneous DSMC of rods of vanishing girth in the
!> plane (seed 001). N samples (v in R^2, theta, omega) of f(v, theta, omega, t)
!> advance by a first-order splitting per step dt:
!>   1. transport (module dsmc_mean_field): d theta/dt = omega,
!>      d omega/dt = V(theta, omega) by semi-implicit Euler;
!>   2. collisions (module dsmc_collisions), Nanbu-Babovsky: floor(N dt/(2 tau))
!>      disjoint pairs drawn without replacement collide by the rod law
!>      (needs dt <= tau: larger steps are refused).
!> f^{n+1} = Q_dt(T_dt(f^n)). Units: mass m (a sample's), length L (a rod's),
!> time t0 of the scene (tau and dt are in t0); energies m L^2/t0^2.
!> Random numbers: the initial samples from the intrinsic random_number seeded from
!> &rods seed; the collisions from a counter-based stream of the same seed (SplitMix64,
!> dsmc_rng.c), whose numbers are a function of (step, pair) only. The pair permutation is in
!> the checkpoint, so a resumed run is bit-identical to an uninterrupted one. OpenMP: the
!> transport, the pair kernel (pairs disjoint, each block draws its own numbers by counter) and
!> the Onsager kicks, so the samples are the same bits for any thread count.
module dsmc_rods
  use kinds, only: dp, i8, pi
  use errors, only: status_t, set_error, exit_bad_input, exit_io, exit_numerical
  use method, only: method_t
  use tables, only: rfmt
  use output_set, only: due
  use ckpt, only: ckpt_writer_t, ckpt_put
  use, intrinsic :: iso_fortran_env, only: int8
  use scene_input, only: kind_len, int_str, real_str
  use schema, only: schema_t, max_steps_all
  use memory, only: check_memory_need
  use dsmc_collisions, only: collision_t, pair_count, draw_pairs, collide_pairs, stream_key, &
       uniforms, numbers_per_pair
  use dsmc_mean_field, only: field_t, transport, interaction_energy
  use dsmc_moments, only: moments_t, sample_moments, h_estimate, histogram, wrap_angle
  implicit none
  private

  public :: rods_t

  integer, parameter :: nlen = 16
  real(dp), parameter :: runaway_bound = 1.0e100_dp   !< guard on sum |state| (see advance)

  type, extends(method_t) :: rods_t
    ! &scene
    character(len=kind_len) :: kind = 'rods'
    character(len=128) :: title = 'untitled'
    ! &rods
    integer(i8) :: n = 10000
    real(dp) :: m = 1.0_dp, length = 1.0_dp, inertia = 1.0_dp
    character(len=nlen) :: inertia_model = 'given'     !< given | thin_rod (I = m L^2/12)
    character(len=nlen) :: v_init = 'two_bumps'        !< two_bumps | maxwellian | bkw
    real(dp) :: v_shift = 1.0_dp, v_spread = 0.3_dp
    character(len=nlen) :: theta_init = 'uniform'      !< uniform | gaussian
    real(dp) :: theta0 = 0.0_dp, theta_spread = 0.0_dp
    real(dp) :: omega0 = 0.0_dp, omega_spread = 1.0_dp
    integer(i8) :: seed = 1
    real(dp) :: dt = 0.05_dp, t_end = 10.0_dp
    real(dp) :: target_rel_error = 0        !< read by pyorch (trade table), ignored here
    ! &collisions
    logical :: collisions = .true.
    real(dp) :: tau = 1.0_dp
    real(dp) :: e_v = 1.0_dp, e_w = 1.0_dp
    logical :: rotation = .true.
    ! &mean_field
    type(field_t) :: field
    ! &output
    integer(i8) :: history_every = 10, histogram_every = 0, samples_every = 0
    integer(i8) :: bins = 50, entropy_bins = 16
    real(dp) :: v_max = 4.0_dp, omega_max = 4.0_dp
    logical :: collision_audit = .false.
    integer(i8) :: fourier_modes = 16, onsager_bins = 512   !< as read (into field in load)
    ! state
    type(collision_t) :: law
    real(dp), allocatable :: v(:, :), theta(:), omega(:), u(:), de(:)
    integer(i8), allocatable :: perm(:)
    integer(i8) :: n_collisions = 0, nc = 0           !< (step, n_steps: method_t's)
    real(dp) :: e_lost = 0.0_dp        !< energy lost in collisions per sample (formula)
    real(dp) :: audit_de = 0.0_dp, audit_dp = 0.0_dp
    integer :: hist = 0, histo = 0, samp = 0          !< output ids (0: off)
  contains
    procedure :: keys, resolve, setup, advance, finish
    procedure :: rules => validate
    procedure :: save_state, restore_state, progress_text, json_fields
  end type rods_t

contains

  !> The scene of this kind, declared once (module schema): reading,
  !> validation, scene.nml and `partsim --describe rods` come from it.
  subroutine keys(self, s)
    class(rods_t), intent(inout), target :: self
    type(schema_t), intent(inout) :: s
    call s%init('rods', 'kind rods (space-homogeneous DSMC). Units: mass m, length L, '// &
         'time t0; energies m L^2/t0^2.')
    call s%scene_group(self%kind, self%title)
    call s%group('rods', 'the samples, their initial law and the step')
    call s%key('n', self%n, '', 'samples (rods)', lo=2_i8, hi=200000000_i8)
    call s%key('m', self%m, 'm', 'mass of a rod', lo=0.0_dp, lo_open=.true., hi=1.0e6_dp)
    call s%key('length', self%length, 'L', 'length of a rod', lo=0.0_dp, lo_open=.true., &
         hi=1.0e6_dp)
    call s%key('inertia_model', self%inertia_model, '', 'given: inertia as written; '// &
         'thin_rod: inertia = m length^2/12 (resolved)', choices='given|thin_rod')
    call s%key('inertia', self%inertia, 'm L^2', 'moment of inertia (resolved)', lo=0.0_dp, &
         lo_open=.true., hi=1.0e12_dp)
    call s%key('v_init', self%v_init, '', 'initial velocities: two bumps at (+-v_shift, 0), '// &
         'a Maxwellian around (v_shift, 0), or BKW', choices='two_bumps|maxwellian|bkw')
    call s%key('v_shift', self%v_shift, 'L/t0', 'centre of the velocity bumps', &
         lo=-1.0e6_dp, hi=1.0e6_dp)
    call s%key('v_spread', self%v_spread, 'L/t0', 'spread of each velocity component', &
         lo=0.0_dp, hi=1.0e6_dp)
    call s%key('theta_init', self%theta_init, '', 'initial angles: uniform or gaussian '// &
         '(theta0, theta_spread)', choices='uniform|gaussian')
    call s%key('theta0', self%theta0, 'rad', 'mean angle (gaussian)', lo=-1.0e3_dp, hi=1.0e3_dp)
    call s%key('theta_spread', self%theta_spread, 'rad', 'angle spread (gaussian)', lo=0.0_dp, &
         hi=1.0e3_dp)
    call s%key('omega0', self%omega0, 'rad/t0', 'mean angular velocity', lo=-1.0e6_dp, &
         hi=1.0e6_dp)
    call s%key('omega_spread', self%omega_spread, 'rad/t0', 'angular velocity spread', &
         lo=0.0_dp, hi=1.0e6_dp)
    call s%key('seed', self%seed, '', 'RNG seed', lo=1_i8, hi=2147483647_i8)
    call s%key('dt', self%dt, 't0', 'step (<= t_end, <= tau with collisions, at most 1e12 '// &
         'steps)', lo=0.0_dp, lo_open=.true., hi=1.0e9_dp)
    call s%key('t_end', self%t_end, 't0', 'run length', lo=0.0_dp, lo_open=.true., hi=1.0e9_dp)
    call s%key('target_rel_error', self%target_rel_error, '1', 'read by pyorch: the '// &
         'cheapest measured setting meeting it (0 = off; the engine ignores it)', lo=0.0_dp, &
         hi=1.0_dp)
    call s%group('collisions', 'Nanbu-Babovsky collisions by the rod law')
    call s%key('enabled', self%collisions, '', 'collisions on')
    call s%key('tau', self%tau, 't0', 'mean time between collisions of a sample', lo=0.0_dp, &
         lo_open=.true., hi=1.0e12_dp)
    call s%key('e_v', self%e_v, '1', 'translational restitution', lo=0.0_dp, hi=1.0_dp)
    call s%key('e_w', self%e_w, '1', 'rotational restitution', lo=0.0_dp, hi=1.0_dp)
    call s%key('rotation', self%rotation, '', '.false.: point particles (omega = 0)')
    call s%group('mean_field', 'the potential of the transport step')
    call s%key('potential', self%field%potential, '', 'none, quadratic well, dipole or '// &
         'Onsager''s |sin| mean field', choices='none|quadratic|dipole|onsager')
    call s%key('alpha', self%field%alpha, 'm L^2/t0^2', 'strength (onsager: times L^2)', &
         lo=0.0_dp, hi=1.0e6_dp)
    call s%key('beta', self%field%beta, '1/t0', 'damping of quadratic', lo=0.0_dp, hi=1.0e6_dp)
    call s%key('theta_hat', self%field%theta_hat, 'rad', 'alignment direction', lo=-1.0e3_dp, &
         hi=1.0e3_dp)
    call s%key('onsager_force', self%field%force, '', 'Onsager force: exact (O(N^2), '// &
         'n <= 1e5), fourier or histogram', choices='exact|fourier|histogram')
    call s%key('fourier_modes', self%fourier_modes, '', 'Fourier modes K (fourier)', lo=1_i8, &
         hi=1000_i8)
    call s%key('onsager_bins', self%onsager_bins, '', 'grid points of the histogram form', &
         lo=8_i8, hi=8192_i8)
    call s%group('output', 'cadences in steps (0 = off)')
    call s%key('history_every', self%history_every, 'steps', 'history.dat rows (0 = off)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('histogram_every', self%histogram_every, 'steps', 'histograms.dat (0 = off)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('samples_every', self%samples_every, 'steps', 'samples.dat (0 = off)', lo=0_i8, &
         hi=max_steps_all)
    call s%key('checkpoint_every', self%checkpoint_every, 'steps', 'checkpoints (0 = none)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('progress_every', self%progress_every, 'steps', 'progress lines (0 = about '// &
         '200 per run)', lo=0_i8, hi=max_steps_all)
    call s%key('bins', self%bins, '', 'bins of the histograms', lo=2_i8, hi=100000_i8)
    call s%key('entropy_bins', self%entropy_bins, '', 'bins per axis of (vx, vy, omega) for H', &
         lo=2_i8, hi=128_i8)
    call s%key('v_max', self%v_max, 'L/t0', 'histogram range of the velocity components', &
         lo=0.0_dp, lo_open=.true., hi=1.0e6_dp)
    call s%key('omega_max', self%omega_max, 'rad/t0', 'histogram range of omega', lo=0.0_dp, &
         lo_open=.true., hi=1.0e6_dp)
    call s%key('collision_audit', self%collision_audit, '', 'per pair: energy and momentum '// &
         'balance against the formula (history.dat audit_dE, audit_dp)')
  end subroutine keys

  !> inertia_model = 'thin_rod': the inertia of a thin rod, m length^2/12.
  subroutine resolve(self)
    class(rods_t), intent(inout) :: self
    if (trim(self%inertia_model) == 'thin_rod') self%inertia = self%m*self%length**2/12.0_dp
  end subroutine resolve

  !> The mean field's and the collision law's parameters, the pair count, the
  !> initial state and the outputs.
  subroutine setup(self, path, st)
    class(rods_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    character(len=*), parameter :: units = ' Units: mass m, length L, time t0; '// &
         'E = m L^2/t0^2 (per sample).'
    self%field%modes = int(self%fourier_modes)
    self%field%bins = int(self%onsager_bins)
    self%field%inertia = self%inertia
    self%field%length = self%length
    self%law = collision_t(self%m, self%inertia, self%length, self%e_v, self%e_w, self%rotation)
    self%n_steps = nint(self%t_end/self%dt, i8)
    self%time_unit = self%dt
    self%nc = 0
    if (self%collisions) self%nc = pair_count(self%n, self%dt, self%tau)
    call initial_state(self)
    call self%out%table(self%hist, 'history.dat', &
         '# history.dat: DSMC rods, moments per sample.'//units, &
         '# step t[t0] T_trans[E] T_rot[E] T[E] E_kin[E] E_int[E] E_total[E] E_lost[E] '// &
         'px[mL/t0] py[mL/t0] spin[mL^2/t0] S1[1] S2[1] M4[L^4/t0^4] H[1] collisions[1] audit_dE[1] '// &
         'audit_dp[1]', on=self%history_every > 0)
    call self%out%table(self%histo, 'histograms.dat', &
         '# histograms.dat: densities of v_x, v_y, |v|, theta (wrapped to [-pi, pi)), omega '// &
         'per snapshot.'//units, &
         '# step t[t0] bin vx[L/t0] f_vx[t0/L] vy[L/t0] f_vy[t0/L] speed[L/t0] f_speed[t0/L] '// &
         'theta[rad] f_theta[1/rad] omega[rad/t0] f_omega[t0/rad]', on=self%histogram_every > 0)
    call self%out%table(self%samp, 'samples.dat', &
         '# samples.dat: every sample per snapshot (theta not wrapped).'//units, &
         '# step t[t0] id vx[L/t0] vy[L/t0] theta[rad] omega[rad/t0]', on=self%samples_every > 0)
  end subroutine setup

  !> Rules across keys (each key's own range is the declaration's, checked before).
  subroutine validate(self, s, path, st)
    class(rods_t), intent(inout) :: self
    type(schema_t), intent(in) :: s
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    if (self%dt > self%t_end .or. self%t_end/self%dt > real(max_steps_all, dp)) then
      call set_error(st, exit_bad_input, trim(path)//': &rods dt = '//real_str(self%dt)// &
           ': allowed [t_end/'//int_str(max_steps_all)//', t_end] = ['// &
           real_str(self%t_end/real(max_steps_all, dp))//', '//real_str(self%t_end)// &
           '] t0 (at most '//int_str(max_steps_all)//' steps)')
    else if (self%collisions .and. self%dt > self%tau) then
      call set_error(st, exit_bad_input, trim(path)//': &rods dt = '//real_str(self%dt)// &
           ': allowed (0, &collisions tau = '//real_str(self%tau)//'] (Nanbu-Babovsky draws '// &
           'floor(N dt/(2 tau)) disjoint pairs per step, at most N/2: dt <= tau)')
    else if (trim(self%field%potential) == 'onsager' .and. trim(self%field%force) == 'exact' &
         .and. self%n > 100000_i8) then
      call set_error(st, exit_bad_input, trim(path)//': &rods n = '//int_str(self%n)// &
           ': allowed integers in [2, 100000] with &mean_field onsager_force = ''exact'' '// &
           '(O(N^2) per step; ''fourier'' or ''histogram'' for more samples)')
    else
      ! peak while the initial law is drawn: v, theta, omega, three work arrays and the
      ! normals' two, then the permutation and the pair draw: about 100 B a sample
      call check_memory_need(100.0_dp*real(self%n, dp) + 16.0_dp*2.0_dp**20, trim(path)// &
           ': &rods n = '//int_str(self%n), 'reduce n', st)
    end if
  end subroutine validate

  !> N(0,1) variates by Box-Muller from the intrinsic generator.
  subroutine normals(x)
    real(dp), intent(out) :: x(:)
    real(dp), allocatable :: a(:), b(:)
    integer(i8) :: n
    n = size(x, kind=i8)
    allocate(a(n), b(n))
    call random_number(a)
    call random_number(b)
    x = sqrt(-2.0_dp*log(1.0_dp - a))*cos(2.0_dp*pi*b)
  end subroutine normals

  !> Samples from the scene's initial law (seeded): v, then theta, then omega.
  subroutine initial_state(self)
    class(rods_t), intent(inout) :: self
    integer :: k
    integer(i8) :: i
    integer, allocatable :: put(:)
    real(dp), allocatable :: a(:), b(:), r(:)
    call random_seed(size=k)
    allocate(put(k))
    put = int(self%seed) + 7919*[(k, k = 1, size(put))]
    call random_seed(put=put)
    allocate(self%v(2, self%n), self%theta(self%n), self%omega(self%n), a(self%n), &
         b(self%n), r(self%n))
    select case (trim(self%v_init))
    case ('two_bumps')     ! half the samples around (+v_shift, 0), half around (-v_shift, 0)
      call normals(a)
      call normals(b)
      call random_number(r)
      self%v(1, :) = merge(self%v_shift, -self%v_shift, r < 0.5_dp) + self%v_spread*a
      self%v(2, :) = self%v_spread*b
    case ('maxwellian')
      call normals(a)
      call normals(b)
      self%v(1, :) = self%v_shift + self%v_spread*a
      self%v(2, :) = self%v_spread*b
    case ('bkw')           ! f0 = |v|^2 exp(-|v|^2)/pi: |v|^2 ~ Gamma(2, 1), angle uniform
      call random_number(a)
      call random_number(b)
      call random_number(r)
      r = self%v_spread*sqrt(-log((1.0_dp - a)*(1.0_dp - b)))
      call random_number(a)
      self%v(1, :) = r*cos(2.0_dp*pi*a)
      self%v(2, :) = r*sin(2.0_dp*pi*a)
    end select
    if (trim(self%theta_init) == 'uniform') then
      call random_number(a)
      self%theta = -pi + 2.0_dp*pi*a
    else
      call normals(a)
      self%theta = self%theta0 + self%theta_spread*a
    end if
    call normals(a)
    self%omega = self%omega0 + self%omega_spread*a
    if (.not. self%rotation) self%omega = 0.0_dp
    self%perm = [(i, i = 1, self%n)]
    allocate(self%u(max(1_i8, 2*self%nc)), self%de(max(1_i8, self%nc)))   ! u: the pair draw
    self%step = 0
    self%n_collisions = 0
    self%e_lost = 0.0_dp
  end subroutine initial_state

  subroutine write_rows(self, last, st)
    class(rods_t), intent(inout) :: self
    logical, intent(in) :: last
    type(status_t), intent(inout) :: st
    integer :: b, nb
    integer(i8) :: i
    real(dp) :: t, eint, h
    real(dp), allocatable :: fx(:), fy(:), fs(:), ft(:), fw(:)
    type(moments_t) :: mo
    character(len=600) :: line
    if (.not. self%writing) return
    t = real(self%step, dp)*self%dt
    if (due(self%history_every, self%step, last)) then
      mo = sample_moments(self%m, self%inertia, self%rotation, self%v, self%theta, self%omega)
      eint = interaction_energy(self%field, self%theta)
      h = h_estimate(int(self%entropy_bins), self%v_max, self%omega_max, self%v, self%omega)
      write(line, '(i0,15(1x,'//rfmt//'),1x,i0,2(1x,'//rfmt//'))') self%step, t, mo%t_trans, mo%t_rot, mo%t_all, mo%e_kin, eint, &
           mo%e_kin + eint, self%e_lost, mo%px, mo%py, mo%spin, mo%s1, mo%s2, mo%m4, h, &
           self%n_collisions, self%audit_de, self%audit_dp
      call self%out%line(self%hist, trim(line), st)
      self%audit_de = 0.0_dp
      self%audit_dp = 0.0_dp
    end if
    if (due(self%histogram_every, self%step, last)) then
      nb = int(self%bins)
      fx = histogram(self%v(1, :), -self%v_max, self%v_max, nb)
      fy = histogram(self%v(2, :), -self%v_max, self%v_max, nb)
      fs = histogram(sqrt(self%v(1, :)**2 + self%v(2, :)**2), 0.0_dp, self%v_max, nb)
      ft = histogram(wrap_angle(self%theta), -pi, pi, nb)
      fw = histogram(self%omega, -self%omega_max, self%omega_max, nb)
      do b = 1, nb
        write(line, '(i0,1x,'//rfmt//',1x,i0,10(1x,'//rfmt//'))') self%step, t, b, centre(-self%v_max, self%v_max), fx(b), &
             centre(-self%v_max, self%v_max), fy(b), centre(0.0_dp, self%v_max), fs(b), &
             centre(-pi, pi), ft(b), centre(-self%omega_max, self%omega_max), fw(b)
        call self%out%line(self%histo, trim(line), st)
      end do
    end if
    if (due(self%samples_every, self%step, last)) then
      do i = 1, self%n
        write(line, '(i0,1x,'//rfmt//',1x,i0,4(1x,'//rfmt//'))') self%step, t, i, &
             self%v(:, i), self%theta(i), self%omega(i)
        call self%out%line(self%samp, trim(line), st)
      end do
    end if
  contains
    real(dp) function centre(lo, hi)
      real(dp), intent(in) :: lo, hi
      centre = lo + (real(b, dp) - 0.5_dp)*(hi - lo)/real(self%bins, dp)
    end function centre
  end subroutine write_rows

  !> One DSMC step: rows due, transport, collisions, guard.
  subroutine advance(self, st)
    class(rods_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    real(dp) :: absum, thmax
    logical :: vbad
    call write_rows(self, .false., st)
    if (st%code /= 0) return
    call transport(self%field, self%dt, self%theta, self%omega, absum, thmax)
    vbad = .false.
    if (self%nc > 0) call collision_step(self, vbad)
    self%step = self%step + 1
    ! sum of |theta|, |omega| (from the transport's pass; NaN and Inf propagate into it) and the
    ! collided velocities (v changes only in collisions): below the bounds every value and every
    ! power in the moments stays far from overflow (a row is never written with Inf/NaN)
    if (.not. (absum < runaway_bound) .or. vbad) then
      call set_error(st, exit_numerical, 'rods: non-finite sample (or sum of |theta|, '// &
           '|omega| above 1e100, or a collided |v_x| + |v_y| above 1e60) at step '// &
           int_str(self%step)//' (dt = '//real_str(self%dt)//' t0, &mean_field potential = '// &
           trim(self%field%potential)//'): explicit transport unstable, reduce dt')
    else if (trim(self%field%potential) == 'onsager') then
      if (thmax >= 1.0e15_dp) call set_error(st, exit_numerical, &
           'rods: |theta| above 1e15 rad at step '//int_str(self%step)// &
           ': theta mod pi has no digits left for the Onsager field')
    end if
  end subroutine advance

  !> Nanbu-Babovsky: nc disjoint pairs without replacement, the rod law on each. Step s uses
  !> the numbers s*5nc + 1 .. (s+1)*5nc of the counter-based stream of the scene seed (the pair
  !> draw the first 2 nc, on one thread; the pairs' impact parameters the rest, drawn by the
  !> blocks of the pair kernel where they run): the samples are bit-identical for any thread
  !> count, and a checkpoint needs only the step and the permutation to resume them.
  !> The lost energy is summed from a per-pair buffer in pair order (same bits too).
  subroutine collision_step(self, vbad)
    class(rods_t), intent(inout) :: self
    logical, intent(out) :: vbad
    integer(i8) :: nc, key
    real(dp) :: ade, adp
    nc = self%nc
    key = stream_key(self%seed)
    call uniforms(key, self%step, numbers_per_pair*nc, 0_i8, self%u(1:2*nc))
    call draw_pairs(self%perm, self%u(1:2*nc), nc)
    call collide_pairs(self%law, self%perm(1:2*nc), key, self%step, self%collision_audit, &
         self%v, self%theta, self%omega, self%de(1:nc), vbad, ade, adp)
    self%e_lost = self%e_lost - sum(self%de(1:nc))/real(self%n, dp)
    self%audit_de = max(self%audit_de, ade)
    self%audit_dp = max(self%audit_dp, adp)
    self%n_collisions = self%n_collisions + nc
  end subroutine collision_step

  subroutine finish(self, st)
    class(rods_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call write_rows(self, .true., st)
  end subroutine finish

  !> Payload: N, step, counters, generator state, samples, permutation.
  subroutine save_state(self, w)
    class(rods_t), intent(in) :: self
    type(ckpt_writer_t), intent(inout) :: w
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    integer :: k
    integer, allocatable :: rng(:)
    call random_seed(size=k)
    allocate(rng(k))
    call random_seed(get=rng)
    call ckpt_put(w, [transfer(self%n, b), transfer(self%step, b), transfer(self%n_collisions, b), &
         transfer(self%e_lost, b), transfer(self%audit_de, b), transfer(self%audit_dp, b), &
         transfer(k, b)])
    call ckpt_put(w, transfer(rng, b))
    call ckpt_put(w, transfer(self%v, b))
    call ckpt_put(w, transfer(self%theta, b))
    call ckpt_put(w, transfer(self%omega, b))
    call ckpt_put(w, transfer(self%perm, b))
  end subroutine save_state

  subroutine restore_state(self, u, st)
    class(rods_t), intent(inout) :: self
    integer, intent(in) :: u
    type(status_t), intent(inout) :: st
    integer :: ios, k, kk
    integer(i8) :: n
    integer, allocatable :: rng(:)
    call random_seed(size=k)
    read(u, iostat=ios) n
    if (ios == 0 .and. n /= self%n) ios = 1
    if (ios == 0) read(u, iostat=ios) self%step, self%n_collisions, self%e_lost, self%audit_de, &
         self%audit_dp, kk
    if (ios == 0 .and. kk /= k) ios = 1
    if (ios == 0) then
      allocate(rng(k))
      read(u, iostat=ios) rng, self%v, self%theta, self%omega, self%perm
    end if
    if (ios == 0 .and. (self%step < 0 .or. self%step > self%n_steps)) ios = 1
    if (ios == 0 .and. any(self%perm < 1 .or. self%perm > self%n)) ios = 1
    if (ios == 0) call random_seed(put=rng)
    if (ios /= 0) call set_error(st, exit_io, 'checkpoint payload does not match the scene')
  end subroutine restore_state

  function progress_text(self) result(s)
    class(rods_t), intent(in) :: self
    character(len=:), allocatable :: s
    character(len=30) :: buf
    real(dp) :: rn, tt, tr
    rn = real(self%n, dp)       ! T without the angle moments (no trigonometry per line)
    tt = 0.5_dp*self%m*(sum(self%v**2)/rn - (sum(self%v(1, :))/rn)**2 - (sum(self%v(2, :))/rn)**2)
    tr = self%inertia*(sum(self%omega**2)/rn - (sum(self%omega)/rn)**2)
    write(buf, '(es12.5)') merge((2.0_dp*tt + tr)/3.0_dp, tt, self%rotation)
    s = 'T '//trim(adjustl(buf))
  end function progress_text

  function json_fields(self) result(text)
    class(rods_t), intent(in) :: self
    character(len=:), allocatable :: text
    text = '  "n_particles": '//int_str(self%n)//','//achar(10)// &
         '  "pairs_per_step": '//int_str(self%nc)//','//achar(10)// &
         '  "units": {"mass": "m", "length": "L", "time": "t0", "energy": "m L^2/t0^2"},'// &
         achar(10)
  end function json_fields

end module dsmc_rods
