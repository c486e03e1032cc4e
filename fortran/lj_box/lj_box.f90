!> Kind 'lj_box' (seed 000): N particles of radius a in the box [0, L]^2,
!> Longer than 600 lines because the kind is one type: its key declarations (keys: ~110
!> lines, bound to the type's own components), the rules across keys, the initial state, the
!> step and the rows; the physics is elsewhere (pair_forces, fields, mirror_walls, friction).
!>   dv/dt = -(9/2) alpha v + F_ext(x, t) + F_steric,   dx/dt = v          (eq. 6)
!> with the truncated Lennard-Jones steric law (eqs. 3-5, 8-9; pair_forces' lj_law_t, through
!> the bed's neighbour strategies and threaded passes), Stokes drag (friction's viscous term
!> with gamma = 9 alpha/2), an external field (module fields) and inelastic mirror walls
!> (module mirror_walls, eq. 10). Integrators: the seed's explicit Euler, semi-implicit
!> (symplectic) Euler, velocity Verlet (module integrators).
!>
!> Units (the seed's dimensionless form): length a, time T = sqrt(a/g), mass m (every
!> particle mass 1), force m g, energy m g a.
module lj_box
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, exit_io, exit_numerical
  use method, only: method_t
  use memory, only: check_memory_need
  use tables, only: rfmt
  use scene_input, only: json_real
  use output_set, only: due, frames_as
  use scene_input, only: kind_len, choice_index, int_str, real_str
  use schema, only: schema_t, max_steps_all
  use ckpt, only: ckpt_writer_t, ckpt_put, file_crc64
  use state, only: state_t, state_allocate
  use neighbours, only: nlist_t, nlist_setup, nlist_owners, nb_all_pairs, nb_cells, nb_verlet
  use nlist_upkeep, only: nlist_refresh, nlist_pruned, nlist_set_prune, nlist_prune_json, &
       nlist_force_start, nlist_force_done
  use pair_forces, only: lj_law_t, lj_law, pair_forces_all, pair_forces_list, lj_energy, &
       pair_table_t, max_bits
  use pair_eval, only: lj_eval_build
  use pair_table, only: table_json, eval_names, eval_code, eval_exact, eval_table
  use fields, only: field_t, field_add, field_potential, field_has_potential, &
       field_read_table, field_shapes, field_modulations, field_static
  use mirror_walls, only: mirror_reflect
  use friction, only: viscous_friction
  use integrators, only: int_velocity_verlet, int_euler, int_semi_euler, estimate_velocity, &
       finish_velocity, advance_step => advance
  use rng, only: seed_rng
  use checkpoint, only: checkpoint_save, checkpoint_restore
  use start_file, only: start_t, start_read, start_check_region, start_check_distances, &
       start_json, check_start_crc, start_release
  use parallel, only: init_threads
  use, intrinsic :: iso_fortran_env, only: int8
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  private

  public :: lj_box_t

  integer, parameter :: nm = 32
  real(dp), parameter :: big = 1.0e12_dp
  character(len=*), parameter :: units = 'Units: length a (particle radius), time T = '// &
       'sqrt(a/g), mass m (all 1), force m g, energy m g a.'
  character(len=*), parameter :: method_names(3) = [character(len=19) :: 'euler', &
       'semi_implicit_euler', 'velocity_verlet']
  integer, parameter :: method_codes(3) = [int_euler, int_semi_euler, int_velocity_verlet]
  character(len=*), parameter :: neighbour_names(3) = [character(len=9) :: 'verlet', 'cells', &
       'all_pairs']
  integer, parameter :: neighbour_codes(3) = [nb_verlet, nb_cells, nb_all_pairs]
  !> columns of frames.dat and frames.bin after step and t
  character(len=*), parameter :: frame_cols(6) = [character(len=4) :: 'id', 'type', 'x', 'y', &
       'vx', 'vy']
  character(len=*), parameter :: frame_units(6) = [character(len=4) :: '', '', 'a', 'a', 'a/T', &
       'a/T']

  type, extends(method_t) :: lj_box_t
    ! &scene
    character(len=kind_len) :: kind = 'lj_box'
    character(len=128) :: title = 'untitled'
    ! &box
    real(dp) :: l = 40                      !< side L [a]
    ! &particles
    integer(i8) :: n = 200
    character(len=nm) :: placement = 'random'
    real(dp) :: min_distance = 2            !< [a]
    character(len=nm) :: velocities = 'zero'
    real(dp) :: speed = 1                   !< [a/T]
    real(dp) :: temperature = 1             !< kT [m g a]
    integer(i8) :: seed = 1
    integer(i8) :: type_id = 0              !< particle type written to frames (GNS: not 3)
    character(len=512) :: start_file = ''   !< start from this file's frame (module start_file)
    ! &steric
    character(len=nm) :: law = 'lj'
    integer(i8) :: p = 6
    real(dp) :: u0 = 1                      !< [m g a]
    real(dp) :: r_m = 1.8_dp                !< [a]
    real(dp) :: r_cut = 5                   !< R [a]
    character(len=nm) :: neighbour = 'verlet'
    real(dp) :: skin = 0.6_dp               !< [a]
    real(dp) :: prune_skin = -1.0_dp        !< pruned list margin over r_cut [a] (< 0: automatic)
    character(len=nm) :: pair_eval = 'exact'   !< | 'table' | 'single' | 'rsqrt'
    real(dp) :: pair_table_error = 1.0e-6_dp  !< pair_eval /= 'exact': largest relative force error
    ! &physics
    real(dp) :: alpha = 0                   !< eq. (7)
    ! &field (parameters in self%fl)
    character(len=nm) :: field_type = 'none', modulation = 'none'
    character(len=512) :: field_file = ''
    ! &walls
    real(dp) :: gamma = 1
    character(len=nm) :: contact = 'surface'
    ! &integration
    character(len=nm) :: integrator = 'semi_implicit_euler'
    real(dp) :: dt = 1.0e-3_dp              !< [T]
    integer(i8) :: steps = 10000
    real(dp) :: target_rel_error = 0        !< read by pyorch (trade table), ignored here
    ! &output (cadences in steps; 0 = file off)
    integer(i8) :: frame_every = 100, energy_every = 100
    integer(i8) :: field_grid = 0           !< field.dat: grid points per side (0 = off)
    character(len=nm) :: frames_format = 'text'   !< frames.dat | 'binary': frames.bin | 'both'
    ! built
    type(field_t) :: fl
    type(lj_law_t) :: lj
    type(pair_table_t) :: ljtab             !< the law's table (pair_eval = 'table'; off: exact)
    type(state_t) :: s, none
    type(start_t) :: start                  !< the start file as read (path unset: none)
    type(nlist_t) :: nl
    integer :: method = int_semi_euler, strategy = nb_verlet
    logical :: steric_on = .true.
    real(dp) :: lo = 1, hi = 39             !< reachable centre range [a]
    integer(i8) :: wall_hits = 0
    integer(i8) :: table_crc = 0
    real(dp) :: r2min = 0
    integer :: frames = 0, energy = 0, field_out = 0, frames_bin = 0   !< output ids (0: off)
  contains
    procedure :: keys, setup, advance, finish
    procedure :: rules => validate
    procedure :: save_state, restore_state, counters
    procedure :: progress_text, json_fields
  end type lj_box_t

contains

  !> The scene of this kind, declared once (module schema): reading, validation, scene.nml
  !> and `partsim --describe lj_box` come from it. Ranges that depend on other keys are
  !> checked in validate.
  subroutine keys(self, s)
    class(lj_box_t), intent(inout), target :: self
    type(schema_t), intent(inout) :: s
    call s%init('lj_box', 'kind lj_box (seed 000). '//units)
    call s%scene_group(self%kind, self%title)
    call s%group('box', 'the square box [0, L]^2')
    call s%key('l', self%l, 'a', 'side L of the box (> 2 with contact = ''surface'')', &
         lo=0.0_dp, lo_open=.true., hi=1.0e6_dp)
    call s%group('particles', 'number, initial positions and velocities')
    call s%key('n', self%n, '', 'number of particles', lo=1_i8, hi=10000000_i8)
    call s%key('placement', self%placement, '', 'random sequential addition at '// &
         'min_distance, or a square lattice', choices='random|lattice')
    call s%key('min_distance', self%min_distance, 'a', 'least distance between centres at '// &
         't = 0 (<= l)', lo=0.0_dp, hi=1.0e6_dp)
    call s%key('velocities', self%velocities, '', 'initial velocities: zero, one speed in '// &
         'uniform random directions, or Maxwellian at temperature', &
         choices='zero|speed|maxwell')
    call s%key('speed', self%speed, 'a/T', 'initial speed (velocities = ''speed'')', &
         lo=0.0_dp, hi=1.0e6_dp)
    call s%key('temperature', self%temperature, 'm g a', 'kT of the Maxwellian (velocities '// &
         '= ''maxwell'')', lo=0.0_dp, lo_open=.true., hi=1.0e6_dp)
    call s%key('seed', self%seed, '', 'RNG seed of the initial state', lo=1_i8, &
         hi=2147483647_i8)
    call s%key('type_id', self%type_id, '', 'particle type written to the frames (not 3: '// &
         'gns treats type 3 as kinematic)', lo=0_i8, hi=1000_i8)
    call s%key('start_file', self%start_file, '', 'start from this file (format: fortran/md/'// &
         'start_file.f90; pyorch scene start-file makes one from a GSD frame): positions and, '// &
         'if it has them, velocities [a, a/T] (placement unused; velocities only for a file '// &
         'without them); a path relative to the working directory ('''' = placement)')
    call s%group('steric', 'the truncated Lennard-Jones pair law (eqs. 3-5, 8-9) and the '// &
         'neighbour search')
    call s%key('law', self%law, '', 'the pair law (eqs. 3-5), or no pair forces', &
         choices='lj|none')
    call s%key('p', self%p, '', 'exponent of the law', lo=1_i8, hi=64_i8)
    call s%key('u0', self%u0, 'm g a', 'well depth', lo=0.0_dp, hi=1.0e6_dp)
    call s%key('r_m', self%r_m, 'a', 'the force is linear below r_m (seed 000: r_m < 2a)', &
         lo=0.0_dp, lo_open=.true., hi=2.0_dp, hi_open=.true.)
    call s%key('r_cut', self%r_cut, 'a', 'cut-off R: zero force beyond (> r_m)', lo=0.0_dp, &
         lo_open=.true., hi=1.0e6_dp)
    call s%key('neighbour', self%neighbour, '', 'pair search: Verlet list, cell list or '// &
         'all pairs', choices=join(neighbour_names))
    call s%key('skin', self%skin, 'a', 'Verlet list skin (> 0 with neighbour = ''verlet'')', &
         lo=0.0_dp, hi=1.0e3_dp)
    call s%key('prune_skin', self%prune_skin, 'a', 'verlet: the list pruned to r_cut + '// &
         'prune_skin, again when a particle moved prune_skin/2 (speed only: the same bits; '// &
         '< 0: automatic, chosen at every build, 0: off; in [0, skin))', lo=-1.0_dp, hi=1.0e3_dp)
    call s%key('pair_eval', self%pair_eval, '', 'force evaluation: exact (the reference), a '// &
         'table in r^2 between r_m and r_cut (no division) built at load to pair_table_error, '// &
         'or for p = 6 single precision pair arithmetic (double sums) or rsqrt (1/r^2 by '// &
         'three Newton steps: no division)', choices=eval_names)
    call s%key('pair_table_error', self%pair_table_error, '1', 'pair_eval /= exact: largest '// &
         'error of the force over [r_m, r_cut], relative to the sum of its two terms'' '// &
         'magnitudes (measured at load; refused when not met)', lo=1.0e-15_dp, hi=1.0e-2_dp)
    call s%group('physics', 'the drag')
    call s%key('alpha', self%alpha, '1', 'Stokes drag -(9/2) alpha v (eq. 7)', lo=0.0_dp, &
         hi=1.0e6_dp)
    call s%group('field', 'the external force F_ext(x, t) (module fields: formulas there)')
    call s%key('type', self%field_type, '', 'shape of the field', choices=join(field_shapes))
    call fkey('f0x', self%fl%f0x, 'm g', 'uniform part, x')
    call fkey('f0y', self%fl%f0y, 'm g', 'uniform part, y')
    call fkey('gxx', self%fl%gxx, 'm g/a', 'gradient dFx/dx')
    call fkey('gxy', self%fl%gxy, 'm g/a', 'gradient dFx/dy')
    call fkey('gyx', self%fl%gyx, 'm g/a', 'gradient dFy/dx')
    call fkey('gyy', self%fl%gyy, 'm g/a', 'gradient dFy/dy')
    call fkey('x0', self%fl%x0, 'a', 'reference point, x')
    call fkey('y0', self%fl%y0, 'a', 'reference point, y')
    call fkey('amplitude', self%fl%amplitude, 'm g', 'amplitude A (vortex: in m g a)')
    call fkey('ex', self%fl%ex, '1', 'wave force direction (ex, ey), x (normalised in use; '// &
         'not both 0)')
    call fkey('ey', self%fl%ey, '1', 'wave force direction (ex, ey), y')
    call fkey('kx', self%fl%kx, '1/a', 'wave vector, x')
    call fkey('ky', self%fl%ky, '1/a', 'wave vector, y')
    call fkey('omega', self%fl%omega, '1/T', 'wave angular frequency')
    call fkey('phase', self%fl%phase, 'rad', 'wave phase')
    call s%key('power', self%fl%power, '1', 'point field exponent', lo=-10.0_dp, hi=10.0_dp)
    call s%key('r0', self%fl%r0, 'a', 'point field reference distance', lo=0.0_dp, &
         lo_open=.true., hi=big)
    call s%key('r_core', self%fl%r_core, 'a', 'point and vortex core radius', lo=0.0_dp, &
         lo_open=.true., hi=big)
    call s%key('modulation', self%modulation, '', 'time factor m(t): 1, cos(mod_omega t + '// &
         'mod_phase), or min(1, t/mod_time)', choices=join(field_modulations))
    call fkey('mod_omega', self%fl%mod_omega, '1/T', 'modulation angular frequency')
    call fkey('mod_phase', self%fl%mod_phase, 'rad', 'modulation phase')
    call s%key('mod_time', self%fl%mod_time, 'T', 'ramp time', lo=0.0_dp, lo_open=.true., &
         hi=big)
    call s%key('file', self%field_file, '', 'tabulated field (type = ''table''; format in '// &
         'fields.f90 field_read_table)')
    call s%group('walls', 'inelastic mirror walls (eq. 10)')
    call s%key('gamma', self%gamma, '1', 'kinetic energy kept per wall hit', lo=0.0_dp, &
         lo_open=.true., hi=1.0_dp)
    call s%key('contact', self%contact, '', 'a wall is hit by the surface (centre within a) '// &
         'or by the centre', choices='surface|centre')
    call s%group('integration', 'the integrator and the run length')
    call s%key('method', self%integrator, '', 'explicit Euler, semi-implicit (symplectic) '// &
         'Euler or velocity Verlet', choices=join(method_names))
    call s%key('dt', self%dt, 'T', 'time step', lo=0.0_dp, lo_open=.true., hi=1.0e3_dp)
    call s%key('steps', self%steps, 'steps', 'run length', lo=1_i8, hi=max_steps_all)
    call s%key('target_rel_error', self%target_rel_error, '1', 'read by pyorch: the '// &
         'cheapest measured setting meeting it (0 = off; the engine ignores it)', lo=0.0_dp, &
         hi=1.0_dp)
    call s%group('output', 'cadences in steps (0 = file off)')
    call s%key('frame_every', self%frame_every, 'steps', 'frames rows (0 = off)', lo=0_i8, &
         hi=max_steps_all)
    call s%key('energy_every', self%energy_every, 'steps', 'energy.dat rows (0 = off)', &
         lo=0_i8, hi=max_steps_all)
    call s%key('checkpoint_every', self%checkpoint_every, 'steps', 'checkpoints (0 = only '// &
         'at step 0)', lo=0_i8, hi=max_steps_all)
    call s%key('progress_every', self%progress_every, 'steps', 'progress lines (0: about '// &
         '200 per run, resolved in scene.nml)', lo=0_i8, hi=max_steps_all)
    call s%key('field_grid', self%field_grid, '', 'field.dat: grid points per side (0 = off)', &
         lo=0_i8, hi=1000_i8)
    call s%key('frames_format', self%frames_format, '', 'frames.dat (text), frames.bin '// &
         '(binary) or both', choices='text|binary|both')
  contains
    !> A field parameter: any finite value within +-1e12.
    subroutine fkey(name, v, unit, doc)
      character(len=*), intent(in) :: name, unit, doc
      real(dp), intent(inout), target :: v
      call s%key(name, v, unit, doc, lo=-big, hi=big)
    end subroutine fkey
  end subroutine keys

  !> 'a|b|c' from a list of names (a choice key's choices).
  function join(names) result(r)
    character(len=*), intent(in) :: names(:)
    character(len=:), allocatable :: r
    integer :: k
    r = ''
    do k = 1, size(names)
      if (k > 1) r = r//'|'
      r = r//trim(names(k))
    end do
  end function join

  !> After the rules: the derived quantities, the initial state and the outputs.
  subroutine setup(self, path, st)
    class(lj_box_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    if (self%progress_every == 0) self%progress_every = max(1_i8, self%steps/200)  ! as stated
    call build(self, st)
    if (st%code /= 0) return
    call initial_state(self, path, st)
    if (st%code /= 0) return
    call declare_outputs(self)
  end subroutine setup

  !> The rules across keys (each key's own range is declared in keys).
  subroutine validate(self, s, path, st)
    class(lj_box_t), intent(inout) :: self
    type(schema_t), intent(in) :: s
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: mem, pairs   ! the memory estimate [B a particle], listed pairs a particle
    if (self%type_id == 3) then
      call fail('particles', 'type_id', 'type_id = 3: allowed [0, 1000] except 3 (gns '// &
           'treats type 3 as kinematic particles, not learned)')
    else if (self%min_distance > self%l) then
      call fail('particles', 'min_distance', 'min_distance = '//real_str(self%min_distance)// &
           ': allowed [0, l = '//real_str(self%l)//'] [a]')
    else if (self%r_cut <= self%r_m) then
      call fail('steric', 'r_cut', 'r_cut = '//real_str(self%r_cut)//': allowed (r_m = '// &
           real_str(self%r_m)//', 1e6] [a]')
    else if (trim(self%neighbour) == 'verlet' .and. self%skin <= 0) then
      call fail('steric', 'skin', 'skin = '//real_str(self%skin)//': allowed (0, 1000] [a] '// &
           'with neighbour = ''verlet''')
    else if (trim(self%neighbour) == 'verlet' .and. self%prune_skin >= self%skin) then
      call fail('steric', 'prune_skin', 'prune_skin = '//real_str(self%prune_skin)// &
           ': allowed [0, skin = '//real_str(self%skin)//') [a], or < 0 for automatic')
    else if (trim(self%contact) == 'surface' .and. self%l <= 2) then
      call fail('box', 'l', 'l = '//real_str(self%l)//': allowed (2, 1e6] [a] with &walls '// &
           'contact = ''surface'' (the centres stay a away from the walls)')
    else if ((trim(self%field_type) == 'standing_wave' .or. &
         trim(self%field_type) == 'travelling_wave') .and. self%fl%ex == 0 .and. &
         self%fl%ey == 0) then
      call fail('field', 'ex', 'ex = ey = 0: the wave''s force direction (ex, ey) must be '// &
           'non-zero')
    else if (trim(self%field_type) == 'table' .and. len_trim(self%field_file) == 0) then
      call fail('field', 'file', 'file: required with type = ''table'' (a tabulated field)')
    end if
    if (st%code /= 0) return
    ! peak memory, refused before anything is allocated: state, cells and a frame's buffer
    ! 280 B a particle; a Verlet list's pairs at most those of hexagonal packing at r_m
    ! within r_cut + skin, 8 B each (nbr, own) and 16 more pruned (pnbr, pown, the threaded
    ! prune's copies). Measured (RSS, n = 1e6, lj_lammps' liquid, 5.3 pairs a particle):
    ! 314 / 361 MB on 1 / 2 threads without pruning, 366 / 445 MB with; this gives 700 MB.
    ! A list's row sums (pair_forces' lj_rx, lj_ry): 16 B a particle more.
    mem = 280.0_dp
    if (self%steric_on .and. trim(self%neighbour) /= 'all_pairs') then
      mem = mem + 16
      pairs = 0.5_dp*acos(-1.0_dp)*(self%r_cut + self%skin)**2*(2.0_dp/sqrt(3.0_dp))/ &
           self%r_m**2
      mem = mem + 8*pairs
      if (trim(self%neighbour) == 'verlet' .and. self%prune_skin /= 0) mem = mem + 16*pairs
    end if
    call check_memory_need(mem*real(self%n, dp) + 32.0_dp*2.0_dp**20, trim(path)// &
         ': &particles n = '//int_str(self%n), 'reduce n', st)
    if (st%code /= 0) return
    self%fl%shape = choice_index(self%field_type, field_shapes) - 1       ! codes from 0
    self%fl%modulation = choice_index(self%modulation, field_modulations) - 1
  contains
    !> 'path: line N: &group msg' (the line of group%key when the file gives it).
    subroutine fail(group, key, msg)
      character(len=*), intent(in) :: group, key, msg
      character(len=:), allocatable :: where
      where = trim(path)//': '
      if (s%line_of(group, key) > 0) where = where//'line '// &
           int_str(int(s%line_of(group, key), i8))//': '
      call set_error(st, exit_bad_input, where//'&'//group//' '//msg)
    end subroutine fail
  end subroutine validate

  !> Derived quantities: the law, the field (table read), walls, the neighbour list.
  subroutine build(self, st)
    class(lj_box_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    real(dp) :: norm, need_lo, need_hi
    logical :: ok
    character(len=:), allocatable :: what
    associate (f => self%fl)
      if (f%shape == 3 .or. f%shape == 4) then   ! the direction in use; ex, ey stay as given
        norm = sqrt(f%ex**2 + f%ey**2)
        f%ux = f%ex/norm
        f%uy = f%ey/norm
      end if
      if (trim(self%contact) == 'surface') then
        self%lo = 1; self%hi = self%l - 1
      else
        self%lo = 0; self%hi = self%l
      end if
      if (trim(self%field_type) == 'table') then
        call field_read_table(f, trim(self%field_file), st)
        if (st%code /= 0) return
        call file_crc64(trim(self%field_file), self%table_crc, st)
        if (st%code /= 0) return
        need_lo = self%lo; need_hi = self%hi
        if (f%gx0 > need_lo .or. f%gx0 + (f%nx - 1)*f%gdx < need_hi .or. &
             f%gy0 > need_lo .or. f%gy0 + (f%ny - 1)*f%gdy < need_hi) then
          call set_error(st, exit_bad_input, '&field file = '''//trim(self%field_file)// &
               ''': the grid ['//real_str(f%gx0)//', '//real_str(f%gx0 + (f%nx - 1)*f%gdx)// &
               '] x ['//real_str(f%gy0)//', '//real_str(f%gy0 + (f%ny - 1)*f%gdy)// &
               '] [a] does not cover the reachable box ['//real_str(need_lo)//', '// &
               real_str(need_hi)//']^2')
          return
        end if
      end if
    end associate
    self%method = method_codes(choice_index(self%integrator, method_names))
    self%steric_on = trim(self%law) == 'lj'
    self%lj = lj_law(int(self%p), self%u0, self%r_m, self%r_cut)
    if (self%steric_on .and. eval_code(self%pair_eval) /= eval_exact) then
      if (eval_code(self%pair_eval) /= eval_table .and. self%p /= 6) then
        call set_error(st, exit_bad_input, '&steric pair_eval = '''//trim(self%pair_eval)// &
             ''': exists for p = 6 only (p = '//int_str(int(self%p, i8))//'); allowed for '// &
             'this p: exact, table')
        return
      end if
      call lj_eval_build(eval_code(self%pair_eval), self%lj, self%pair_table_error, &
           self%ljtab, ok)
      if (.not. ok) then
        what = 'pair_eval = '''//trim(self%pair_eval)//''''
        if (eval_code(self%pair_eval) == eval_table) what = 'the finest table, '// &
             int_str(2_i8**max_bits)//' segments per octave of r^2,'
        call set_error(st, exit_bad_input, '&steric pair_table_error = '// &
             real_str(self%pair_table_error)//': not reached over r in ['//real_str(self%r_m)// &
             ', '//real_str(self%r_cut)//'] a ('//what//' reaches '// &
             real_str(self%ljtab%max_err)//'); allowed ['//real_str(self%ljtab%max_err)//', 1e-2]')
        return
      end if
    end if
    self%strategy = neighbour_codes(choice_index(self%neighbour, neighbour_names))
    call init_threads()
    call state_allocate(self%s, int(self%n))
    if (self%steric_on .and. self%strategy /= nb_all_pairs) then
      call nlist_setup(self%nl, self%strategy, self%r_cut, self%skin, self%l, self%l, &
           int(self%n))
      self%nl%with_owner = .true.
      if (self%strategy == nb_verlet) &
           call nlist_set_prune(self%nl, self%prune_skin)
    end if
  end subroutine build

  !> Seeded positions (random sequential addition at min_distance, or a square lattice)
  !> and velocities (zero, a speed in uniform random directions, or Maxwellian at kT).
  subroutine initial_state(self, path, st)
    class(lj_box_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp), parameter :: two_pi = 6.283185307179586476925286766559_dp
    real(dp) :: u(2), span, a
    integer :: i, placed, m, side
    character(len=nm) :: rule
    call seed_rng(int(self%seed))
    associate (s => self%s)
      span = self%hi - self%lo
      if (len_trim(self%start_file) > 0) then
        call place_from_file(self, path, st)
        if (st%code /= 0) return
      else if (trim(self%placement) == 'lattice') then
        side = ceiling(sqrt(real(self%n, dp)) - 1.0e-9_dp)
        a = span/side
        if (a < self%min_distance) then
          call set_error(st, exit_bad_input, trim(path)//': &particles placement = '// &
               '''lattice'': spacing '//real_str(a)//' a < min_distance = '// &
               real_str(self%min_distance)//' (lower n or min_distance, or enlarge &box l)')
          return
        end if
        do i = 1, s%n
          s%x(i) = self%lo + (mod(i - 1, side) + 0.5_dp)*a
          s%y(i) = self%lo + ((i - 1)/side + 0.5_dp)*a
        end do
      else
        call random_addition(self, placed)
        if (placed < s%n) then
          call set_error(st, exit_bad_input, trim(path)//': &particles n = '// &
               int_str(self%n)//', min_distance = '//real_str(self%min_distance)// &
               ': random addition placed only '//int_str(int(placed, i8))//' particles in '// &
               'the box (lower n or min_distance, enlarge &box l, or placement = ''lattice'')')
          return
        end if
      end if
      rule = self%velocities
      if (self%start%has_velocity) rule = 'file'
      select case (trim(rule))
      case ('file')
        s%vx = self%start%vx; s%vy = self%start%vy
      case ('speed')
        do i = 1, s%n
          call random_number(u(1))
          s%vx(i) = self%speed*cos(two_pi*u(1))
          s%vy(i) = self%speed*sin(two_pi*u(1))
        end do
      case ('maxwell')
        do i = 1, s%n
          do m = 1, 2
            call random_number(u)
            u(1) = 1 - u(1)                ! (0, 1]
            a = sqrt(-2*log(u(1)))*sqrt(self%temperature)
            if (m == 1) then
              s%vx(i) = a*cos(two_pi*u(2))
            else
              s%vy(i) = a*cos(two_pi*u(2))
            end if
          end do
        end do
      case default
        s%vx = 0; s%vy = 0
      end select
      call start_release(self%start)
      s%mass = 1; s%mu = 1; s%wsin = 0
      s%step = 0
      s%t = 0
      s%has_previous = .false.
    end associate
    self%wall_hits = 0
  end subroutine initial_state

  !> &particles start_file: positions (and velocities) of its rows, particle k = row k.
  !> Refused, naming the line: what start_read refuses, a centre outside the reachable box
  !> [lo, hi]^2 (&walls contact), two centres closer than &particles min_distance.
  subroutine place_from_file(self, path, st)
    class(lj_box_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: where
    where = trim(path)//': &particles start_file = '''//trim(self%start_file)//''''
    call start_read(where, trim(self%start_file), 'lj_box', 'a', 'a/T', int(self%n), &
         [self%l, self%l], '&box l', 0, 1.0e6_dp, '&particles speed', self%start, st)
    if (st%code /= 0) return
    call start_check_region(self%start, [self%lo, self%lo], [self%hi, self%hi], 'a', &
         'the box the centres reach (&box l, &walls contact = '''//trim(self%contact)// &
         ''': with ''surface'' at least a from each wall)', st)
    if (st%code /= 0) return
    call start_check_distances(self%start, self%min_distance, 'a', '&particles min_distance', st)
    if (st%code /= 0) return
    self%s%x = self%start%x
    self%s%y = self%start%y
  end subroutine place_from_file

  !> Random sequential addition with a cell grid of side >= min_distance: each particle
  !> gets up to 20 000 tries. placed = how many found room.
  subroutine random_addition(self, placed)
    class(lj_box_t), intent(inout) :: self
    integer, intent(out) :: placed
    integer :: nc, i, tries, cx, cy, jx, jy, j
    integer, allocatable :: head(:), next(:)
    real(dp) :: u(2), span, cs, d2, xi, yi
    logical :: ok
    associate (s => self%s)
      span = self%hi - self%lo
      nc = max(1, min(4096, int(span/max(self%min_distance, 1.0e-300_dp))))
      cs = span/nc
      allocate(head(nc*nc), next(s%n))
      head = 0
      d2 = self%min_distance**2
      placed = 0
      do i = 1, s%n
        ok = .false.
        do tries = 1, 20000
          call random_number(u)
          xi = self%lo + span*u(1)
          yi = self%lo + span*u(2)
          cx = min(nc - 1, int((xi - self%lo)/cs))
          cy = min(nc - 1, int((yi - self%lo)/cs))
          ok = .true.
          do jy = max(0, cy - 1), min(nc - 1, cy + 1)
            do jx = max(0, cx - 1), min(nc - 1, cx + 1)
              j = head(1 + jx + nc*jy)
              do while (j > 0 .and. ok)
                if ((s%x(j) - xi)**2 + (s%y(j) - yi)**2 < d2) ok = .false.
                j = next(j)
              end do
            end do
          end do
          if (ok) exit
        end do
        if (.not. ok) return
        s%x(i) = xi
        s%y(i) = yi
        next(i) = head(1 + cx + nc*cy)
        head(1 + cx + nc*cy) = i
        placed = i
      end do
    end associate
  end subroutine random_addition

  !> Forces at the current step: steric pairs, field, drag [m g].
  subroutine forces(self)
    class(lj_box_t), intent(inout) :: self
    logical, parameter :: no_r3 = .false.
    associate (s => self%s, nl => self%nl)
      s%fx = 0
      s%fy = 0
      self%r2min = huge(1.0_dp)
      if (self%steric_on) then
        if (self%strategy == nb_all_pairs) then
          call pair_forces_all(s%n, s%x, s%y, s%mu, s%wsin, 1.0_dp, no_r3, s%fx, s%fy, &
               s%s3, self%r2min, law=self%lj, tab=self%ljtab)
        else
          ! the pruned list when there is one (nlist_t; the same bits as the whole list)
          call nlist_refresh(nl, s, nl%prune > 0)
          if (nlist_pruned(nl) .and. nl%prune > 0) then
            call nlist_force_start(nl)
            call pair_forces_list(s%n, s%x, s%y, s%mu, s%wsin, 1.0_dp, self%r_cut**2, &
                 0.0_dp, .true., no_r3, nl%start, nl%nbr, s%fx, s%fy, s%s3, self%r2min, &
                 law=self%lj, own=nl%own, tab=self%ljtab, pstart=nl%pstart, pnbr=nl%pnbr, &
                 pown=nl%pown)
            call nlist_force_done(nl)
          else
            call pair_forces_list(s%n, s%x, s%y, s%mu, s%wsin, 1.0_dp, self%r_cut**2, &
                 0.0_dp, .true., no_r3, nl%start, nl%nbr, s%fx, s%fy, s%s3, self%r2min, &
                 law=self%lj, own=nl%own, tab=self%ljtab)
          end if
          nl%evaluated = nl%evaluated + nl%pairs
        end if
      end if
      call field_add(self%fl, s%t, s%n, s%x, s%y, s%fx, s%fy)
      if (self%alpha > 0) call viscous_friction(s%n, s%mass, 4.5_dp*self%alpha, s%vx, s%vy, &
           s%fx, s%fy)
    end associate
  end subroutine forces

  !> Kinetic energy, steric and field potential energies [m g a] (velocities of the step).
  subroutine energies(self, ek, up, uf)
    class(lj_box_t), intent(in) :: self
    real(dp), intent(out) :: ek, up, uf
    associate (s => self%s)
      ek = 0.5_dp*sum(s%vx**2 + s%vy**2)
      up = 0
      if (self%steric_on) then
        if (self%strategy == nb_all_pairs) then
          up = lj_energy(s%n, s%x, s%y, self%lj)
        else
          up = lj_energy(s%n, s%x, s%y, self%lj, self%nl%start, self%nl%nbr)
        end if
      end if
      uf = field_potential(self%fl, s%t, s%n, s%x, s%y)
    end associate
  end subroutine energies

  !> The outputs of the scene (method_t's out): frames as text and/or binary, energies,
  !> the field on a grid.
  subroutine declare_outputs(self)
    class(lj_box_t), intent(inout) :: self
    call self%out%table(self%frames, 'frames.dat', '# frames.dat: Lennard-Jones box (seed '// &
         '000), one row per particle per frame. '//units, &
         '# step t[T] id type x[a] y[a] vx[a/T] vy[a/T]', &
         on=frames_as(self%frame_every, self%frames_format, 'text'))
    call self%out%frames(self%frames_bin, 'frames.bin', int(self%n), frame_cols, frame_units, &
         ['i4', 'i4', 'f8', 'f8', 'f8', 'f8'], 'step', 'T', '"kind": "lj_box", "box": ['// &
         json_real(self%l)//', '//json_real(self%l)//'], "radius": 1', &
         on=frames_as(self%frame_every, self%frames_format, 'binary'))
    call self%out%table(self%energy, 'energy.dat', &
         '# energy.dat: energies summed over the particles (u_field 0 for fields '// &
         'without a potential); wall_hits cumulative; r_min the closest listed pair. '// &
         units, '# step t[T] e_kin[mga] u_pair[mga] u_field[mga] wall_hits r_min[a]', &
         on=self%energy_every > 0)
    call self%out%table(self%field_out, 'field.dat', &
         '# field.dat: F_ext at the cell centres of a field_grid^2 grid over the box, at '// &
         'step 0 and, for a time-dependent field, at every frame. '//units, &
         '# step t[T] x[a] y[a] fx[mg] fy[mg]', on=self%field_grid > 0)
  end subroutine declare_outputs

  !> The rows of the current step that are due (forces already computed).
  subroutine write_rows(self, last, st)
    class(lj_box_t), intent(inout) :: self
    logical, intent(in) :: last
    type(status_t), intent(inout) :: st
    logical :: o_frm, o_en
    integer :: i, k
    integer, allocatable :: at(:)
    real(dp) :: ek, up, uf, rmin
    character(len=240) :: line
    if (.not. self%writing) return
    associate (s => self%s)
      o_frm = due(self%frame_every, s%step, last)
      o_en = due(self%energy_every, s%step, last)
      if (self%field_grid > 0 .and. (s%step == 0 .or. (o_frm .and. .not. &
           field_static(self%fl)))) call write_field(self, st)
      if (.not. (o_frm .or. o_en)) return
      call finish_velocity(self%method, self%dt, s)
      if (o_frm) then
        allocate(at(s%n))
        at(s%id) = [(k, k = 1, s%n)]          ! rows in particle-id order
        if (self%frames > 0) then
          do k = 1, s%n
            i = at(k)
            write(line, '(i0,1x,'//rfmt//',1x,i0,1x,i0,4(1x,'//rfmt//'))') s%step, s%t, &
                 s%id(i), self%type_id, s%x(i), s%y(i), s%vx(i), s%vy(i)
            call self%out%line(self%frames, trim(line), st)
          end do
        end if
        if (self%frames_bin > 0) then
          associate (o => self%out, b => self%frames_bin)
            call o%frame_begin(b, s%step, s%t, st)
            call o%frame_put(b, [(k, k = 1, s%n)], st)
            call o%frame_put(b, [(int(self%type_id), k = 1, s%n)], st)
            call o%frame_put(b, s%x(at), st)
            call o%frame_put(b, s%y(at), st)
            call o%frame_put(b, s%vx(at), st)
            call o%frame_put(b, s%vy(at), st)
            call o%frame_end(b, st)
          end associate
        end if
      end if
      if (o_en) then
        call energies(self, ek, up, uf)
        rmin = -1
        if (self%steric_on) rmin = sqrt(min(self%r2min, (self%r_cut + self%skin)**2))
        write(line, '(i0,4(1x,'//rfmt//'),1x,i0,1x,'//rfmt//')') s%step, s%t, ek, up, uf, &
             self%wall_hits, rmin
        call self%out%line(self%energy, trim(line), st)
      end if
    end associate
  end subroutine write_rows

  !> F_ext at the cell centres (i - 1/2) L/G, (j - 1/2) L/G of the grid, x fastest.
  subroutine write_field(self, st)
    class(lj_box_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    integer :: g, i, j, k
    real(dp), allocatable :: gx(:), gy(:), fx(:), fy(:)
    character(len=200) :: line
    g = int(self%field_grid)
    allocate(gx(g*g), gy(g*g), fx(g*g), fy(g*g))
    do j = 1, g
      do i = 1, g
        gx(i + g*(j - 1)) = (i - 0.5_dp)*self%l/g
        gy(i + g*(j - 1)) = (j - 0.5_dp)*self%l/g
      end do
    end do
    fx = 0; fy = 0
    call field_add(self%fl, self%s%t, g*g, gx, gy, fx, fy)
    do k = 1, g*g
      write(line, '(i0,5(1x,'//rfmt//'))') self%s%step, self%s%t, gx(k), gy(k), fx(k), fy(k)
      call self%out%line(self%field_out, trim(line), st)
    end do
  end subroutine write_field

  !> One time step: forces f_n, rows of step n, x_n -> x_{n+1}, walls, guards.
  subroutine advance(self, st)
    class(lj_box_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    integer :: bad
    associate (s => self%s)
      s%t = real(s%step, dp)*self%dt
      if (self%alpha > 0) call estimate_velocity(self%method, self%dt, s)
      call forces(self)
      call write_rows(self, .false., st)
      if (st%code /= 0) return
      call advance_step(self%method, self%dt, s)
      if (self%method == int_velocity_verlet) then   ! xp, yp carry v_{n+1/2}
        call mirror_reflect(s%n, s%x, s%y, s%xp, s%yp, self%lo, self%hi, self%gamma, &
             self%wall_hits, bad)
      else
        call mirror_reflect(s%n, s%x, s%y, s%vx, s%vy, self%lo, self%hi, self%gamma, &
             self%wall_hits, bad)
      end if
      s%step = s%step + 1
      s%t = real(s%step, dp)*self%dt
      if (bad > 0) call set_error(st, exit_numerical, 'lj_box: particle '// &
           int_str(int(s%id(bad), i8))//' left the box at step '//int_str(s%step)// &
           ' (x, y = '//real_str(s%x(bad))//', '//real_str(s%y(bad))//' a): it moved '// &
           'further than the box in one step or the state is not finite; &integration dt = '// &
           real_str(self%dt)//' T is too large for these forces (explicit Euler gains '// &
           'energy at every step: prefer semi_implicit_euler or velocity_verlet)')
    end associate
  end subroutine advance

  subroutine finish(self, st)
    class(lj_box_t), intent(inout) :: self
    type(status_t), intent(inout) :: st
    if (self%alpha > 0) call estimate_velocity(self%method, self%dt, self%s)
    call forces(self)
    call write_rows(self, .true., st)
  end subroutine finish

  !> The bed's payload (state, integrator history, neighbour list, RNG), then the wall
  !> hits, the field table's and the start file's CRC-64 (a changed file refuses the resume).
  subroutine save_state(self, w)
    class(lj_box_t), intent(in) :: self
    type(ckpt_writer_t), intent(inout) :: w
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    call checkpoint_save(w, self%s, self%nl, self%none)
    call ckpt_put(w, [transfer(self%wall_hits, b), transfer(self%table_crc, b), &
         transfer(self%start%crc, b)])
  end subroutine save_state

  subroutine restore_state(self, u, st)
    class(lj_box_t), intent(inout) :: self
    integer, intent(in) :: u
    type(status_t), intent(inout) :: st
    integer :: ios
    integer(i8) :: crc
    call checkpoint_restore(u, self%s, self%nl, self%none, st)
    if (st%code /= 0) return
    if (self%nl%valid) call nlist_owners(self%nl, self%s%n)
    read(u, iostat=ios) self%wall_hits, crc
    if (ios /= 0 .or. self%s%step < 0 .or. self%s%step > self%steps) then
      call set_error(st, exit_io, 'checkpoint: payload does not match the scene')
    else if (crc /= self%table_crc) then
      call set_error(st, exit_io, 'checkpoint: the field table '''//trim(self%field_file)// &
           ''' changed since the checkpoint (CRC-64 differs)')
    else
      call check_start_crc(u, self%start, st)
    end if
  end subroutine restore_state

  subroutine counters(self, done, total, t)
    class(lj_box_t), intent(in) :: self
    integer(i8), intent(out) :: done, total
    real(dp), intent(out) :: t
    done = self%s%step
    total = self%steps
    t = real(self%s%step, dp)*self%dt
  end subroutine counters

  function progress_text(self) result(s)
    class(lj_box_t), intent(in) :: self
    character(len=:), allocatable :: s
    character(len=30) :: buf
    write(buf, '(es11.4)') 0.5_dp*sum(self%s%vx**2 + self%s%vy**2)
    s = 'E_kin '//trim(adjustl(buf))
  end function progress_text

  function json_fields(self) result(text)
    class(lj_box_t), intent(in) :: self
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = achar(10)
    text = '  "n_particles": '//int_str(self%n)//','//nl// &
         '  "wall_hits": '//int_str(self%wall_hits)//','//nl// &
         '  "list_builds": '//int_str(self%nl%builds)//','//nl//nlist_prune_json(self%nl)// &
         '  "pairs_evaluated": '//int_str(self%nl%evaluated)//','//nl// &
         '  "field_conservative": '//trim(merge('true ', 'false', &
         field_has_potential(self%fl)))//','//nl// &
         '  "units": {"length": "a", "time": "T = sqrt(a/g)", "mass": "m", '// &
         '"force": "m g", "energy": "m g a"},'//nl//start_json(self%start)// &
         table_json(self%ljtab)
  end function json_fields

end module lj_box
