!> Scene input: the namelist groups, their defaults, reading, validation and
!> the resolved-namelist writer.
!>
!> Units: group &material is in SI; every other length is in big-particle
!> diameters D1, every time in T = sqrt(D1/g), every speed in D1/T.
module scene
  use kinds, only: dp
  use errors, only: status_t, set_error, exit_bad_input, exit_io, msg_len
  implicit none
  private

  public :: scene_t, max_species, scene_read, scene_validate, scene_write
  public :: known_groups

  integer, parameter :: max_species = 8
  integer, parameter :: name_len = 32
  character(len=*), parameter :: known_groups(8) = [character(len=12) :: &
       'scene', 'material', 'cell', 'particles', 'physics', 'integration', &
       'protocol', 'output']

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
    character(len=name_len) :: truncation = 'plain'  !< | 'shifted_force'
    character(len=name_len) :: tail = 'none'         !< | 'frozen' (far field every tail_every steps)
    integer :: tail_every = 100
    real(dp) :: target_rel_error = 0.0_dp  !< read by pyorch (bench table), ignored by the engine
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
    integer :: distance_every = 1000
    integer :: energy_every = 0
    integer :: progress_every = 0        !< 0: about 200 progress lines per run
    integer :: checkpoint_every = 50000  !< steps between checkpoints; 0 = none
  end type scene_t

