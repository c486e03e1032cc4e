!> Scene input: the namelist groups, their defaults, reading, validation and
!> the resolved-namelist writer.
!>
!> Units: group &material is in SI; every other length is in big-particle
!> diameters D1, every time in T = sqrt(D1/g), every speed in D1/T.
module scene
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, exit_io, exit_internal, msg_len
  use scene_input, only: printable, real_str, int_str
  use schema, only: schema_t
  use memory, only: check_memory_need
  use pair_table, only: eval_names
  implicit none
  private

  public :: scene_t, max_species, scene_keys, scene_read, scene_validate, scene_text

  integer, parameter :: max_species = 8
  integer(i8), parameter :: max_steps = 1000000000000_i8  !< 1e12 steps (about 3e3 years at 0.1 us/step)
  real(dp), parameter :: pi_ = 3.141592653589793_dp
  integer, parameter :: name_len = 32
  type :: scene_t
    ! &scene
    character(len=name_len) :: kind = 'magnet_bed'  !< scene kind
    character(len=128) :: title = 'untitled'        !< free text
    ! &material (SI)
    real(dp) :: diameter = 6.0e-3_dp    !< big-particle diameter D1 [m]
    real(dp) :: thickness = 3.0e-3_dp   !< magnet thickness epsilon [m]
    real(dp) :: density = 7368.0_dp     !< magnet density rho [kg/m^3]
    real(dp) :: remanence = 1.3_dp      !< residual magnetisation Br [T]
    real(dp) :: gap = 3.1e-3_dp         !< Hele-Shaw wall separation E [m]
    real(dp) :: gravity_si = 9.8_dp     !< g [m/s^2], also sets T = sqrt(D1/g)
    ! &cell [D1]
    real(dp) :: width = 60.0_dp         !< cell width W [D1]
    real(dp) :: height = 75.0_dp        !< cell height (fixed top) [D1]
    ! &particles
    integer :: n = 368                  !< number of particles
    integer :: seed = 12345             !< RNG seed of the initial condition
    real(dp) :: speed_init = 1.0e-2_dp  !< initial speed, random direction [D1/T]
    real(dp) :: jitter = 0.1_dp         !< grid perturbation, fraction of spacing
    real(dp) :: fill_height = -1.0_dp   !< top of the initial grid [D1] (<0: h_start)
    integer :: n_species = 1
    real(dp) :: species_diameter(max_species) = 1.0_dp  !< D_k / D1
    real(dp) :: mix_ratio = 0.0_dp      !< R: fraction of species 2 (bi-disperse)
    real(dp) :: species_fraction(max_species) = 0.0_dp  !< number fractions (n_species > 2)
    character(len=name_len) :: placement = 'interleave'  !< 'interleave' | 'random'
    character(len=512) :: start_file = ''  !< start from this file's frame (module start_file)
    ! &physics
    character(len=name_len) :: pair_law = 'dipole'        !< 'dipole' | 'none'
    character(len=name_len) :: wall_law = 'experimental'  !< 'experimental' | 'infinite' | 'slab' | 'none'
    logical :: gravity = .true.
    character(len=name_len) :: dry_friction = 'first_order'  !< 'none' | 'first_order' | 'second_order'
    real(dp) :: mu_static = 0.6_dp
    real(dp) :: mu_dynamic = 0.45_dp
    real(dp) :: v_threshold = 1.0e-6_dp  !< [D1/T]
    real(dp) :: viscous_gamma = 0.0_dp   !< dimensionless gamma T/m1; 0 = off
    real(dp) :: min_distance = 0.5_dp    !< guard: stop when two centres come closer [D1]; 0 = off
    character(len=name_len) :: tilt = 'eq_2_10'  !< tilt angle: 'eq_2_10' (with - phi) | 'eq_4_10' (without)
    ! &integration
    character(len=name_len) :: integrator = 'stormer_verlet'  !< | 'velocity_verlet' | 'euler'
    character(len=name_len) :: neighbour = 'all_pairs'  !< | 'cells' | 'verlet' | 'thesis'
    real(dp) :: dt = 2.0e-3_dp           !< time step [T]
    real(dp) :: r_cut = 7.13_dp          !< pair cut-off r_c [D1] (truncated strategies)
    real(dp) :: skin = 1.0_dp            !< Verlet skin r_v - r_c [D1]
    !> margin of the pruned list over r_c [D1] (verlet): < 0 automatic (nlist_upkeep nlist_margin), 0 none
    real(dp) :: prune_skin = -1.0_dp
    character(len=name_len) :: truncation = 'plain'  !< | 'shifted_force'
    character(len=name_len) :: tail = 'none'         !< | 'frozen' (far field every tail_every steps)
                                                     !< | 'linear' (and extrapolated in between)
    integer :: tail_every = 100
    real(dp) :: tail_switch = -1.0_dp    !< width of the smooth near/far hand-over below r_cut [D1]
                                         !< (<0: 0 = sharp for 'frozen', 1 D1 for 'linear')
    character(len=name_len) :: friction_velocity = 'lagged'  !< | 'implicit' (Verlet schemes)
    real(dp) :: target_rel_error = 0.0_dp  !< read by pyorch (bench table), ignored by the engine
    character(len=name_len) :: pair_eval = 'exact'   !< | 'table' | 'single' | 'rsqrt'
    real(dp) :: pair_table_error = 1.0e-6_dp  !< pair_eval /= 'exact': largest relative force error
    ! &protocol
    character(len=name_len) :: piston = 'prescribed'  !< 'prescribed' | 'fixed' | 'none'
    real(dp) :: h_start = -1.0_dp        !< piston height at t = 0 [D1] (<0: cell height)
    real(dp) :: t_relax = 100.0_dp       !< relaxation time [T]
    real(dp) :: relax_rate = 5.0_dp      !< steepness k of the exponential descent
    real(dp) :: h0 = -1.0_dp             !< compression start height [D1] (<0: h_start)
    real(dp) :: hf = 14.0_dp             !< maximum-compression height [D1]
    real(dp) :: phi_final = 0.0_dp       !< if > 0: hf from this packing fraction
    real(dp) :: hf_reference = 0.0_dp    !< if > 0: hf = hf_reference sum_k f_k (D_k/D1)^2 (eq. 4.23)
    real(dp) :: piston_speed = 0.02318_dp  !< [D1/T]
    real(dp) :: t_hold = 0.0_dp          !< rest at hf [T]
    logical :: expand = .true.           !< expand back to h0 after compression
    real(dp) :: t_final = 0.0_dp         !< final relaxation at h0 [T]
    real(dp) :: t_end = -1.0_dp          !< total time for piston = fixed|none [T]
    real(dp) :: piston_mass = 100.0_dp   !< free piston: mass [m1]
    real(dp) :: piston_gamma = 0.0_dp    !< free piston: viscous friction, force -gamma M v
    real(dp) :: t_settle = 50.0_dp       !< free piston, nudge > 0: longest wait for the settling [T]
    real(dp) :: nudge = 0.0_dp           !< free piston: lift once settled [D1]; 0 = record the fall
    real(dp) :: t_record = 20.0_dp       !< free piston: recorded motion (the fall, or after the nudge) [T]
    real(dp) :: settle_speed = 0.005_dp  !< free piston, nudge > 0: settled below this piston speed [D1/T]
    real(dp) :: settle_ekin = 1.0e-4_dp  !< ... and below this bed kinetic energy per particle [m1 g D1]
    real(dp) :: settle_hold = 25.0_dp    !< ... both held without a break for this long [T]
    ! &output (cadences in steps; 0 switches a file off)
    integer :: piston_every = 100
    integer :: frame_every = 0
    character(len=name_len) :: frames_format = 'text'   !< particles.dat | 'binary': particles.bin | 'both'
    integer :: distance_every = 1000
    integer :: energy_every = 0
    integer :: progress_every = 0        !< 0: about 200 progress lines per run
    integer :: checkpoint_every = 50000  !< steps between checkpoints; 0 = none
  end type scene_t

