!> Scene input: the namelist groups, their defaults, reading, validation and
!> the resolved-namelist writer.
!>
!> Units: group &material is in SI; every other length is in big-particle
!> diameters D1, every time in T = sqrt(D1/g), every speed in D1/T.
module scene
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use, intrinsic :: iso_c_binding, only: c_int, c_long
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, exit_io, exit_internal, msg_len
  use scene_input, only: read_text, max_scene_bytes, printable, lower => lower_case
  implicit none
  private

  public :: scene_t, max_species, scene_read, scene_validate, scene_write, scene_text
  public :: known_groups

  integer, parameter :: max_species = 8
  integer(i8), parameter :: max_steps = 1000000000000_i8  !< 1e12 steps (about 3e3 years at 0.1 us/step)
  real(dp), parameter :: pi_ = 3.141592653589793_dp
  integer(c_int), parameter :: rlimit_data = 2, rlimit_as = 9   !< Linux resource numbers

  type, bind(C) :: rlimit_t
    integer(c_long) :: cur, max   !< rlim_t; RLIM_INFINITY reads as -1
  end type rlimit_t

  interface
    integer(c_int) function c_getrlimit(resource, rl) bind(C, name='getrlimit')
      import :: c_int, rlimit_t
      integer(c_int), value :: resource
      type(rlimit_t), intent(out) :: rl
    end function c_getrlimit
  end interface
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
                                                     !< | 'linear' (and extrapolated in between)
    integer :: tail_every = 100
    real(dp) :: tail_switch = -1.0_dp    !< width of the smooth near/far hand-over below r_cut [D1]
                                         !< (<0: 0 = sharp for 'frozen', 1 D1 for 'linear')
    character(len=name_len) :: friction_velocity = 'lagged'  !< | 'implicit' (Verlet schemes)
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
    character(len=name_len) :: integrator, neighbour, truncation, tail, friction_velocity
    real(dp) :: dt, r_cut, skin, target_rel_error, tail_switch
    integer :: tail_every
    character(len=name_len) :: piston
    real(dp) :: h_start, t_relax, relax_rate, h0, hf, phi_final, piston_speed
    real(dp) :: t_hold, t_final, t_end, piston_mass, piston_gamma, t_settle, nudge, t_record
    real(dp) :: settle_speed, settle_ekin, settle_hold
    logical :: expand
    integer :: piston_every, frame_every, distance_every, energy_every, progress_every
    integer :: checkpoint_every
    character(len=name_len) :: frames_format

    namelist /scene/ kind, title
    namelist /material/ diameter, thickness, density, remanence, gap, gravity_si
    namelist /cell/ width, height
    namelist /particles/ n, seed, speed_init, jitter, fill_height, n_species, &
         species_diameter, mix_ratio, placement, species_fraction
    namelist /physics/ pair_law, wall_law, gravity, dry_friction, mu_static, &
         mu_dynamic, v_threshold, viscous_gamma, min_distance, tilt
    namelist /integration/ integrator, neighbour, dt, r_cut, skin, truncation, tail, &
         tail_every, tail_switch, friction_velocity, target_rel_error
    namelist /protocol/ piston, h_start, t_relax, relax_rate, h0, hf, phi_final, hf_reference, &
         piston_speed, t_hold, expand, t_final, t_end, piston_mass, piston_gamma, t_settle, &
         nudge, t_record, settle_speed, settle_ekin, settle_hold
    namelist /output/ piston_every, frame_every, distance_every, energy_every, &
         progress_every, checkpoint_every, frames_format

    character(len=:), allocatable :: text
    integer :: pos, line, nkeys
    logical :: kind_given
    character(len=:), allocatable :: assigned
    integer, parameter :: max_keys = 64
    character(len=32) :: kname(max_keys)
    character :: ktype(max_keys)
    integer :: ksize(max_keys), klen(max_keys)

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
    tail_switch = sc%tail_switch; friction_velocity = sc%friction_velocity
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
    frames_format = sc%frames_format

    call read_text(path, text, st)
    if (st%code /= 0) return
    call parse_file()
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
    sc%tail_switch = tail_switch; sc%friction_velocity = friction_velocity
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
    sc%frames_format = frames_format

  contains

    ! One reading of the file, shared by both doors: this tokenizer knows
    ! quotes and comments, finds every group, refuses anything ambiguous
    ! (text outside groups, unknown or repeated groups and keys, unclosed
    ! groups, wrong types, non-finite reals, repeat counts), and hands each
    ! checked assignment alone to gfortran's namelist read. The keys and
    ! their types come from the namelist groups themselves (a namelist write
    ! of the defaults), so a new key needs no table here.

    subroutine parse_file()
      integer :: g, gl(size(known_groups))
      logical :: seen(size(known_groups))
      character(len=64) :: name
      pos = 1
      line = 1
      seen = .false.
      gl = 0
      kind_given = .false.
      do
        call skip_blank()
        if (pos > len(text)) exit
        if (text(pos:pos) /= '&') then
          call fail('text outside a group: '''//snippet()//''' (a scene is a sequence of '// &
               '&group ... / blocks and ! comments)')
          return
        end if
        pos = pos + 1
        name = lower(ident())
        g = group_index(name)
        if (g == 0) then
          if (len_trim(name) == 0) then
            call fail('''&'' without a group name')
          else
            call fail('unknown namelist group &'//trim(printable(name))//' (allowed: &scene '// &
                 '&material &cell &particles &physics &integration &protocol &output)')
          end if
          return
        end if
        if (seen(g)) then
          call fail('group &'//trim(name)//' given twice (first at line '//istr(gl(g))// &
               '): give each group once')
          return
        end if
        seen(g) = .true.
        gl(g) = line
        call parse_group(g)
        if (st%code /= 0) return
      end do
      if (.not. any(seen)) then
        call set_error(st, exit_bad_input, trim(path)//': no namelist group: a scene file '// &
             'names its kind (&scene kind = ''magnet_bed'' /) and holds its groups')
      else if (.not. kind_given) then
        call set_error(st, exit_bad_input, trim(path)//': the scene does not name its kind: '// &
             'add &scene kind = ''magnet_bed'' /')
      end if
    end subroutine parse_file

    !> One group: assignments until '/'.
    subroutine parse_group(g)
      integer, intent(in) :: g
      integer :: start_line, kline, idx, nv, kk, first
      character(len=64) :: key
      character(len=:), allocatable :: vals, tok
      character(len=32) :: grp
      grp = known_groups(g)
      start_line = line
      call schema(g)
      if (st%code /= 0) return
      assigned = ''
      do
        call skip_blank()
        if (pos > len(text)) then
          call fail('group &'//trim(grp)//' (line '//istr(start_line)//') is not closed '// &
               'with ''/''')
          return
        end if
        if (text(pos:pos) == '/') then
          pos = pos + 1
          return
        end if
        if (text(pos:pos) == '&') then
          call fail('group &'//trim(grp)//' (line '//istr(start_line)//') is not closed '// &
               'with ''/'' before the next group')
          return
        end if
        if (text(pos:pos) == ',') then
          pos = pos + 1
          cycle
        end if
        kline = line
        key = lower(ident())
        if (len_trim(key) == 0) then
          call fail('&'//trim(grp)//': expected key = value, found '''//snippet()//'''')
          return
        end if
        kk = key_index(key)
        if (kk == 0) then
          call fail('&'//trim(grp)//': unknown key '''//trim(printable(key))//''' (keys: '// &
               key_list()//')')
          return
        end if
        idx = 0
        call skip_spaces()
        if (peek() == '(') then
          pos = pos + 1
          call skip_spaces()
          tok = digit_run()
          call skip_spaces()
          if (len(tok) == 0 .or. len(tok) > 6 .or. peek() /= ')') then
            call fail('&'//trim(grp)//' '//trim(key)//'(: the index must be a whole '// &
                 'number, e.g. '//trim(key)//'(2)')
            return
          end if
          read(tok, *) idx
          pos = pos + 1
          if (ksize(kk) == 1) then
            call fail('&'//trim(grp)//' '//trim(key)//'('//tok//'): '//trim(key)// &
                 ' is not an array')
            return
          end if
          if (idx < 1 .or. idx > ksize(kk)) then
            call fail('&'//trim(grp)//' '//trim(key)//'('//tok//'): index out of range [1, '// &
                 istr(ksize(kk))//']')
            return
          end if
          call skip_spaces()
        end if
        if (peek() /= '=') then
          call fail('&'//trim(grp)//' '//trim(key)//': expected ''='' after the key, found '''// &
               snippet()//'''')
          return
        end if
        pos = pos + 1
        vals = ''
        nv = 0
        do
          call skip_blank()
          if (nv > 0) then
            if (peek() == ',') then
              pos = pos + 1
              call skip_blank()
            end if
          end if
          if (pos > len(text)) exit
          if (index('/&,', text(pos:pos)) > 0) exit
          if (nv > 0 .and. next_is_key()) exit
          call value_token(tok)
          if (st%code /= 0) return
          call check_value(grp, key, kk, tok, kline)
          if (st%code /= 0) return
          nv = nv + 1
          if (nv > 1) vals = vals//', '
          vals = vals//tok
        end do
        if (nv == 0) then
          call fail_at(kline, '&'//trim(grp)//' '//trim(key)//' = : no value (give a value '// &
               'or leave the key out for its default)')
          return
        end if
        first = max(idx, 1)
        if (first + nv - 1 > ksize(kk)) then
          if (ksize(kk) == 1) then
            call fail_at(kline, '&'//trim(grp)//' '//trim(key)//' = '//printable(vals)// &
                 ': one value expected')
          else
            call fail_at(kline, '&'//trim(grp)//' '//trim(key)//' = '//printable(vals)// &
                 ': at most '//istr(ksize(kk) - first + 1)//' values from index '//istr(first))
          end if
          return
        end if
        call mark_assigned(grp, key, first, nv, kline)
        if (st%code /= 0) return
        if (g == 1 .and. trim(key) == 'kind') kind_given = .true.
        if (idx > 0) then
          call nml_read(g, '&'//trim(grp)//' '//trim(key)//'('//istr(idx)//') = '//vals// &
               ' /', kline)
        else
          call nml_read(g, '&'//trim(grp)//' '//trim(key)//' = '//vals//' /', kline)
        end if
        if (st%code /= 0) return
      end do
    end subroutine parse_group

    !> Record key(first..first+nv-1) as given; a second assignment is refused.
    subroutine mark_assigned(grp, key, first, nv, kline)
      character(len=*), intent(in) :: grp, key
      integer, intent(in) :: first, nv, kline
      integer :: i
      character(len=80) :: tag
      do i = first, first + nv - 1
        write(tag, '(a,a,i0,a)') trim(key), '(', i, ')'
        if (index(assigned, ' '//trim(tag)//' ') > 0) then
          call fail_at(kline, '&'//trim(grp)//' '//trim(key)//': given twice in the group')
          return
        end if
        assigned = assigned//' '//trim(tag)//' '
      end do
    end subroutine mark_assigned

    !> The value's type must be the key's: integer, finite real, logical, or a
    !> quoted string no longer than the key holds.
    subroutine check_value(grp, key, kk, tok, kline)
      character(len=*), intent(in) :: grp, key, tok
      integer, intent(in) :: kk, kline
      integer :: ios, m
      integer(i8) :: iv
      real(dp) :: rv
      character(len=:), allocatable :: what, low
      what = '&'//trim(grp)//' '//trim(key)//' = '//printable(tok)//': '
      low = lower(tok)
      if (index(tok, '*') > 0 .and. tok(1:1) /= '''' .and. tok(1:1) /= '"') then
        call fail_at(kline, what//'repeat counts (r*value) are not accepted: write the values out')
        return
      end if
      select case (ktype(kk))
      case ('i')
        m = 1
        if (index('+-', tok(1:1)) > 0) m = 2
        if (len(tok) < m) then
          call fail_at(kline, what//'must be an integer')
          return
        end if
        if (verify(tok(m:), '0123456789') /= 0) then
          call fail_at(kline, what//'must be an integer')
          return
        end if
        iv = 0
        ios = 1
        if (len(tok) <= 18) read(tok, *, iostat=ios) iv
        if (ios /= 0 .or. abs(iv) > int(huge(1), i8)) then
          call fail_at(kline, what//'integer out of range [-'//istr(huge(1))//', '// &
               istr(huge(1))//']')
          return
        end if
      case ('r')
        if (verify(low, '0123456789+-.ed') /= 0 .or. scan(low, '0123456789') == 0) then
          if (index(low, 'nan') > 0 .or. index(low, 'inf') > 0) then
            call fail_at(kline, what//'must be a finite number')
          else
            call fail_at(kline, what//'must be a number')
          end if
          return
        end if
        read(tok, *, iostat=ios) rv
        if (ios /= 0) then
          call fail_at(kline, what//'must be a number')
        else if (.not. ieee_is_finite(rv)) then
          call fail_at(kline, what//'must be a finite number (it overflows)')
        end if
      case ('l')
        select case (low)
        case ('.true.', '.false.', 't', 'f', '.t.', '.f.', 'true', 'false')
        case default
          call fail_at(kline, what//'must be .true. or .false.')
        end select
      case ('c')
        if (tok(1:1) /= '''' .and. tok(1:1) /= '"') then
          call fail_at(kline, what//'must be a quoted string, e.g. '''//printable(tok)//'''')
        else if (len(tok) - 2 - count_doubled(tok) > klen(kk)) then
          call fail_at(kline, what//'longer than '//istr(klen(kk))//' characters')
        end if
      end select
    end subroutine check_value

    integer function count_doubled(tok)
      character(len=*), intent(in) :: tok
      integer :: i
      count_doubled = 0
      i = 2
      do while (i < len(tok))
        if (tok(i:i) == tok(1:1)) then
          count_doubled = count_doubled + 1
          i = i + 1
        end if
        i = i + 1
      end do
    end function count_doubled

    !> One value: a quoted string (quotes doubled inside), or a run of
    !> characters up to a blank, ',', '/', '!', '&' or '='.
    subroutine value_token(tok)
      character(len=:), allocatable, intent(out) :: tok
      integer :: p0
      character :: q
      p0 = pos
      q = text(pos:pos)
      tok = ''
      if (q == '''' .or. q == '"') then
        pos = pos + 1
        do
          if (pos > len(text)) then
            call fail('string not closed: '''//printable(text(p0:min(p0 + 30, len(text))))//'''')
            return
          end if
          if (text(pos:pos) == achar(10)) then
            call fail('string not closed on its line: '''//printable(text(p0:pos - 1))//'''')
            return
          end if
          if (text(pos:pos) == q) then
            if (pos < len(text)) then
              if (text(pos + 1:pos + 1) == q) then
                pos = pos + 2
                cycle
              end if
            end if
            pos = pos + 1
            exit
          end if
          pos = pos + 1
        end do
        tok = text(p0:pos - 1)
        return
      end if
      do while (pos <= len(text))
        if (index(' ,/!&='//achar(9)//achar(10)//achar(13), text(pos:pos)) > 0) exit
        if (iachar(text(pos:pos)) > 126 .or. text(pos:pos) == '''' .or. &
             text(pos:pos) == '"' .or. text(pos:pos) == '(' .or. text(pos:pos) == ')') then
          call fail('unexpected character in a value: '''//snippet()//'''')
          return
        end if
        pos = pos + 1
      end do
      tok = text(p0:pos - 1)
      if (len(tok) == 0) call fail('expected a value, found '''//snippet()//'''')
    end subroutine value_token

    !> Does an identifier followed by '=' or '(' start at pos (a new key)?
    logical function next_is_key()
      integer :: p
      p = pos
      next_is_key = .false.
      if (p > len(text)) return
      if (.not. is_alpha(text(p:p))) return
      do while (p <= len(text))
        if (.not. (is_alpha(text(p:p)) .or. index('0123456789', text(p:p)) > 0)) exit
        p = p + 1
      end do
      do while (p <= len(text))
        if (text(p:p) /= ' ' .and. text(p:p) /= achar(9)) exit
        p = p + 1
      end do
      if (p > len(text)) return
      next_is_key = text(p:p) == '=' .or. text(p:p) == '('
    end function next_is_key

    logical function is_alpha(c)
      character, intent(in) :: c
      is_alpha = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z') .or. c == '_'
    end function is_alpha

    !> An identifier at pos (letters, digits, '_'), possibly empty.
    function ident() result(r)
      character(len=:), allocatable :: r
      integer :: p0
      p0 = pos
      if (pos <= len(text)) then
        if (is_alpha(text(pos:pos))) then
          do while (pos <= len(text))
            if (.not. (is_alpha(text(pos:pos)) .or. index('0123456789', text(pos:pos)) > 0)) exit
            pos = pos + 1
          end do
        end if
      end if
      r = text(p0:pos - 1)
    end function ident

    function digit_run() result(r)
      character(len=:), allocatable :: r
      integer :: p0
      p0 = pos
      do while (pos <= len(text))
        if (index('0123456789', text(pos:pos)) == 0) exit
        pos = pos + 1
      end do
      r = text(p0:pos - 1)
    end function digit_run

    character function peek()
      peek = achar(0)
      if (pos <= len(text)) peek = text(pos:pos)
    end function peek

    subroutine skip_spaces()
      do while (pos <= len(text))
        if (text(pos:pos) /= ' ' .and. text(pos:pos) /= achar(9)) exit
        pos = pos + 1
      end do
    end subroutine skip_spaces

    !> Skip blanks, newlines and ! comments (comments may hold any text).
    subroutine skip_blank()
      do while (pos <= len(text))
        select case (text(pos:pos))
        case (' ', achar(9), achar(13))
          pos = pos + 1
        case (achar(10))
          pos = pos + 1
          line = line + 1
        case ('!')
          do while (pos <= len(text))
            if (text(pos:pos) == achar(10)) exit
            pos = pos + 1
          end do
        case default
          exit
        end select
      end do
    end subroutine skip_blank

    !> Up to 30 characters from pos, for messages.
    function snippet() result(r)
      character(len=:), allocatable :: r
      integer :: e
      e = pos
      do while (e <= len(text) .and. e < pos + 30)
        if (text(e:e) == achar(10)) exit
        e = e + 1
      end do
      r = printable(text(pos:e - 1))
    end function snippet

    subroutine fail(msg)
      character(len=*), intent(in) :: msg
      call fail_at(line, msg)
    end subroutine fail

    subroutine fail_at(l, msg)
      integer, intent(in) :: l
      character(len=*), intent(in) :: msg
      call set_error(st, exit_bad_input, trim(path)//': line '//istr(l)//': '//msg)
    end subroutine fail_at

    integer function group_index(name)
      character(len=*), intent(in) :: name
      integer :: k
      group_index = 0
      do k = 1, size(known_groups)
        if (trim(known_groups(k)) == trim(name)) group_index = k
      end do
    end function group_index

    integer function key_index(key)
      character(len=*), intent(in) :: key
      integer :: k
      key_index = 0
      do k = 1, nkeys
        if (trim(kname(k)) == trim(key)) key_index = k
      end do
    end function key_index

    function key_list() result(r)
      character(len=:), allocatable :: r
      integer :: k
      r = ''
      do k = 1, nkeys
        if (k > 1) r = r//', '
        r = r//trim(kname(k))
      end do
    end function key_list

    !> Keys of group g with type ('i', 'r', 'l', 'c'), array size and string
    !> length, from gfortran's namelist write of the (still default) values.
    subroutine schema(g)
      integer, intent(in) :: g
      integer :: ios, e, q2, r
      character(len=1024), allocatable :: recs(:)
      character(len=1024) :: rec
      character(len=:), allocatable :: v
      nkeys = 0
      allocate(recs(2*max_keys))
      recs = ''
      select case (g)   ! an internal file: no disk involved
      case (1); write(recs, nml=scene, delim='quote', iostat=ios)
      case (2); write(recs, nml=material, delim='quote', iostat=ios)
      case (3); write(recs, nml=cell, delim='quote', iostat=ios)
      case (4); write(recs, nml=particles, delim='quote', iostat=ios)
      case (5); write(recs, nml=physics, delim='quote', iostat=ios)
      case (6); write(recs, nml=integration, delim='quote', iostat=ios)
      case (7); write(recs, nml=protocol, delim='quote', iostat=ios)
      case (8); write(recs, nml=output, delim='quote', iostat=ios)
      end select
      if (ios /= 0) then
        call set_error(st, exit_internal, trim(path)//': cannot list the keys of group &'// &
             trim(known_groups(g)))
        return
      end if
      do r = 1, size(recs)
        rec = adjustl(recs(r))
        if (rec(1:1) == '&' .or. rec(1:1) == '/' .or. len_trim(rec) == 0) cycle
        e = index(rec, '=')
        if (e > 1 .and. rec(1:1) /= '"') then
          if (verify(trim(rec(1:e - 1)), 'ABCDEFGHIJKLMNOPQRSTUVWXYZ_0123456789') == 0) then
            nkeys = nkeys + 1
            kname(nkeys) = lower(rec(1:e - 1))
            v = trim(adjustl(rec(e + 1:)))
            ksize(nkeys) = 0
            klen(nkeys) = 0
            if (v(1:1) == '"') then
              ktype(nkeys) = 'c'
              q2 = index(v(2:), '"')
              klen(nkeys) = q2 - 1
            else if (v(1:1) == 'T' .or. v(1:1) == 'F') then
              ktype(nkeys) = 'l'
            else if (scan(v, '.E') > 0) then
              ktype(nkeys) = 'r'
            else
              ktype(nkeys) = 'i'
            end if
            call count_values(v)
            cycle
          end if
        end if
        if (nkeys > 0) call count_values(trim(rec))   ! continuation line of an array
      end do
    end subroutine schema

    subroutine count_values(v)
      character(len=*), intent(in) :: v
      integer :: p, c, star, r, ios
      character(len=:), allocatable :: item
      p = 1
      do while (p <= len_trim(v))
        c = index(v(p:), ',')
        if (c == 0) then
          item = trim(adjustl(v(p:)))
          p = len(v) + 1
        else
          item = trim(adjustl(v(p:p + c - 2)))
          p = p + c
        end if
        if (len(item) == 0) cycle
        if (ktype(nkeys) == 'c') then
          ksize(nkeys) = ksize(nkeys) + 1
          exit   ! string keys are scalars here
        end if
        star = index(item, '*')
        r = 1
        if (star > 1) then
          read(item(1:star - 1), *, iostat=ios) r
          if (ios /= 0) r = 1
        end if
        ksize(nkeys) = ksize(nkeys) + r
      end do
    end subroutine count_values

    !> gfortran reads one checked assignment, alone.
    subroutine nml_read(g, buf, kline)
      integer, intent(in) :: g, kline
      character(len=*), intent(in) :: buf
      integer :: ios
      character(len=msg_len) :: iom
      iom = ''
      select case (g)
      case (1); read(buf, nml=scene, iostat=ios, iomsg=iom)
      case (2); read(buf, nml=material, iostat=ios, iomsg=iom)
      case (3); read(buf, nml=cell, iostat=ios, iomsg=iom)
      case (4); read(buf, nml=particles, iostat=ios, iomsg=iom)
      case (5); read(buf, nml=physics, iostat=ios, iomsg=iom)
      case (6); read(buf, nml=integration, iostat=ios, iomsg=iom)
      case (7); read(buf, nml=protocol, iostat=ios, iomsg=iom)
      case (8); read(buf, nml=output, iostat=ios, iomsg=iom)
      end select
      if (ios /= 0) call fail_at(kline, printable(buf(2:len(buf) - 2))//': cannot read: '// &
           trim(printable(iom)))
    end subroutine nml_read

  end subroutine scene_read



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
      ! every species present (fraction > 0) must be able to tilt against the glass (eq. 2.10)
      dmax = sqrt((sc%diameter*present_d_min(sc))**2 + sc%thickness**2)
      if (sc%gap <= sc%thickness .or. sc%gap >= dmax) call bad('material', 'gap', &
           rstr(sc%gap), 'with dry friction on, every magnet must be able to tilt: '// &
           'thickness < gap < sqrt(D_min^2 + thickness^2) = '//rstr(dmax)//' m')
      ! eq. 4.10 without - phi: phi + theta < 90 deg (a positive normal force, eq. 4.11)
      ! needs E/sqrt(D^2+eps^2) < cos(phi) = D/sqrt(D^2+eps^2), i.e. gap < D_min
      dmax = sc%diameter*present_d_min(sc)
      if (trim(sc%tilt) == 'eq_4_10' .and. sc%gap >= dmax) call bad('physics', 'tilt', &
           "'"//trim(sc%tilt)//"'", 'needs gap < smallest diameter = '//rstr(dmax)//' m (gap = '// &
           rstr(sc%gap)//' m: phi + theta >= 90 deg, the normal force of eq. 4.11 would be < 0)')
    end if

    call choice('integration', 'integrator', sc%integrator, &
         [character(len=name_len) :: 'stormer_verlet', 'velocity_verlet', 'euler'])
    call choice('integration', 'neighbour', sc%neighbour, &
         [character(len=name_len) :: 'all_pairs', 'cells', 'verlet', 'thesis'])
    call choice('integration', 'friction_velocity', sc%friction_velocity, &
         [character(len=name_len) :: 'lagged', 'implicit'])
    if (trim(sc%friction_velocity) == 'implicit' .and. trim(sc%integrator) == 'euler') &
         call bad('integration', 'friction_velocity', "'implicit'", &
         "needs integrator = 'stormer_verlet' or 'velocity_verlet' (allowed with euler: 'lagged')")
    call rpos('integration', 'dt', sc%dt, 1.0e-12_dp, 1.0_dp)
    call choice('integration', 'truncation', sc%truncation, &
         [character(len=name_len) :: 'plain', 'shifted_force'])
    call choice('integration', 'tail', sc%tail, [character(len=name_len) :: 'none', 'frozen', 'linear'])
    call rpos('integration', 'target_rel_error', sc%target_rel_error, 0.0_dp, 1.0_dp, .true.)
    if (trim(sc%neighbour) /= 'all_pairs') then
      call rpos('integration', 'r_cut', sc%r_cut, 1.0_dp, 1.0e4_dp)
      call ipos('integration', 'tail_every', sc%tail_every, 1, huge(1))
      if (sc%tail_switch >= 0) call rpos('integration', 'tail_switch', &
           sc%tail_switch, 0.0_dp, 0.999_dp*sc%r_cut, .true.)
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
    if (st%code /= 0) return
    call check_step_count(sc, hs, h0, path, st)
    if (st%code /= 0) return
    ! before anything is allocated: the start grid needs at least (1.05 D_max)^2 per particle
    if (real(sc%n, dp) > sc%width*merge(sc%fill_height, hs, sc%fill_height > 0.0_dp)/1.05_dp**2) &
         call bad('particles', 'n', istr(sc%n), 'particles cannot fit in the cell below the '// &
         'piston (at most '//istr(int(sc%width*merge(sc%fill_height, hs, sc%fill_height > &
         0.0_dp)/1.05_dp**2))//' in '//rstr(sc%width)//' x '//rstr(merge(sc%fill_height, hs, &
         sc%fill_height > 0.0_dp))//' D1^2)')
    if (st%code /= 0) return
    call check_memory(sc, path, st)
    if (st%code /= 0) return

    call ipos('output', 'piston_every', sc%piston_every, 0, huge(1))
    call ipos('output', 'frame_every', sc%frame_every, 0, huge(1))
    call ipos('output', 'distance_every', sc%distance_every, 0, huge(1))
    call ipos('output', 'energy_every', sc%energy_every, 0, huge(1))
    call ipos('output', 'progress_every', sc%progress_every, 0, huge(1))
    call ipos('output', 'checkpoint_every', sc%checkpoint_every, 0, huge(1))
    call choice('output', 'frames_format', sc%frames_format, &
         [character(len=name_len) :: 'text', 'binary', 'both'])
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
      call set_error(st, exit_bad_input, trim(path)//': &integration dt = '//rstr(sc%dt)// &
           ': the protocol lasts '//rstr(t)//' T, about '//trim(adjustl(b))//' steps; at '// &
           'most '//istr8(max_steps)//' steps are allowed (raise dt or shorten the protocol)')
    end if
  end subroutine check_step_count

  !> Estimated memory of a run [bytes]: per-particle state, neighbour list
  !> (dense packing within r_cut + skin), start-grid work arrays.
  real(dp) function memory_estimate(sc) result(bytes)
    type(scene_t), intent(in) :: sc
    real(dp) :: per, rv, dmin
    ! state arrays, placement work arrays, frame writer, cell bins and checkpoint copies:
    ! measured 208 B per particle (max RSS 203 MB at n = 1e6, cells, r_cut 1.5), 240 B kept
    per = 240
    if (trim(sc%neighbour) /= 'all_pairs') then
      rv = sc%r_cut
      if (trim(sc%neighbour) /= 'cells') rv = rv + sc%skin
      dmin = minval(sc%species_diameter(1:max(1, min(sc%n_species, max_species))))
      ! half the neighbours within r_v at hexagonal packing of the smallest species, 4 B each
      per = per + 4.0_dp*0.5_dp*pi_*rv**2*(2.0_dp/sqrt(3.0_dp))/dmin**2 + 2*8 + 2*4
    end if
    bytes = real(sc%n, dp)*per + 16.0_dp*2.0_dp**20
  end function memory_estimate

  !> Refuse a scene whose memory estimate exceeds what this process may use:
  !> MemAvailable, the cgroup limit, RLIMIT_AS and RLIMIT_DATA (each minus
  !> what is already in use), whichever is smallest.
  subroutine check_memory(sc, path, st)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: need, avail
    character(len=:), allocatable :: which
    character(len=80) :: b
    need = memory_estimate(sc)
    call memory_available(avail, which)
    if (avail > 0 .and. need > avail) then
      write(b, '(f0.1,a,f0.1,a)') need/2.0_dp**20, ' MiB of memory, ', avail/2.0_dp**20, ' MiB'
      call set_error(st, exit_bad_input, trim(path)//': &particles n = '//istr(sc%n)// &
           ': the run needs about '//trim(b)//' are available ('//which//'): reduce n')
    end if
  end subroutine check_memory

  subroutine memory_available(avail, which)
    real(dp), intent(out) :: avail     !< bytes; <= 0: unknown
    character(len=:), allocatable, intent(out) :: which
    type(rlimit_t) :: rl
    real(dp) :: v, vm_size, vm_data
    avail = -1
    which = 'unknown'
    vm_size = proc_kb('/proc/self/status', 'VmSize:')*1024
    vm_data = proc_kb('/proc/self/status', 'VmData:')*1024
    v = proc_kb('/proc/meminfo', 'MemAvailable:')*1024
    if (v > 0) call take(v, 'MemAvailable')
    v = file_number('/sys/fs/cgroup/memory.max')
    if (v > 0) call take(v - max(0.0_dp, file_number('/sys/fs/cgroup/memory.current')), &
         'cgroup memory.max')
    if (c_getrlimit(rlimit_as, rl) == 0) then
      if (rl%cur > 0) call take(real(rl%cur, dp) - max(0.0_dp, vm_size), 'ulimit -v')
    end if
    if (c_getrlimit(rlimit_data, rl) == 0) then
      if (rl%cur > 0) call take(real(rl%cur, dp) - max(0.0_dp, vm_data), 'ulimit -d')
    end if
  contains
    subroutine take(x, name)
      real(dp), intent(in) :: x
      character(len=*), intent(in) :: name
      if (avail < 0 .or. x < avail) then
        avail = max(x, 1.0_dp)
        which = name
      end if
    end subroutine take
  end subroutine memory_available

  !> The number after `key` in a /proc file such as /proc/meminfo (kB); -1 if absent.
  real(dp) function proc_kb(path, key) result(v)
    character(len=*), intent(in) :: path, key
    integer :: u, ios
    character(len=256) :: ln
    v = -1
    open(newunit=u, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) return
    do
      read(u, '(a)', iostat=ios) ln
      if (ios /= 0) exit
      if (index(ln, key) == 1) then
        read(ln(len(key) + 1:), *, iostat=ios) v
        if (ios /= 0) v = -1
        exit
      end if
    end do
    close(u)
  end function proc_kb

  !> A file holding one number (e.g. cgroup memory.max); -1 if absent or 'max'.
  real(dp) function file_number(path) result(v)
    character(len=*), intent(in) :: path
    integer :: u, ios
    v = -1
    open(newunit=u, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) return
    read(u, *, iostat=ios) v
    if (ios /= 0) v = -1
    close(u)
  end function file_number

  function istr8(v) result(s)
    integer(i8), intent(in) :: v
    character(len=:), allocatable :: s
    character(len=24) :: b
    write(b, '(i0)') v
    s = trim(b)
  end function istr8

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

  !> The fully resolved scene as namelist text the engine reads back
  !> bit-exactly (17 significant digits), with units as comments: every key,
  !> one group each, strings quoted with doubled quotes, arrays in full.
  !> This is the format of a run directory's scene.nml and the one text
  !> pyorch reads (one reading of a scene, shared by both doors).
  function scene_text(sc) result(text)
    type(scene_t), intent(in) :: sc
    character(len=:), allocatable :: text
    integer :: k
    character(len=400) :: ln
    character(len=:), allocatable :: arr
    text = ''
    call emit('! resolved scene: every key with the value the engine used')
    call emit('&scene')
    call ps('kind', sc%kind, 'scene kind')
    call ps('title', sc%title, '')
    call emit('/')
    call emit('&material ! SI units')
    call pr('diameter', sc%diameter, 'm, big-particle diameter D1 (length unit)')
    call pr('thickness', sc%thickness, 'm, magnet thickness epsilon')
    call pr('density', sc%density, 'kg/m^3')
    call pr('remanence', sc%remanence, 'T, residual magnetisation Br')
    call pr('gap', sc%gap, 'm, Hele-Shaw wall separation E')
    call pr('gravity_si', sc%gravity_si, 'm/s^2, sets the time unit T = sqrt(D1/g)')
    call emit('/')
    call emit('&cell ! lengths in D1')
    call pr('width', sc%width, 'D1')
    call pr('height', sc%height, 'D1')
    call emit('/')
    call emit('&particles')
    call pi_('n', sc%n, '')
    call pi_('seed', sc%seed, '')
    call pr('speed_init', sc%speed_init, 'D1/T')
    call pr('jitter', sc%jitter, 'fraction of grid spacing')
    call pr('fill_height', sc%fill_height, 'D1 (<0: h_start)')
    call pi_('n_species', sc%n_species, '')
    arr = ''
    do k = 1, max_species
      write(ln, '(es25.17e3)') sc%species_diameter(k)
      arr = arr//trim(adjustl(ln))
      if (k < max_species) arr = arr//', '
    end do
    call emit('  species_diameter = '//arr//' ! D_k/D1, every species slot')
    call pr('mix_ratio', sc%mix_ratio, 'fraction of species 2')
    arr = ''
    do k = 1, max_species
      write(ln, '(es25.17e3)') sc%species_fraction(k)
      arr = arr//trim(adjustl(ln))
      if (k < max_species) arr = arr//', '
    end do
    call emit('  species_fraction = '//arr//' ! number fractions (n_species > 2)')
    call ps('placement', sc%placement, '')
    call emit('/')
    call emit('&physics')
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
    call emit('/')
    call emit('&integration')
    call ps('integrator', sc%integrator, '')
    call ps('neighbour', sc%neighbour, '')
    call pr('dt', sc%dt, 'T')
    call pr('r_cut', sc%r_cut, 'D1')
    call pr('skin', sc%skin, 'D1')
    call ps('truncation', sc%truncation, '')
    call ps('tail', sc%tail, '')
    call pi_('tail_every', sc%tail_every, '')
    call pr('tail_switch', sc%tail_switch, 'D1 (<0: 0 for frozen, 1 for linear)')
    call ps('friction_velocity', sc%friction_velocity, '')
    call pr('target_rel_error', sc%target_rel_error, 'used by pyorch only')
    call emit('/')
    call emit('&protocol')
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
    call emit('/')
    call emit('&output ! cadences in steps, 0 = off')
    call pi_('piston_every', sc%piston_every, '')
    call pi_('frame_every', sc%frame_every, '')
    call pi_('distance_every', sc%distance_every, '')
    call pi_('energy_every', sc%energy_every, '')
    call pi_('progress_every', sc%progress_every, '')
    call pi_('checkpoint_every', sc%checkpoint_every, '')
    call ps('frames_format', sc%frames_format, 'text: particles.dat, binary: particles.bin, both')
    call emit('/')
  contains
    subroutine emit(line)
      character(len=*), intent(in) :: line
      text = text//line//achar(10)
    end subroutine emit
    !> A string for a quoted namelist value: quotes doubled.
    function quoted(v) result(r)
      character(len=*), intent(in) :: v
      character(len=:), allocatable :: r
      integer :: i
      r = ''
      do i = 1, len(v)
        r = r//v(i:i)
        if (v(i:i) == achar(39)) r = r//achar(39)
      end do
    end function quoted
    subroutine pr(key, v, note)
      character(len=*), intent(in) :: key, note
      real(dp), intent(in) :: v
      if (len(note) > 0) then
        write(ln, '(2x,a,a,es25.17e3,a,a)') key, ' = ', v, ' ! ', note
      call emit(trim(ln))
      else
        write(ln, '(2x,a,a,es25.17e3)') key, ' = ', v
      call emit(trim(ln))
      end if
    end subroutine pr
    subroutine pi_(key, v, note)
      character(len=*), intent(in) :: key, note
      integer, intent(in) :: v
      write(ln, '(2x,a,a,i0)') key, ' = ', v
      call emit(trim(ln))
      if (len(note) > 0) continue
    end subroutine pi_
    subroutine ps(key, v, note)
      character(len=*), intent(in) :: key, v, note
      call emit('  '//key//' = '''//quoted(trim(v))//'''')
      if (len(note) > 0) continue
    end subroutine ps
    subroutine pl(key, v)
      character(len=*), intent(in) :: key
      logical, intent(in) :: v
      if (v) then
        call emit('  '//key//' = .true.')
      else
        call emit('  '//key//' = .false.')
      end if
    end subroutine pl
  end function scene_text

  !> Write scene_text(sc) to path. gfortran drops ENOSPC silently, so the
  !> size on disk is compared with the text written.
  subroutine scene_write(path, sc, st)
    character(len=*), intent(in) :: path
    type(scene_t), intent(in) :: sc
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: text
    integer :: u, ios
    integer(i8) :: on_disk
    character(len=64) :: b
    text = scene_text(sc)
    open(newunit=u, file=path, access='stream', form='unformatted', status='replace', &
         action='write', iostat=ios)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot write resolved scene')
      return
    end if
    write(u, iostat=ios) text
    close(u)
    inquire(file=path, size=on_disk)
    if (ios /= 0 .or. on_disk /= len(text, i8)) then
      write(b, '(i0,a,i0)') on_disk, ' of ', len(text)
      call set_error(st, exit_io, trim(path)//': write failed (the file has '//trim(b)// &
           ' bytes: is the disk full?)')
    end if
  end subroutine scene_write

end module scene