contains

  !> Read every group of a namelist file into `sc` (absent groups keep defaults).
  subroutine scene_read(path, sc, st)
    character(len=*), intent(in) :: path
    type(scene_t), intent(out) :: sc
    type(status_t), intent(inout) :: st

    ! namelist variables (one local per key, defaults from scene_t)
    character(len=name_len) :: kind
    character(len=128) :: title
    real(dp) :: diameter, thickness, density, remanence, gap, gravity_si
    real(dp) :: width, height
    integer :: n, seed, n_species
    real(dp) :: speed_init, jitter, fill_height, species_diameter(max_species), mix_ratio
    real(dp) :: species_fraction(max_species), hf_reference
    character(len=name_len) :: placement
    character(len=name_len) :: pair_law, wall_law, dry_friction, tilt
    logical :: gravity
    real(dp) :: mu_static, mu_dynamic, v_threshold, viscous_gamma, min_distance
    character(len=name_len) :: integrator, neighbour, truncation, tail
    real(dp) :: dt, r_cut, skin, target_rel_error
    integer :: tail_every
    character(len=name_len) :: piston
    real(dp) :: h_start, t_relax, relax_rate, h0, hf, phi_final, piston_speed
    real(dp) :: t_hold, t_final, t_end, piston_mass, piston_gamma, t_settle, nudge, t_record
    real(dp) :: settle_speed, settle_ekin, settle_hold
    logical :: expand
    integer :: piston_every, frame_every, distance_every, energy_every, progress_every
    integer :: checkpoint_every

    namelist /scene/ kind, title
    namelist /material/ diameter, thickness, density, remanence, gap, gravity_si
    namelist /cell/ width, height
    namelist /particles/ n, seed, speed_init, jitter, fill_height, n_species, &
         species_diameter, mix_ratio, placement, species_fraction
    namelist /physics/ pair_law, wall_law, gravity, dry_friction, mu_static, &
         mu_dynamic, v_threshold, viscous_gamma, min_distance, tilt
    namelist /integration/ integrator, neighbour, dt, r_cut, skin, truncation, tail, &
         tail_every, target_rel_error
    namelist /protocol/ piston, h_start, t_relax, relax_rate, h0, hf, phi_final, hf_reference, &
         piston_speed, t_hold, expand, t_final, t_end, piston_mass, piston_gamma, t_settle, &
         nudge, t_record, settle_speed, settle_ekin, settle_hold
    namelist /output/ piston_every, frame_every, distance_every, energy_every, &
         progress_every, checkpoint_every

    integer :: u, ios
    character(len=msg_len) :: iom

    kind = sc%kind; title = sc%title
    diameter = sc%diameter; thickness = sc%thickness; density = sc%density
    remanence = sc%remanence; gap = sc%gap; gravity_si = sc%gravity_si
    width = sc%width; height = sc%height
    n = sc%n; seed = sc%seed; speed_init = sc%speed_init; jitter = sc%jitter
    fill_height = sc%fill_height; n_species = sc%n_species
    species_diameter = sc%species_diameter; mix_ratio = sc%mix_ratio
    species_fraction = sc%species_fraction; hf_reference = sc%hf_reference
    placement = sc%placement
    pair_law = sc%pair_law; wall_law = sc%wall_law; gravity = sc%gravity
    dry_friction = sc%dry_friction; mu_static = sc%mu_static; tilt = sc%tilt
    mu_dynamic = sc%mu_dynamic; v_threshold = sc%v_threshold
    viscous_gamma = sc%viscous_gamma; min_distance = sc%min_distance
    integrator = sc%integrator; neighbour = sc%neighbour; dt = sc%dt
    r_cut = sc%r_cut; skin = sc%skin; truncation = sc%truncation; tail = sc%tail
    tail_every = sc%tail_every; target_rel_error = sc%target_rel_error
    piston = sc%piston; h_start = sc%h_start; t_relax = sc%t_relax
    relax_rate = sc%relax_rate; h0 = sc%h0; hf = sc%hf; phi_final = sc%phi_final
    piston_speed = sc%piston_speed; t_hold = sc%t_hold; expand = sc%expand
    t_final = sc%t_final; t_end = sc%t_end
    piston_mass = sc%piston_mass; piston_gamma = sc%piston_gamma; t_settle = sc%t_settle
    nudge = sc%nudge; t_record = sc%t_record
    settle_speed = sc%settle_speed; settle_ekin = sc%settle_ekin; settle_hold = sc%settle_hold
    piston_every = sc%piston_every; frame_every = sc%frame_every
    distance_every = sc%distance_every; energy_every = sc%energy_every
    progress_every = sc%progress_every; checkpoint_every = sc%checkpoint_every

    open(newunit=u, file=path, status='old', action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot open scene file: '//trim(iom))
      return
    end if
    call check_groups(u, path, st)
    if (st%code /= 0) then
      close(u); return
    end if

    rewind(u); read(u, nml=scene, iostat=ios, iomsg=iom)
    call group_status('scene')
    rewind(u); read(u, nml=material, iostat=ios, iomsg=iom)
    call group_status('material')
    rewind(u); read(u, nml=cell, iostat=ios, iomsg=iom)
    call group_status('cell')
    rewind(u); read(u, nml=particles, iostat=ios, iomsg=iom)
    call group_status('particles')
    rewind(u); read(u, nml=physics, iostat=ios, iomsg=iom)
    call group_status('physics')
    rewind(u); read(u, nml=integration, iostat=ios, iomsg=iom)
    call group_status('integration')
    rewind(u); read(u, nml=protocol, iostat=ios, iomsg=iom)
    call group_status('protocol')
    rewind(u); read(u, nml=output, iostat=ios, iomsg=iom)
    call group_status('output')
    close(u)
    if (st%code /= 0) return

    sc%kind = kind; sc%title = title
    sc%diameter = diameter; sc%thickness = thickness; sc%density = density
    sc%remanence = remanence; sc%gap = gap; sc%gravity_si = gravity_si
    sc%width = width; sc%height = height
    sc%n = n; sc%seed = seed; sc%speed_init = speed_init; sc%jitter = jitter
    sc%fill_height = fill_height; sc%n_species = n_species
    sc%species_diameter = species_diameter; sc%mix_ratio = mix_ratio
    sc%species_fraction = species_fraction; sc%hf_reference = hf_reference
    sc%placement = placement
    sc%pair_law = pair_law; sc%wall_law = wall_law; sc%gravity = gravity
    sc%dry_friction = dry_friction; sc%mu_static = mu_static; sc%tilt = tilt
    sc%mu_dynamic = mu_dynamic; sc%v_threshold = v_threshold
    sc%viscous_gamma = viscous_gamma; sc%min_distance = min_distance
    sc%integrator = integrator; sc%neighbour = neighbour; sc%dt = dt
    sc%r_cut = r_cut; sc%skin = skin; sc%truncation = truncation; sc%tail = tail
    sc%tail_every = tail_every; sc%target_rel_error = target_rel_error
    sc%piston = piston; sc%h_start = h_start; sc%t_relax = t_relax
    sc%relax_rate = relax_rate; sc%h0 = h0; sc%hf = hf; sc%phi_final = phi_final
    sc%piston_speed = piston_speed; sc%t_hold = t_hold; sc%expand = expand
    sc%t_final = t_final; sc%t_end = t_end
    sc%piston_mass = piston_mass; sc%piston_gamma = piston_gamma; sc%t_settle = t_settle
    sc%nudge = nudge; sc%t_record = t_record
    sc%settle_speed = settle_speed; sc%settle_ekin = settle_ekin; sc%settle_hold = settle_hold
    sc%piston_every = piston_every; sc%frame_every = frame_every
    sc%distance_every = distance_every; sc%energy_every = energy_every
    sc%progress_every = progress_every; sc%checkpoint_every = checkpoint_every

  contains

    subroutine group_status(group)
      character(len=*), intent(in) :: group
      if (ios > 0) then
        call set_error(st, exit_bad_input, trim(path)//': &'//group// &
             ': cannot read group: '//trim(iom))
      end if
      ! ios < 0: group absent, defaults stand
    end subroutine group_status

  end subroutine scene_read

  !> Refuse unknown group names (a namelist read would silently skip them).
  subroutine check_groups(u, path, st)
    integer, intent(in) :: u
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    character(len=512) :: line, name
    integer :: ios, k, e
    rewind(u)
    do
      read(u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      line = adjustl(line)
      if (len_trim(line) < 2) cycle
      if (line(1:1) /= '&' .and. line(1:1) /= '$') cycle
      e = scan(line(2:), ' !/,') 
      if (e == 0) then
        name = line(2:)
      else
        name = line(2:e)
      end if
      name = lower(name)
      if (trim(name) == 'end' .or. len_trim(name) == 0) cycle
      if (.not. any([(trim(known_groups(k)) == trim(name), k = 1, size(known_groups))])) then
        call set_error(st, exit_bad_input, trim(path)//': unknown namelist group &'// &
             trim(name)//' (allowed: &scene &material &cell &particles &physics '// &
             '&integration &protocol &output)')
        return
      end if
    end do
  end subroutine check_groups

  !> Control and non-ASCII bytes shown as '?', so a message is one clean line.
  pure function printable(s) result(r)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: r
    integer :: i, c
    r = s
    do i = 1, len(s)
      c = iachar(s(i:i))
      if (c < 32 .or. c > 126) r(i:i) = '?'
    end do
  end function printable

  pure function lower(s) result(r)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: r
    integer :: i
    r = s
    do i = 1, len(s)
      if (s(i:i) >= 'A' .and. s(i:i) <= 'Z') r(i:i) = achar(iachar(s(i:i)) + 32)
    end do
  end function lower

  !> Check every value and every consistency rule; the first violation is
  !> reported as "FILE: &group key = value: allowed range".
  subroutine scene_validate(sc, path, st)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: hs, h0, hf, dmax
    integer :: k

    call choice('scene', 'kind', sc%kind, [character(len=name_len) :: 'magnet_bed'])
    call rpos('material', 'diameter', sc%diameter, 1.0e-6_dp, 1.0_dp)
    call rpos('material', 'thickness', sc%thickness, 1.0e-7_dp, 1.0_dp)
    call rpos('material', 'density', sc%density, 1.0_dp, 1.0e5_dp)
    call rpos('material', 'remanence', sc%remanence, 0.0_dp, 1.0e3_dp, .true.)
    call rpos('material', 'gap', sc%gap, 1.0e-7_dp, 1.0_dp)
    call rpos('material', 'gravity_si', sc%gravity_si, 1.0e-3_dp, 1.0e3_dp)
    call rpos('cell', 'width', sc%width, 1.0_dp, 1.0e6_dp)
    call rpos('cell', 'height', sc%height, 1.0_dp, 1.0e6_dp)
    call ipos('particles', 'n', sc%n, 1, 50000000)
    call rpos('particles', 'speed_init', sc%speed_init, 0.0_dp, 1.0e3_dp, .true.)
    call rpos('particles', 'jitter', sc%jitter, 0.0_dp, 0.45_dp, .true.)
    call ipos('particles', 'n_species', sc%n_species, 1, max_species)
    do k = 1, min(max(sc%n_species, 1), max_species)
      call rpos('particles', 'species_diameter', sc%species_diameter(k), 0.05_dp, 1.0_dp)
    end do
    if (st%code /= 0) return
    if (sc%species_diameter(1) /= 1.0_dp) call bad('particles', 'species_diameter(1)', &
         rstr(sc%species_diameter(1)), 'must be 1: species 1 defines D1 (the length unit)')
    call rpos('particles', 'mix_ratio', sc%mix_ratio, 0.0_dp, 1.0_dp, .true.)
    if (sc%n_species == 1 .and. sc%mix_ratio /= 0.0_dp) call bad('particles', 'mix_ratio', &
         rstr(sc%mix_ratio), 'must be 0 when n_species = 1')
    if (sc%n_species > 2) then
      do k = 1, sc%n_species
        call rpos('particles', 'species_fraction', sc%species_fraction(k), 0.0_dp, 1.0_dp, .true.)
      end do
      if (abs(sum(sc%species_fraction(1:sc%n_species)) - 1.0_dp) > 1.0e-9_dp) call bad( &
           'particles', 'species_fraction', rstr(sum(sc%species_fraction(1:sc%n_species))), &
           'the n_species number fractions must sum to 1')
    end if
    call choice('particles', 'placement', sc%placement, &
         [character(len=name_len) :: 'interleave', 'random'])

    call choice('physics', 'pair_law', sc%pair_law, [character(len=name_len) :: 'dipole', 'none'])
    call choice('physics', 'wall_law', sc%wall_law, &
         [character(len=name_len) :: 'experimental', 'infinite', 'slab', 'none'])
    call choice('physics', 'dry_friction', sc%dry_friction, &
         [character(len=name_len) :: 'none', 'first_order', 'second_order'])
    call rpos('physics', 'mu_static', sc%mu_static, 0.0_dp, 10.0_dp, .true.)
    call rpos('physics', 'mu_dynamic', sc%mu_dynamic, 0.0_dp, 10.0_dp, .true.)
    call rpos('physics', 'v_threshold', sc%v_threshold, 1.0e-15_dp, 1.0_dp)
    call rpos('physics', 'viscous_gamma', sc%viscous_gamma, 0.0_dp, 1.0e6_dp, .true.)
    call rpos('physics', 'min_distance', sc%min_distance, 0.0_dp, 1.0_dp, .true.)
    call choice('physics', 'tilt', sc%tilt, [character(len=name_len) :: 'eq_2_10', 'eq_4_10'])
    if (trim(sc%dry_friction) /= 'none') then
      ! every species must be able to tilt against the glass (eq. 2.10)
      dmax = sqrt((sc%diameter*minval(sc%species_diameter(1:max(1, min(sc%n_species, &
           max_species)))))**2 + sc%thickness**2)
      if (sc%gap <= sc%thickness .or. sc%gap >= dmax) call bad('material', 'gap', &
           rstr(sc%gap), 'with dry friction on, every magnet must be able to tilt: '// &
           'thickness < gap < sqrt(D_min^2 + thickness^2) = '//rstr(dmax)//' m')
    end if

    call choice('integration', 'integrator', sc%integrator, &
         [character(len=name_len) :: 'stormer_verlet', 'velocity_verlet', 'euler'])
    call choice('integration', 'neighbour', sc%neighbour, &
         [character(len=name_len) :: 'all_pairs', 'cells', 'verlet', 'thesis'])
    call rpos('integration', 'dt', sc%dt, 1.0e-12_dp, 1.0_dp)
    call choice('integration', 'truncation', sc%truncation, &
         [character(len=name_len) :: 'plain', 'shifted_force'])
    call choice('integration', 'tail', sc%tail, [character(len=name_len) :: 'none', 'frozen'])
    call rpos('integration', 'target_rel_error', sc%target_rel_error, 0.0_dp, 1.0_dp, .true.)
    if (trim(sc%neighbour) /= 'all_pairs') then
      call rpos('integration', 'r_cut', sc%r_cut, 1.0_dp, 1.0e4_dp)
      call ipos('integration', 'tail_every', sc%tail_every, 1, huge(1))
      if (trim(sc%neighbour) /= 'cells') &
           call rpos('integration', 'skin', sc%skin, 0.0_dp, 1.0e3_dp)
    end if

    call choice('protocol', 'piston', sc%piston, &
         [character(len=name_len) :: 'prescribed', 'fixed', 'none', 'free'])
    if (st%code /= 0) return
    hs = sc%h_start
    if (hs < 0.0_dp) hs = sc%height
    h0 = sc%h0
    if (h0 < 0.0_dp) h0 = hs
    if (hs > sc%height .or. hs <= 1.0_dp) call bad('protocol', 'h_start', rstr(sc%h_start), &
         'must be in (1, cell height = '//rstr(sc%height)//'] D1 (negative: cell height)')
    if (trim(sc%piston) == 'prescribed') then
      call rpos('protocol', 't_relax', sc%t_relax, 0.0_dp, 1.0e9_dp, .true.)
      call rpos('protocol', 'relax_rate', sc%relax_rate, 1.0e-3_dp, 50.0_dp)
      if (h0 > hs .or. h0 <= 1.0_dp) call bad('protocol', 'h0', rstr(sc%h0), &
           'must be in (1, h_start = '//rstr(hs)//'] D1 (negative: h_start)')
      call rpos('protocol', 'phi_final', sc%phi_final, 0.0_dp, 0.9069_dp, .true.)
      call rpos('protocol', 'hf_reference', sc%hf_reference, 0.0_dp, h0, .true.)
      if (sc%phi_final > 0.0_dp .and. sc%hf_reference > 0.0_dp) call bad('protocol', &
           'hf_reference', rstr(sc%hf_reference), 'give phi_final or hf_reference, not both')
      hf = sc%hf
      if (sc%phi_final <= 0.0_dp .and. sc%hf_reference <= 0.0_dp .and. &
           (hf >= h0 .or. hf <= 0.0_dp)) call bad('protocol', 'hf', &
           rstr(sc%hf), 'must be in (0, h0 = '//rstr(h0)//') D1')
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
         rstr(sc%fill_height), 'must be <= h_start = '//rstr(hs)//' D1')

    call ipos('output', 'piston_every', sc%piston_every, 0, huge(1))
    call ipos('output', 'frame_every', sc%frame_every, 0, huge(1))
    call ipos('output', 'distance_every', sc%distance_every, 0, huge(1))
    call ipos('output', 'energy_every', sc%energy_every, 0, huge(1))
    call ipos('output', 'progress_every', sc%progress_every, 0, huge(1))
    call ipos('output', 'checkpoint_every', sc%checkpoint_every, 0, huge(1))
    if (sc%energy_every > 0 .and. trim(sc%wall_law) == 'slab') call bad('output', &
         'energy_every', istr(sc%energy_every), 'must be 0 with wall_law = ''slab'' '// &
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
          call bad(group, key, rstr(v), 'allowed range ['//rstr(lo)//', '//rstr(hi)//']')
        else
          call bad(group, key, rstr(v), 'allowed range ('//rstr(lo)//', '//rstr(hi)//']')
        end if
      end if
    end subroutine rpos

    subroutine ipos(group, key, v, lo, hi)
      character(len=*), intent(in) :: group, key
      integer, intent(in) :: v, lo, hi
      if (v < lo .or. v > hi) call bad(group, key, istr(v), &
           'allowed range ['//istr(lo)//', '//istr(hi)//']')
    end subroutine ipos

    subroutine choice(group, key, v, allowed)
      character(len=*), intent(in) :: group, key, v
      character(len=*), intent(in) :: allowed(:)
      character(len=512) :: lst
      integer :: i
      if (any([(trim(allowed(i)) == trim(v), i = 1, size(allowed))])) return
      lst = ''
      do i = 1, size(allowed)
        lst = trim(lst)//' '''//trim(allowed(i))//''''
      end do
      call bad(group, key, ''''//trim(v)//'''', 'allowed values:'//trim(lst))
    end subroutine choice

  end subroutine scene_validate

  !> Shortest decimal text that reads back to exactly v (e.g. 0.5, -1, 1e-07).
  function rstr(v) result(s)
    real(dp), intent(in) :: v
    character(len=:), allocatable :: s
    character(len=40) :: b, fmt
    real(dp) :: w
    integer :: p, ios, e
    if (v /= v) then
      s = 'NaN'
      return
    end if
    if (abs(v) > huge(v)) then
      s = merge('+Infinity', '-Infinity', v > 0)
      return
    end if
    do p = 1, 17
      write(fmt, '(a,i0,a)') '(es30.', p - 1, 'e3)'
      write(b, fmt) v
      read(b, *, iostat=ios) w
      if (ios == 0 .and. w == v) exit
    end do
    b = adjustl(b)
    e = index(b, 'E')
    s = b(1:e - 1)
    if (index(s, '.') > 0) then       ! strip trailing zeros of the mantissa
      do while (s(len(s):len(s)) == '0')
        s = s(1:len(s) - 1)
      end do
      if (s(len(s):len(s)) == '.') s = s(1:len(s) - 1)
    end if
    read(b(e + 1:), *) p
    s = positional(s, p)
  contains
    !> mantissa text m (e.g. '-6.708') times 10^p, as 67.08 or 1e-07 style.
    function positional(m, p) result(r)
      character(len=*), intent(in) :: m
      integer, intent(in) :: p
      character(len=:), allocatable :: r, digits, sgn
      character(len=12) :: ex
      integer :: k
      sgn = ''
      digits = m
      if (m(1:1) == '-') then
        sgn = '-'
        digits = m(2:)
      end if
      k = index(digits, '.')
      if (k > 0) digits = digits(1:k - 1)//digits(k + 1:)
      if (p >= 0 .and. p < 15) then
        do while (len(digits) < p + 1)
          digits = digits//'0'
        end do
        if (len(digits) > p + 1) then
          r = sgn//digits(1:p + 1)//'.'//digits(p + 2:)
        else
          r = sgn//digits
        end if
      else if (p < 0 .and. p > -5) then
        r = sgn//'0.'//repeat('0', -p - 1)//digits
      else
        write(ex, '(i0)') p
        r = m//'e'//trim(ex)
      end if
    end function positional
  end function rstr

  function istr(v) result(s)
    integer, intent(in) :: v
    character(len=:), allocatable :: s
    character(len=20) :: b
    write(b, '(i0)') v
    s = trim(b)
  end function istr

  !> Write the fully resolved scene as a namelist the engine reads back
  !> bit-exactly (17 significant digits), with units as comments.
  subroutine scene_write(path, sc, st)
    character(len=*), intent(in) :: path
    type(scene_t), intent(in) :: sc
    type(status_t), intent(inout) :: st
    integer :: u, ios, k
    open(newunit=u, file=path, status='replace', action='write', iostat=ios)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot write resolved scene')
      return
    end if
    write(u, '(a)') '! resolved scene: every key with the value the engine used'
    write(u, '(a)') '&scene'
    call ps('kind', sc%kind, 'scene kind')
    call ps('title', sc%title, '')
    write(u, '(a)') '/'
    write(u, '(a)') '&material ! SI units'
    call pr('diameter', sc%diameter, 'm, big-particle diameter D1 (length unit)')
    call pr('thickness', sc%thickness, 'm, magnet thickness epsilon')
    call pr('density', sc%density, 'kg/m^3')
    call pr('remanence', sc%remanence, 'T, residual magnetisation Br')
    call pr('gap', sc%gap, 'm, Hele-Shaw wall separation E')
    call pr('gravity_si', sc%gravity_si, 'm/s^2, sets the time unit T = sqrt(D1/g)')
    write(u, '(a)') '/'
    write(u, '(a)') '&cell ! lengths in D1'
    call pr('width', sc%width, 'D1')
    call pr('height', sc%height, 'D1')
    write(u, '(a)') '/'
    write(u, '(a)') '&particles'
    call pi_('n', sc%n, '')
    call pi_('seed', sc%seed, '')
    call pr('speed_init', sc%speed_init, 'D1/T')
    call pr('jitter', sc%jitter, 'fraction of grid spacing')
    call pr('fill_height', sc%fill_height, 'D1 (<0: h_start)')
    call pi_('n_species', sc%n_species, '')
    do k = 1, sc%n_species
      write(u, '(2x,a,i0,a,es25.17e3)') 'species_diameter(', k, ') = ', sc%species_diameter(k)
    end do
    call pr('mix_ratio', sc%mix_ratio, 'fraction of species 2')
    do k = 1, sc%n_species
      if (sc%n_species > 2) write(u, '(2x,a,i0,a,es25.17e3)') 'species_fraction(', k, ') = ', &
           sc%species_fraction(k)
    end do
    call ps('placement', sc%placement, '')
    write(u, '(a)') '/'
    write(u, '(a)') '&physics'
    call ps('pair_law', sc%pair_law, '')
    call ps('wall_law', sc%wall_law, '')
    call pl('gravity', sc%gravity)
    call ps('dry_friction', sc%dry_friction, '')
    call pr('mu_static', sc%mu_static, '')
    call pr('mu_dynamic', sc%mu_dynamic, '')
    call pr('v_threshold', sc%v_threshold, 'D1/T')
    call pr('viscous_gamma', sc%viscous_gamma, 'dimensionless gamma*T/m1')
    call pr('min_distance', sc%min_distance, 'D1, guard (0 = off)')
    call ps('tilt', sc%tilt, 'eq_2_10: arcsin(E/sqrt(D^2+eps^2)) - phi; eq_4_10: without - phi')
    write(u, '(a)') '/'
    write(u, '(a)') '&integration'
    call ps('integrator', sc%integrator, '')
    call ps('neighbour', sc%neighbour, '')
    call pr('dt', sc%dt, 'T')
    call pr('r_cut', sc%r_cut, 'D1')
    call pr('skin', sc%skin, 'D1')
    call ps('truncation', sc%truncation, '')
    call ps('tail', sc%tail, '')
    call pi_('tail_every', sc%tail_every, '')
    call pr('target_rel_error', sc%target_rel_error, 'used by pyorch only')
    write(u, '(a)') '/'
    write(u, '(a)') '&protocol'
    call ps('piston', sc%piston, '')
    call pr('h_start', sc%h_start, 'D1')
    call pr('t_relax', sc%t_relax, 'T')
    call pr('relax_rate', sc%relax_rate, '')
    call pr('h0', sc%h0, 'D1')
    call pr('hf', sc%hf, 'D1')
    call pr('phi_final', sc%phi_final, '')
    call pr('hf_reference', sc%hf_reference, 'D1, eq. 4.23 (0 = off)')
    call pr('piston_speed', sc%piston_speed, 'D1/T')
    call pr('t_hold', sc%t_hold, 'T')
    call pl('expand', sc%expand)
    call pr('t_final', sc%t_final, 'T')
    call pr('t_end', sc%t_end, 'T')
    call pr('piston_mass', sc%piston_mass, 'm1 (free piston)')
    call pr('piston_gamma', sc%piston_gamma, 'free piston viscous friction')
    call pr('t_settle', sc%t_settle, 'T (free piston, nudge > 0: longest wait for settling)')
    call pr('nudge', sc%nudge, 'D1 (free piston; 0 = record the fall)')
    call pr('t_record', sc%t_record, 'T (free piston)')
    call pr('settle_speed', sc%settle_speed, 'D1/T (free piston, nudge > 0)')
    call pr('settle_ekin', sc%settle_ekin, 'm1 g D1 per particle (free piston, nudge > 0)')
    call pr('settle_hold', sc%settle_hold, 'T (free piston, nudge > 0)')
    write(u, '(a)') '/'
    write(u, '(a)') '&output ! cadences in steps, 0 = off'
    call pi_('piston_every', sc%piston_every, '')
    call pi_('frame_every', sc%frame_every, '')
    call pi_('distance_every', sc%distance_every, '')
    call pi_('energy_every', sc%energy_every, '')
    call pi_('progress_every', sc%progress_every, '')
    call pi_('checkpoint_every', sc%checkpoint_every, '')
    write(u, '(a)') '/'
    close(u)
  contains
    subroutine pr(key, v, note)
      character(len=*), intent(in) :: key, note
      real(dp), intent(in) :: v
      if (len(note) > 0) then
        write(u, '(2x,a,a,es25.17e3,a,a)') key, ' = ', v, ' ! ', note
      else
        write(u, '(2x,a,a,es25.17e3)') key, ' = ', v
      end if
    end subroutine pr
    subroutine pi_(key, v, note)
      character(len=*), intent(in) :: key, note
      integer, intent(in) :: v
      write(u, '(2x,a,a,i0)') key, ' = ', v
      if (len(note) > 0) continue
    end subroutine pi_
    subroutine ps(key, v, note)
      character(len=*), intent(in) :: key, v, note
      write(u, '(2x,a,a,a,a)') key, ' = ''', trim(v), ''''
      if (len(note) > 0) continue
    end subroutine ps
    subroutine pl(key, v)
      character(len=*), intent(in) :: key
      logical, intent(in) :: v
      if (v) then
        write(u, '(2x,a,a)') key, ' = .true.'
      else
        write(u, '(2x,a,a)') key, ' = .false.'
      end if
    end subroutine pl
  end subroutine scene_write

end module scene