contains

  !> Smallest relative diameter D_k/D1 among the species the scene places (number fraction
  !> > 0: 1 - mix_ratio and mix_ratio for two species, species_fraction for more). A species
  !> with no particles (e.g. mix_ratio = 0) does not restrict the gap or the tilt law.
  pure real(dp) function present_d_min(sc) result(d)
    type(scene_t), intent(in) :: sc
    integer :: k, ns
    real(dp) :: f
    ns = max(1, min(sc%n_species, max_species))
    d = huge(1.0_dp)
    do k = 1, ns
      if (ns == 1) then
        f = 1
      else if (ns == 2) then
        f = merge(1.0_dp - sc%mix_ratio, sc%mix_ratio, k == 1)
      else
        f = sc%species_fraction(k)
      end if
      if (f > 0) d = min(d, sc%species_diameter(k))
    end do
    if (d == huge(1.0_dp)) d = minval(sc%species_diameter(1:ns))
  end function present_d_min

  !> The bed's scene, declared once (module schema): reading, validation of
  !> every key's range, scene.nml and `partsim --describe magnet_bed` come from it.
  subroutine scene_keys(sc, s)
    type(scene_t), intent(inout), target :: sc
    type(schema_t), intent(inout) :: s
    integer(i8), parameter :: big = huge(1)
    call s%init('magnet_bed', 'kind magnet_bed. Units: &material in SI; lengths in D1 '// &
         '(big-particle diameter), times in T = sqrt(D1/g), speeds in D1/T, masses in m1, '// &
         'forces in m1 g.')
    call s%group('scene', 'what this scene is', required=.true.)
    call s%key('kind', sc%kind, '', 'the method and system of this scene', choices='magnet_bed')
    call s%key('title', sc%title, '', 'free text (UTF-8)')
    call s%group('material', 'SI units')
    call s%key('diameter', sc%diameter, 'm', 'big-particle diameter D1 (the length unit)', &
         lo=1.0e-6_dp, hi=1.0_dp, lo_open=.true.)
    call s%key('thickness', sc%thickness, 'm', 'magnet thickness epsilon', lo=1.0e-7_dp, &
         hi=1.0_dp, lo_open=.true.)
    call s%key('density', sc%density, 'kg/m^3', 'magnet density rho', lo=1.0_dp, hi=1.0e5_dp, &
         lo_open=.true.)
    call s%key('remanence', sc%remanence, 'T', 'residual magnetisation Br', lo=0.0_dp, &
         hi=1.0e3_dp)
    call s%key('gap', sc%gap, 'm', 'Hele-Shaw wall separation E', lo=1.0e-7_dp, hi=1.0_dp, &
         lo_open=.true.)
    call s%key('gravity_si', sc%gravity_si, 'm/s^2', 'g; sets the time unit T = sqrt(D1/g)', &
         lo=1.0e-3_dp, hi=1.0e3_dp, lo_open=.true.)
    call s%group('cell', 'lengths in D1')
    call s%key('width', sc%width, 'D1', 'cell width W', lo=1.0_dp, hi=1.0e6_dp, lo_open=.true.)
    call s%key('height', sc%height, 'D1', 'cell height (fixed top)', lo=1.0_dp, hi=1.0e6_dp, &
         lo_open=.true.)
    call s%group('particles', 'the particles and their initial placement')
    call s%key('n', sc%n, '', 'number of particles', lo=1_i8, hi=50000000_i8)
    call s%key('seed', sc%seed, '', 'RNG seed of the initial condition')
    call s%key('speed_init', sc%speed_init, 'D1/T', 'initial speed, random direction', &
         lo=0.0_dp, hi=1.0e3_dp)
    call s%key('jitter', sc%jitter, '1', 'perturbation of the start grid, fraction of its '// &
         'spacing', lo=0.0_dp, hi=0.45_dp)
    call s%key('fill_height', sc%fill_height, 'D1', 'top of the start grid (< 0: h_start)')
    call s%key('n_species', sc%n_species, '', 'number of species', lo=1_i8, &
         hi=int(max_species, i8))
    call s%key('species_diameter', sc%species_diameter, 'D1', 'D_k/D1 (species 1 = 1)', &
         lo=0.05_dp, hi=1.0_dp, lo_open=.true.)
    call s%key('mix_ratio', sc%mix_ratio, '1', 'R: number fraction of species 2 (two '// &
         'species; interleaving rule floor(1/R), thesis 4.2.2)', lo=0.0_dp, hi=1.0_dp)
    call s%key('species_fraction', sc%species_fraction, '1', 'number fractions (n_species > 2)', &
         lo=0.0_dp, hi=1.0_dp)
    call s%key('placement', sc%placement, '', 'species on the grid', choices='interleave|random')
    call s%key('start_file', sc%start_file, '', 'start from this file (format: fortran/md/'// &
         'start_file.f90; pyorch scene start-file makes one from a GSD frame): positions, '// &
         'species and, if it has them, velocities [D1, D1/T]; the grid keys (seed: only for '// &
         'velocities it lacks) are then unused; a path relative to the working directory '// &
         '('''' = the grid)')
    call s%group('physics', 'each term switched by the scene')
    call s%key('pair_law', sc%pair_law, '', 'pair force: dipole repulsion (3/4) F mu_i mu_j '// &
         'r^-4 (eq. 4.3)', choices='dipole|none')
    call s%key('wall_law', sc%wall_law, '', 'magnetic side walls (eqs. 2.8, 3.3, 3.17)', &
         choices='experimental|infinite|slab|none')
    call s%key('gravity', sc%gravity, '', 'gravity m_i G')
    call s%key('dry_friction', sc%dry_friction, '', 'regularised Coulomb friction on the '// &
         'glass (eq. 4.5)', choices='none|first_order|second_order')
    call s%key('mu_static', sc%mu_static, '1', 'static friction coefficient', lo=0.0_dp, &
         hi=10.0_dp)
    call s%key('mu_dynamic', sc%mu_dynamic, '1', 'dynamic friction coefficient', lo=0.0_dp, &
         hi=10.0_dp)
    call s%key('v_threshold', sc%v_threshold, 'D1/T', 'regularisation speed of dry friction', &
         lo=1.0e-15_dp, hi=1.0_dp, lo_open=.true.)
    call s%key('viscous_gamma', sc%viscous_gamma, '1', 'viscous friction gamma T/m1 (0 = off)', &
         lo=0.0_dp, hi=1.0e6_dp)
    call s%key('min_distance', sc%min_distance, 'D1', 'guard: stop when two centres come '// &
         'closer (0 = off)', lo=0.0_dp, hi=1.0_dp)
    call s%key('tilt', sc%tilt, '', 'tilt angle: eq. 2.10 (with - phi) or the printed eq. '// &
         '4.10 (without)', choices='eq_2_10|eq_4_10')
    call s%group('integration', 'time stepping and pair evaluation')
    call s%key('integrator', sc%integrator, '', 'time integrator', &
         choices='stormer_verlet|velocity_verlet|euler')
    call s%key('neighbour', sc%neighbour, '', 'pair search: all pairs (reference), cell '// &
         'grid, Verlet list, or the thesis'' r_c = r_v list', choices='all_pairs|cells|verlet|thesis')
    call s%key('dt', sc%dt, 'T', 'time step', lo=1.0e-12_dp, hi=1.0_dp, lo_open=.true.)
    call s%key('r_cut', sc%r_cut, 'D1', 'pair cut-off r_c (truncated strategies; in '// &
         '(1, 1e4])')
    call s%key('skin', sc%skin, 'D1', 'Verlet skin r_v - r_c (in (0, 1e3])')
    call s%key('prune_skin', sc%prune_skin, 'D1', 'verlet: the list pruned to r_c + '// &
         'prune_skin, again when a particle moved prune_skin/2 (speed only: the same bits; '// &
         '< 0: automatic, chosen at every build, 0: off; in [0, skin))', lo=-1.0_dp, hi=1.0e3_dp)
    call s%key('truncation', sc%truncation, '', 'pair force at r_c', &
         choices='plain|shifted_force')
    call s%key('tail', sc%tail, '', 'far field r >= r_c: none, frozen every tail_every '// &
         'steps, or linearly extrapolated in time', choices='none|frozen|linear')
    call s%key('tail_every', sc%tail_every, 'steps', 'far-field refresh interval (>= 1)')
    call s%key('tail_switch', sc%tail_switch, 'D1', 'width of the smooth near/far hand-over '// &
         'below r_cut (< 0: 0 for frozen, 1 for linear)')
    call s%key('friction_velocity', sc%friction_velocity, '', 'velocity of the '// &
         'velocity-dependent forces: v_n ~ v_{n-1/2} + h a/2 (lagged) or solved at v_n '// &
         '(implicit, Verlet schemes)', choices='lagged|implicit')
    call s%key('target_rel_error', sc%target_rel_error, '1', 'read by pyorch: the cheapest '// &
         'measured setting meeting it (0 = off; the engine ignores it)', lo=0.0_dp, hi=1.0_dp)
    call s%key('pair_eval', sc%pair_eval, '', 'dipole force evaluation: exact (the '// &
         'reference), a table in r^2 (no sqrt, no division) built at load to '// &
         'pair_table_error, single precision pair arithmetic (double sums), or rsqrt (r^-1 '// &
         'by three Newton steps: no sqrt, no division)', choices=eval_names)
    call s%key('pair_table_error', sc%pair_table_error, '1', 'pair_eval /= exact: largest '// &
         'relative error of the pair force and r^-3 sums over [min_distance, the farthest '// &
         'pair] (measured at load; refused when not met)', lo=1.0e-15_dp, hi=1.0e-2_dp)
    call s%group('protocol', 'the piston (Algorithm 2.1); lengths in D1, times in T')
    call s%key('piston', sc%piston, '', 'prescribed schedule, fixed at h_start, none, or a '// &
         'free body', choices='prescribed|fixed|none|free')
    call s%key('h_start', sc%h_start, 'D1', 'piston height at t = 0 (< 0: cell height)')
    call s%key('t_relax', sc%t_relax, 'T', 'relaxation (exponential descent to h0)')
    call s%key('relax_rate', sc%relax_rate, '1', 'steepness k of the exponential descent')
    call s%key('h0', sc%h0, 'D1', 'compression start height (< 0: h_start)')
    call s%key('hf', sc%hf, 'D1', 'maximum-compression height')
    call s%key('phi_final', sc%phi_final, '1', 'if > 0: hf from this packing fraction')
    call s%key('hf_reference', sc%hf_reference, 'D1', 'if > 0: hf = hf_reference sum_k f_k '// &
         '(D_k/D1)^2 (eq. 4.23)')
    call s%key('piston_speed', sc%piston_speed, 'D1/T', 'compression and expansion speed')
    call s%key('t_hold', sc%t_hold, 'T', 'rest at hf')
    call s%key('expand', sc%expand, '', 'expand back to h0 after the compression')
    call s%key('t_final', sc%t_final, 'T', 'final relaxation at h0')
    call s%key('t_end', sc%t_end, 'T', 'run length for piston = fixed | none')
    call s%key('piston_mass', sc%piston_mass, 'm1', 'free piston: mass')
    call s%key('piston_gamma', sc%piston_gamma, '1', 'free piston: viscous friction, force '// &
         '-gamma M v')
    call s%key('t_settle', sc%t_settle, 'T', 'free piston, nudge > 0: longest wait for the '// &
         'settling')
    call s%key('nudge', sc%nudge, 'D1', 'free piston: lift once settled (0 = record the fall)')
    call s%key('t_record', sc%t_record, 'T', 'free piston: recorded motion')
    call s%key('settle_speed', sc%settle_speed, 'D1/T', 'free piston, nudge > 0: settled '// &
         'below this piston speed')
    call s%key('settle_ekin', sc%settle_ekin, 'm1 g D1', '... and below this bed kinetic '// &
         'energy per particle')
    call s%key('settle_hold', sc%settle_hold, 'T', '... both held without a break this long')
    call s%group('output', 'cadences in steps (0 = file off)')
    call s%key('piston_every', sc%piston_every, 'steps', 'piston.dat rows', lo=0_i8, hi=big)
    call s%key('frame_every', sc%frame_every, 'steps', 'particle frames', lo=0_i8, hi=big)
    call s%key('distance_every', sc%distance_every, 'steps', 'mean_distance.dat rows', &
         lo=0_i8, hi=big)
    call s%key('energy_every', sc%energy_every, 'steps', 'energy.dat rows', lo=0_i8, hi=big)
    call s%key('progress_every', sc%progress_every, 'steps', 'progress lines (0: about 200 '// &
         'per run)', lo=0_i8, hi=big)
    call s%key('checkpoint_every', sc%checkpoint_every, 'steps', 'checkpoints (0 = only at '// &
         'step 0)', lo=0_i8, hi=big)
    call s%key('frames_format', sc%frames_format, '', 'particles.dat (text), particles.bin '// &
         '(binary) or both', choices='text|binary|both')
  end subroutine scene_keys

  !> Read a scene file into `sc` (absent groups and keys keep their defaults;
  !> types and syntax checked, ranges by scene_validate).
  subroutine scene_read(path, sc, st)
    character(len=*), intent(in) :: path
    type(scene_t), intent(out), target :: sc
    type(status_t), intent(inout) :: st
    type(schema_t) :: s
    call scene_keys(sc, s)
    call s%read(path, st)
  end subroutine scene_read

  !> The resolved scene (every key, value, unit and meaning) as scene.nml text.
  function scene_text(sc) result(text)
    type(scene_t), intent(in) :: sc
    character(len=:), allocatable :: text
    type(scene_t), target :: copy
    type(schema_t) :: s
    copy = sc
    call scene_keys(copy, s)
    text = s%text()
  end function scene_text

  !> Check every value and every consistency rule; the first violation is
  !> reported as "FILE: &group key = value: allowed range".
  subroutine scene_validate(sc, path, st)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: hs, h0, hf, dmax
    type(scene_t), target :: copy
    type(schema_t) :: keys

    copy = sc
    call scene_keys(copy, keys)
    call keys%validate(path, st)
    if (st%code /= 0) return
    if (sc%species_diameter(1) /= 1.0_dp) call bad('particles', 'species_diameter(1)', &
         real_str(sc%species_diameter(1)), 'must be 1: species 1 defines D1 (the length unit)')
    if (sc%n_species == 1 .and. sc%mix_ratio /= 0.0_dp) call bad('particles', 'mix_ratio', &
         real_str(sc%mix_ratio), 'must be 0 when n_species = 1')
    if (sc%n_species > 2) then
      if (abs(sum(sc%species_fraction(1:sc%n_species)) - 1.0_dp) > 1.0e-9_dp) call bad( &
           'particles', 'species_fraction', real_str(sum(sc%species_fraction(1:sc%n_species))), &
           'the n_species number fractions must sum to 1')
    end if
    if (trim(sc%dry_friction) /= 'none') then
      ! every species present (fraction > 0) must be able to tilt against the glass (eq. 2.10)
      dmax = sqrt((sc%diameter*present_d_min(sc))**2 + sc%thickness**2)
      if (sc%gap <= sc%thickness .or. sc%gap >= dmax) call bad('material', 'gap', &
           real_str(sc%gap), 'with dry friction on, every magnet must be able to tilt: '// &
           'thickness < gap < sqrt(D_min^2 + thickness^2) = '//real_str(dmax)//' m')
      ! eq. 4.10 without - phi: phi + theta < 90 deg (a positive normal force, eq. 4.11)
      ! needs E/sqrt(D^2+eps^2) < cos(phi) = D/sqrt(D^2+eps^2), i.e. gap < D_min
      dmax = sc%diameter*present_d_min(sc)
      if (trim(sc%tilt) == 'eq_4_10' .and. sc%gap >= dmax) call bad('physics', 'tilt', &
           "'"//trim(sc%tilt)//"'", 'needs gap < smallest diameter = '//real_str(dmax)//' m (gap = '// &
           real_str(sc%gap)//' m: phi + theta >= 90 deg, the normal force of eq. 4.11 would be < 0)')
    end if

    if (trim(sc%friction_velocity) == 'implicit' .and. trim(sc%integrator) == 'euler') &
         call bad('integration', 'friction_velocity', "'implicit'", &
         "needs integrator = 'stormer_verlet' or 'velocity_verlet' (allowed with euler: 'lagged')")
    if (trim(sc%neighbour) /= 'all_pairs') then
      call rpos('integration', 'r_cut', sc%r_cut, 1.0_dp, 1.0e4_dp)
      call ipos('integration', 'tail_every', sc%tail_every, 1, huge(1))
      if (sc%tail_switch >= 0) call rpos('integration', 'tail_switch', &
           sc%tail_switch, 0.0_dp, 0.999_dp*sc%r_cut, .true.)
      if (trim(sc%neighbour) /= 'cells') &
           call rpos('integration', 'skin', sc%skin, 0.0_dp, 1.0e3_dp)
      if (trim(sc%neighbour) == 'verlet' .and. sc%prune_skin >= sc%skin) &
           call bad('integration', 'prune_skin', real_str(sc%prune_skin), 'allowed [0, skin = '// &
           real_str(sc%skin)//') D1, or < 0 for automatic')
    end if

    hs = sc%h_start
    if (hs < 0.0_dp) hs = sc%height
    h0 = sc%h0
    if (h0 < 0.0_dp) h0 = hs
    if (hs > sc%height .or. hs <= 1.0_dp) call bad('protocol', 'h_start', real_str(sc%h_start), &
         'must be in (1, cell height = '//real_str(sc%height)//'] D1 (negative: cell height)')
    if (trim(sc%piston) == 'prescribed') then
      call rpos('protocol', 't_relax', sc%t_relax, 0.0_dp, 1.0e9_dp, .true.)
      call rpos('protocol', 'relax_rate', sc%relax_rate, 1.0e-3_dp, 50.0_dp)
      if (h0 > hs .or. h0 <= 1.0_dp) call bad('protocol', 'h0', real_str(sc%h0), &
           'must be in (1, h_start = '//real_str(hs)//'] D1 (negative: h_start)')
      call rpos('protocol', 'phi_final', sc%phi_final, 0.0_dp, 0.9069_dp, .true.)
      call rpos('protocol', 'hf_reference', sc%hf_reference, 0.0_dp, h0, .true.)
      if (sc%phi_final > 0.0_dp .and. sc%hf_reference > 0.0_dp) call bad('protocol', &
           'hf_reference', real_str(sc%hf_reference), 'give phi_final or hf_reference, not both')
      hf = sc%hf
      if (sc%phi_final <= 0.0_dp .and. sc%hf_reference <= 0.0_dp .and. &
           (hf >= h0 .or. hf <= 0.0_dp)) call bad('protocol', 'hf', &
           real_str(sc%hf), 'must be in (0, h0 = '//real_str(h0)//') D1')
      call rpos('protocol', 'piston_speed', sc%piston_speed, 1.0e-9_dp, 1.0e3_dp)
      call rpos('protocol', 't_hold', sc%t_hold, 0.0_dp, 1.0e9_dp, .true.)
      call rpos('protocol', 't_final', sc%t_final, 0.0_dp, 1.0e9_dp, .true.)
    else if (trim(sc%piston) == 'free') then
      call rpos('protocol', 'piston_mass', sc%piston_mass, 0.0_dp, 1.0e9_dp)
      call rpos('protocol', 'piston_gamma', sc%piston_gamma, 0.0_dp, 1.0e6_dp, .true.)
      call rpos('protocol', 't_relax', sc%t_relax, 0.0_dp, 1.0e9_dp, .true.)
      call rpos('protocol', 't_settle', sc%t_settle, 0.0_dp, 1.0e9_dp, .true.)
      call rpos('protocol', 'nudge', sc%nudge, 0.0_dp, 1.0e3_dp, .true.)
      call rpos('protocol', 't_record', sc%t_record, 0.0_dp, 1.0e9_dp)
      call rpos('protocol', 'settle_speed', sc%settle_speed, 0.0_dp, 1.0e3_dp)
      call rpos('protocol', 'settle_ekin', sc%settle_ekin, 0.0_dp, 1.0e6_dp)
      call rpos('protocol', 'settle_hold', sc%settle_hold, 0.0_dp, 1.0e9_dp, .true.)
    else
      call rpos('protocol', 't_end', sc%t_end, 1.0e-12_dp, 1.0e9_dp)
    end if
    if (sc%fill_height > 0.0_dp .and. sc%fill_height > hs) call bad('particles', 'fill_height', &
         real_str(sc%fill_height), 'must be <= h_start = '//real_str(hs)//' D1')
    if (st%code /= 0) return
    call check_step_count(sc, hs, h0, path, st)
    if (st%code /= 0) return
    ! before anything is allocated: the start grid needs at least (1.05 D_max)^2 per particle
    ! (a start file is checked for overlaps instead)
    if (len_trim(sc%start_file) == 0 .and. real(sc%n, dp) > sc%width* &
         merge(sc%fill_height, hs, sc%fill_height > 0.0_dp)/1.05_dp**2) &
         call bad('particles', 'n', int_str(int(sc%n, i8)), 'particles cannot fit in the cell '// &
         'below the piston (at most '//int_str(int(sc%width*merge(sc%fill_height, hs, &
         sc%fill_height > 0.0_dp)/1.05_dp**2, i8))//' in '//real_str(sc%width)//' x '//real_str(merge(sc%fill_height, hs, &
         sc%fill_height > 0.0_dp))//' D1^2)')
    if (st%code /= 0) return
    call check_memory(sc, path, st)
    if (st%code /= 0) return

    if (sc%energy_every > 0 .and. trim(sc%wall_law) == 'slab') call bad('output', &
         'energy_every', int_str(int(sc%energy_every, i8)), 'must be 0 with wall_law = ''slab'' '// &
         '(the slab law has no closed-form potential)')

  contains

    subroutine bad(group, key, value, rule)
      character(len=*), intent(in) :: group, key, value, rule
      call set_error(st, exit_bad_input, trim(path)//': &'//group//' '//key//' = '// &
           printable(trim(value))//': '//rule)
    end subroutine bad

    subroutine rpos(group, key, v, lo, hi, lo_closed)
      character(len=*), intent(in) :: group, key
      real(dp), intent(in) :: v, lo, hi
      logical, intent(in), optional :: lo_closed
      logical :: closed, ok
      closed = .false.
      if (present(lo_closed)) closed = lo_closed
      if (closed) then
        ok = v >= lo .and. v <= hi
      else
        ok = v > lo .and. v <= hi
      end if
      if (.not. ok) then
        if (closed) then
          call bad(group, key, real_str(v), 'allowed range ['//real_str(lo)//', '//real_str(hi)//']')
        else
          call bad(group, key, real_str(v), 'allowed range ('//real_str(lo)//', '//real_str(hi)//']')
        end if
      end if
    end subroutine rpos

    subroutine ipos(group, key, v, lo, hi)
      character(len=*), intent(in) :: group, key
      integer, intent(in) :: v, lo, hi
      if (v < lo .or. v > hi) call bad(group, key, int_str(int(v, i8)), &
           'allowed range ['//int_str(int(lo, i8))//', '//int_str(int(hi, i8))//']')
    end subroutine ipos


  end subroutine scene_validate

  !> The run's step count must fit (64-bit counters, with a margin): an
  !> upper bound of the protocol duration over dt is at most max_steps.
  subroutine check_step_count(sc, hs, h0, path, st)
    type(scene_t), intent(in) :: sc
    real(dp), intent(in) :: hs, h0   !< resolved start and compression heights [D1]
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: t
    character(len=40) :: b
    select case (trim(sc%piston))
    case ('prescribed')
      t = sc%t_relax + sc%t_hold + sc%t_final + merge(2.0_dp, 1.0_dp, sc%expand)*h0/sc%piston_speed
    case ('free')
      t = sc%t_relax + sc%t_settle + sc%t_record
    case default
      t = sc%t_end
    end select
    if (hs < 0) return
    if (t/sc%dt > real(max_steps, dp)) then
      write(b, '(es9.2)') t/sc%dt
      call set_error(st, exit_bad_input, trim(path)//': &integration dt = '//real_str(sc%dt)// &
           ': the protocol lasts '//real_str(t)//' T, about '//trim(adjustl(b))//' steps; at '// &
           'most '//int_str(max_steps)//' steps are allowed (raise dt or shorten the protocol)')
    end if
  end subroutine check_step_count

  !> Estimated memory of a run [bytes]: per-particle state, neighbour list
  !> (dense packing within r_cut + skin), start-grid work arrays.
  real(dp) function memory_estimate(sc) result(bytes)
    type(scene_t), intent(in) :: sc
    real(dp) :: per, rv, dmin, pb
    ! state arrays, placement work arrays, frame writer, cell bins and checkpoint copies:
    ! measured 208 B per particle (max RSS 203 MB at n = 1e6, cells, r_cut 1.5), 240 B kept
    per = 240
    if (trim(sc%neighbour) /= 'all_pairs') then
      rv = sc%r_cut
      if (trim(sc%neighbour) /= 'cells') rv = rv + sc%skin
      dmin = minval(sc%species_diameter(1:max(1, min(sc%n_species, max_species))))
      ! half the neighbours within r_v at hexagonal packing of the smallest species: 8 B each
      ! (nbr, own), per particle xref, yref, start, cell_part, rowmax; the pruned list (only
      ! below 24 listed pairs per particle, its arrays with a quarter's room): 16 B a pair
      ! (pnbr, pown and the threaded prune's copies) and xpr, ypr, pstart
      pb = 0.5_dp*pi_*rv**2*(2.0_dp/sqrt(3.0_dp))/dmin**2
      per = per + 8*pb + 2*8 + 3*4
      if (trim(sc%neighbour) == 'verlet' .and. sc%prune_skin /= 0) &
           per = per + 16*min(pb, 30.0_dp) + 2*8 + 4
    end if
    bytes = real(sc%n, dp)*per + 16.0_dp*2.0_dp**20
  end function memory_estimate

  !> Refuse a scene whose memory estimate exceeds what this process may use (core/memory).
  subroutine check_memory(sc, path, st)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    call check_memory_need(memory_estimate(sc), trim(path)//': &particles n = '// &
         int_str(int(sc%n, i8)), 'reduce n', st)
  end subroutine check_memory

end module scene
