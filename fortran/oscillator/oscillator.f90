!> Kind 'oscillator': N independent damped harmonic oscillators,
!>   x'' = -omega^2 x - 2 zeta omega x',   0 <= zeta < 1 (under-damped),
!> with the exact solution x(t) = e^{-zeta omega t} (x0 cos(w_d t) + (v0 + zeta omega x0)/w_d sin(w_d t)),
!> w_d = omega sqrt(1 - zeta^2). It is the second method behind the runner's
!> interface (module method) and the validation kind of the test suite:
!> integrator orders, exact solutions, checkpoints and resume on a state
!> that has nothing of the bed.
!>
!> Units: any consistent length L and time tau chosen by the user (omega in
!> rad/tau, t in tau, x in L, v in L/tau); unit mass, energies in L^2/tau^2.
!> Integrators: 'euler' (explicit, order 1), 'velocity_verlet' (Strang
!> splitting: exact damping half-steps around kick-drift-kick, order 2),
!> 'exact' (the analytic propagator: round-off only).
module oscillator
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, exit_io, exit_numerical, msg_len
  use method, only: method_t
  use tables, only: rfmt
  use output_set, only: due
  use scene_input, only: kind_len, int_str, real_str
  use schema, only: schema_t, max_steps_all
  use ckpt, only: ckpt_writer_t, ckpt_put
  use, intrinsic :: iso_fortran_env, only: int8
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  private

  public :: oscillator_t

  integer, parameter :: name_len = 32
  !> The energy of a damped oscillator never grows: a numerical energy above
  !> this multiple of the initial one is an unstable integration (guard).
  real(dp), parameter :: max_energy_growth = 1.0e6_dp

  type, extends(method_t) :: oscillator_t
    ! &scene
    character(len=kind_len) :: kind = 'oscillator'
    character(len=128) :: title = 'untitled'
    ! &oscillator
    integer(i8) :: n = 1                    !< number of oscillators
    real(dp) :: omega = 1.0_dp              !< natural angular frequency [rad/tau]
    real(dp) :: zeta = 0.0_dp               !< damping ratio [1], 0 <= zeta < 1
    real(dp) :: amplitude = 1.0_dp          !< initial amplitude [L]
    integer(i8) :: seed = 1                 !< RNG seed of the initial phases
    character(len=name_len) :: integrator = 'velocity_verlet'
    real(dp) :: dt = 1.0e-2_dp              !< time step [tau]
    real(dp) :: t_end = 10.0_dp             !< run length [tau]
    real(dp) :: target_rel_error = 0        !< read by pyorch (trade table), ignored here
    ! &output (cadences in steps, 0 = file off)
    integer(i8) :: trajectory_every = 10
    integer(i8) :: energy_every = 10
    ! state (step, n_steps: method_t's)
    real(dp), allocatable :: x(:), v(:), x0(:), v0(:)
    real(dp) :: e0 = 0                      !< initial energy [L^2/tau^2] (growth guard)
    integer :: traj = 0, energy = 0         !< output ids (0: off)
  contains
    procedure :: keys, setup, advance, finish
    procedure :: rules => validate
    procedure :: save_state, restore_state, progress_text, json_fields
  end type oscillator_t

contains

  !> The scene of this kind, declared once (module schema): reading,
  !> validation, scene.nml and `partsim --describe oscillator` come from it.
  subroutine keys(self, s)
    class(oscillator_t), intent(inout), target :: self
    type(schema_t), intent(inout) :: s
    call s%init('oscillator', 'kind oscillator. Units: length L, time tau (the user''s '// &
         'choice), unit mass.')
    call s%scene_group(self%kind, self%title)
    call s%group('oscillator', 'the oscillators and their integration')
    call s%key('n', self%n, '', 'number of oscillators', lo=1_i8, hi=10000000_i8)
    call s%key('omega', self%omega, 'rad/tau', 'natural angular frequency', lo=0.0_dp, &
         hi=1.0e6_dp, lo_open=.true.)
    call s%key('zeta', self%zeta, '1', 'damping ratio (under-damped)', lo=0.0_dp, hi=0.999_dp)
    call s%key('amplitude', self%amplitude, 'L', 'initial amplitude', lo=0.0_dp, hi=1.0e12_dp, &
         lo_open=.true.)
    call s%key('seed', self%seed, '', 'RNG seed of the initial phases', lo=1_i8, &
         hi=2147483647_i8)
    call s%key('integrator', self%integrator, '', 'explicit Euler (order 1), velocity '// &
         'Verlet with exact damping half-steps (order 2, stable for omega dt < 2), or the '// &
         'analytic propagator', choices='euler|velocity_verlet|exact')
    call s%key('dt', self%dt, 'tau', 'time step (<= t_end)', lo=0.0_dp, lo_open=.true., &
         hi=1.0e12_dp)
    call s%key('t_end', self%t_end, 'tau', 'run length', lo=0.0_dp, hi=1.0e12_dp, &
         lo_open=.true.)
    call s%key('target_rel_error', self%target_rel_error, '1', 'read by pyorch: the '// &
         'cheapest measured integrator and dt meeting it (0 = off; the engine ignores it)', &
         lo=0.0_dp, hi=1.0_dp)
    call s%group('output', 'cadences in steps (0 = file off)')
    call s%key('trajectory_every', self%trajectory_every, 'steps', 'trajectory.dat rows '// &
         '(0 = off)', lo=0_i8, hi=max_steps_all)
    call s%key('energy_every', self%energy_every, 'steps', 'energy.dat rows (0 = off)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('checkpoint_every', self%checkpoint_every, 'steps', 'checkpoints (0 = only '// &
         'at step 0)', lo=0_i8, hi=max_steps_all)
  end subroutine keys

  !> The step count, the initial state and the outputs.
  subroutine setup(self, path, st)
    class(oscillator_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    character(len=*), parameter :: units = 'Units: length L, time tau (omega in rad/tau), unit mass.'
    self%n_steps = nint(self%t_end/self%dt, i8)
    self%time_unit = self%dt
    call initial_state(self)
    self%e0 = total_energy(self)
    call self%out%table(self%traj, 'trajectory.dat', &
         '# trajectory.dat: damped harmonic oscillators. '//units, &
         '# step t[tau] id x[L] v[L/tau]', on=self%trajectory_every > 0)
    call self%out%table(self%energy, 'energy.dat', &
         '# energy.dat: energies summed over the oscillators. '//units, &
         '# step t[tau] E_kin[L^2/tau^2] E_pot[L^2/tau^2] E_total[L^2/tau^2]', &
         on=self%energy_every > 0)
  end subroutine setup

  !> Rules across keys: the step count, and the step's stability (the
  !> run must not be accepted to explode: rule 2).
  subroutine validate(self, s, path, st)
    class(oscillator_t), intent(inout) :: self
    type(schema_t), intent(in) :: s
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: wh, growth
    if (self%dt > self%t_end) then
      call set_error(st, exit_bad_input, trim(path)//': &oscillator dt = '// &
           real_str(self%dt)//': allowed (0, t_end = '//real_str(self%t_end)//'] [tau]')
      return
    end if
    if (self%t_end/self%dt > real(max_steps_all, dp)) then
      call set_error(st, exit_bad_input, trim(path)//': &oscillator t_end/dt = '// &
           real_str(self%t_end/self%dt)//': at most '//int_str(max_steps_all)//' steps')
      return
    end if
    wh = self%omega*self%dt
    select case (trim(self%integrator))
    case ('velocity_verlet')
      if (wh >= 2.0_dp) call set_error(st, exit_bad_input, trim(path)//': &oscillator dt = '// &
           real_str(self%dt)//': velocity_verlet is unstable for omega dt >= 2 (here '// &
           real_str(wh)//'): allowed dt < '//real_str(2.0_dp/self%omega)//' tau')
    case ('euler')
      growth = log10(euler_radius(wh, self%zeta))*2.0_dp*self%t_end/self%dt
      if (growth > log10(max_energy_growth)) call set_error(st, exit_bad_input, trim(path)// &
           ': &oscillator dt = '//real_str(self%dt)//': explicit Euler multiplies the energy '// &
           'by 10^'//trim(adjustl(fstr(growth)))//' over t_end (spectral radius '// &
           real_str(euler_radius(wh, self%zeta))//' per step); allowed: growth <= 1e6 '// &
           '(a smaller dt or t_end, or integrator = ''velocity_verlet'')')
    end select
  end subroutine validate

  !> Spectral radius of one explicit Euler step of x'' = -w^2 x - 2 zeta w x'
  !> (wh = omega dt): the amplitude grows by at most this factor per step.
  pure real(dp) function euler_radius(wh, zeta) result(rho)
    real(dp), intent(in) :: wh, zeta
    complex(dp) :: disc, l1, l2
    real(dp) :: tr, det
    tr = 2.0_dp - 2.0_dp*zeta*wh
    det = 1.0_dp - 2.0_dp*zeta*wh + wh**2
    disc = sqrt(cmplx(tr**2 - 4.0_dp*det, 0.0_dp, dp))
    l1 = 0.5_dp*(tr + disc)
    l2 = 0.5_dp*(tr - disc)
    rho = max(abs(l1), abs(l2))
  end function euler_radius

  pure real(dp) function total_energy(self) result(e)
    class(oscillator_t), intent(in) :: self
    e = 0.5_dp*sum(self%v**2) + 0.5_dp*self%omega**2*sum(self%x**2)
  end function total_energy

  !> x = A cos(phase), v = -A omega sin(phase), phases uniform from the seed.
  subroutine initial_state(self)
    class(oscillator_t), intent(inout) :: self
    integer :: k
    integer, allocatable :: put(:)
    real(dp), allocatable :: phase(:)
    real(dp), parameter :: two_pi = 6.283185307179586476925286766559_dp
    call random_seed(size=k)
    allocate(put(k))
    put = int(self%seed) + 7919*[(k, k = 1, size(put))]
    call random_seed(put=put)
    allocate(phase(self%n))
    call random_number(phase)
    phase = two_pi*phase
    self%x0 = self%amplitude*cos(phase)
    self%v0 = -self%amplitude*self%omega*sin(phase)
    self%x = self%x0
    self%v = self%v0
    self%step = 0
  end subroutine initial_state

  !> Rows due at the current step (every `every` steps, and at the last).
  subroutine write_rows(self, last, st)
    class(oscillator_t), intent(inout) :: self
    logical, intent(in) :: last
    type(status_t), intent(inout) :: st
    integer(i8) :: i
    real(dp) :: t, ek, ep
    character(len=120) :: line
    logical :: o_traj, o_en
    if (.not. self%writing) return
    o_traj = due(self%trajectory_every, self%step, last)
    o_en = due(self%energy_every, self%step, last)
    if (o_traj .or. o_en) call growth_guard(self, st)
    if (st%code /= 0) return
    t = real(self%step, dp)*self%dt
    if (o_traj) then
      do i = 1, self%n
        write(line, '(i0,1x,'//rfmt//',1x,i0,2(1x,'//rfmt//'))') self%step, t, i, self%x(i), &
             self%v(i)
        call self%out%line(self%traj, trim(line), st)
      end do
    end if
    if (o_en) then
      ek = 0.5_dp*sum(self%v**2)
      ep = 0.5_dp*self%omega**2*sum(self%x**2)
      write(line, '(i0,4(1x,'//rfmt//'))') self%step, t, ek, ep, ek + ep
      call self%out%line(self%energy, trim(line), st)
    end if
  end subroutine write_rows

  !> The energy of a damped oscillator never grows: a numerical energy above
  !> max_energy_growth times the initial one is an unstable step. Checked where rows are
  !> written and at the end (not every step: two more sums per step for nothing).
  subroutine growth_guard(self, st)
    class(oscillator_t), intent(in) :: self
    type(status_t), intent(inout) :: st
    real(dp) :: e
    e = total_energy(self)
    if (e > max_energy_growth*self%e0) call set_error(st, exit_numerical, &
         'oscillator: the energy grew '//trim(adjustl(rstr(e/self%e0)))//'-fold by step '// &
         int_str(self%step)//' (a damped oscillator''s energy never grows): the '// &
         trim(self%integrator)//' step is unstable at omega dt = '// &
         trim(adjustl(rstr(self%omega*self%dt))))
  end subroutine growth_guard

  subroutine advance(self, st)
    class(oscillator_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    real(dp) :: h, w2, damp
    call write_rows(self, .false., st)
    if (st%code /= 0) return
    h = self%dt
    w2 = self%omega**2
    select case (trim(self%integrator))
    case ('euler')
      call euler_step(self%x, self%v, h, w2, 2.0_dp*self%zeta*self%omega)
    case ('velocity_verlet')
      damp = exp(-self%zeta*self%omega*h)     ! exact damping over h/2: v' = -2 zeta omega v
      self%v = damp*self%v
      self%v = self%v - 0.5_dp*h*w2*self%x
      self%x = self%x + h*self%v
      self%v = self%v - 0.5_dp*h*w2*self%x
      self%v = damp*self%v
    case ('exact')
      call exact(self, real(self%step + 1, dp)*h, self%x, self%v)
    end select
    self%step = self%step + 1
    if (.not. all(ieee_is_finite(self%x)) .or. .not. all(ieee_is_finite(self%v))) then
      call set_error(st, exit_numerical, 'oscillator: non-finite state at step '// &
           int_str(self%step)//' (dt = '//trim(adjustl(rstr(self%dt)))//' tau; explicit Euler '// &
           'grows as (1 + (omega dt)^2)^(n/2))')
    end if
  end subroutine advance

  pure subroutine euler_step(x, v, h, w2, c)
    real(dp), intent(inout) :: x(:), v(:)
    real(dp), intent(in) :: h, w2, c
    real(dp) :: a(size(x))
    a = -w2*x - c*v
    x = x + h*v
    v = v + h*a
  end subroutine euler_step

  !> The analytic solution at time t from the initial state.
  subroutine exact(self, t, x, v)
    class(oscillator_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: x(:), v(:)
    real(dp) :: wd, e, c, s, zw
    zw = self%zeta*self%omega
    wd = self%omega*sqrt(1.0_dp - self%zeta**2)
    e = exp(-zw*t)
    c = cos(wd*t)
    s = sin(wd*t)
    x = e*(self%x0*c + (self%v0 + zw*self%x0)/wd*s)
    v = e*(self%v0*c - (zw*self%v0 + self%omega**2*self%x0)/wd*s)
  end subroutine exact

  subroutine finish(self, st)
    class(oscillator_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    call growth_guard(self, st)
    call write_rows(self, .true., st)
  end subroutine finish

  subroutine save_state(self, w)
    class(oscillator_t), intent(in) :: self
    type(ckpt_writer_t), intent(inout) :: w
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    call ckpt_put(w, [transfer(self%n, b), transfer(self%step, b)])
    call ckpt_put(w, transfer(self%x, b))
    call ckpt_put(w, transfer(self%v, b))
  end subroutine save_state

  subroutine restore_state(self, u, st)
    class(oscillator_t), intent(inout) :: self
    integer, intent(in) :: u
    type(status_t), intent(inout) :: st
    integer :: ios
    integer(i8) :: n
    read(u, iostat=ios) n
    if (ios == 0 .and. n /= self%n) ios = 1
    if (ios == 0) read(u, iostat=ios) self%step, self%x, self%v
    if (ios == 0 .and. (self%step < 0 .or. self%step > self%n_steps)) ios = 1
    if (ios /= 0) call set_error(st, exit_io, 'checkpoint payload does not match the scene')
  end subroutine restore_state

  function progress_text(self) result(s)
    class(oscillator_t), intent(in) :: self
    character(len=:), allocatable :: s
    character(len=30) :: buf
    write(buf, '(es12.5)') 0.5_dp*sum(self%v**2) + 0.5_dp*self%omega**2*sum(self%x**2)
    s = 'run '//trim(adjustl(buf))
  end function progress_text

  function json_fields(self) result(text)
    class(oscillator_t), intent(in) :: self
    character(len=:), allocatable :: text
    text = '  "n_particles": '//int_str(self%n)//','//achar(10)// &
         '  "units": {"length": "L", "time": "tau", "mass": "1", "energy": "L^2/tau^2"},'// &
         achar(10)
  end function json_fields

  function fstr(v) result(s)
    real(dp), intent(in) :: v
    character(len=24) :: s
    write(s, '(f0.1)') v
  end function fstr

  function rstr(v) result(s)
    real(dp), intent(in) :: v
    character(len=24) :: s
    write(s, '(es12.5)') v
  end function rstr

end module oscillator
