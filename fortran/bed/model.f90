!> The dimensionless model built once from a scene: unit scales, dimensionless
!> groups (thesis Table 4.1), the physics switches and the per-species tables.
!>
!> Units: length D1, mass m1, time T = sqrt(D1/g), hence force m1*g.
!>   G = g T^2/D1 = 1                     (gravity)
!>   F = mu0 mu1^2 T^2/(pi m1 D1^5)        (magnetic intensity)
!>   pair force  (3/4) F mu_i mu_j r^-4     (thesis eq. 2.7 / 4.3)
!>   wall force  (1/2) F mu_i w^-3.5        (eq. 2.8 with M = mu1/sqrt(D1))
!>               F mu_i w^-3                (eq. 3.3, infinite wall)
!>               (3/4) F mu_i l^-3 [g(A)+g(B)]  (eq. 3.17, finite slab, M = mu1/D1)
!>   normal force N_i = F c_i mu_i sum_j mu_j sin(theta_j) r^-3   (eqs. 2.15, 3.2, 4.11)
!> with mu_k = (D_k/D1)^2 and m_k = (D_k/D1)^2 (same material and thickness).
module model
  use kinds, only: dp, pi, mu0
  use integrators, only: int_stormer_verlet, int_velocity_verlet, int_euler, int_semi_euler
  use scene, only: scene_t
  use pair_forces, only: split_t, split_of, pair_table_t
  implicit none
  private

  public :: model_t, model_build
  public :: law_none, law_dipole, wall_experimental, wall_infinite, wall_slab
  public :: int_stormer_verlet, int_velocity_verlet, int_euler, int_semi_euler
  public :: piston_prescribed, piston_fixed, piston_none, piston_free

  integer, parameter :: law_none = 0, law_dipole = 1
  integer, parameter :: wall_experimental = 1, wall_infinite = 2, wall_slab = 3
  integer, parameter :: piston_prescribed = 1, piston_fixed = 2, piston_none = 0, piston_free = 3

  type :: model_t
    ! unit scales (SI)
    real(dp) :: length_unit = 0   !< D1 [m]
    real(dp) :: time_unit = 0     !< T = sqrt(D1/g) [s]
    real(dp) :: mass_unit = 0     !< m1 [kg]
    real(dp) :: force_unit = 0    !< m1 g [N]
    real(dp) :: moment_unit = 0   !< mu1 = Br V1/mu0 [A m^2]
    ! dimensionless groups
    real(dp) :: big_f = 0         !< F
    real(dp) :: big_g = 0         !< G (= 1 with this time unit)
    real(dp) :: k_pair = 0        !< (3/4) F
    real(dp) :: k_wall = 0        !< wall prefactor of the chosen law
    ! switches
    integer :: pair_law = law_dipole
    integer :: wall_law = wall_experimental   !< 0 = none
    integer :: integrator = int_stormer_verlet
    integer :: piston_mode = piston_prescribed
    real(dp) :: piston_mass = 0, piston_gamma = 0   !< free piston [m1], [1/T]
    integer :: dry_order = 1                  !< 0 none, 1 first, 2 second order torque
    logical :: gravity_on = .true.
    logical :: viscous_on = .false.
    logical :: friction_implicit = .false.    !< friction at the scheme's own v_n (solved), not lagged
    real(dp) :: mu_s = 0, mu_d = 0, v_t = 0, gamma = 0
    ! neighbours and truncation
    integer :: neighbour = 0             !< nb_* of module neighbours
    real(dp) :: r_cut = 0, skin = 0
    real(dp) :: prune_skin = 0   !< margin of the pruned list over r_c [D1] (0: none, < 0: automatic)
    real(dp) :: shift4 = 0               !< r_c^-4 for the shifted force, else 0
    logical :: tail_frozen = .false.     !< a far field beyond r_c evaluated every tail_every steps
    logical :: tail_linear = .false.     !< ... and extrapolated linearly in between
    type(split_t) :: split               !< near/far hand-over (off: sharp at r_c, or no tail)
    type(pair_table_t) :: tab            !< the dipole law's table (&integration pair_eval; off: exact)
    integer :: tail_every = 100
    ! geometry and step
    real(dp) :: width = 0, height = 0, dt = 0
    ! species tables (index k = 1..n_species)
    integer :: n_species = 1
    real(dp), allocatable :: sp_diam(:)   !< D_k/D1
    real(dp), allocatable :: sp_mass(:)   !< m_k/m1
    real(dp), allocatable :: sp_mu(:)     !< mu_k/mu1
    real(dp), allocatable :: sp_sin(:)    !< sin(theta_k), tilt against the glass
    real(dp), allocatable :: sp_nfac(:)   !< F c_k mu_k, so that N_i = nfac_i * sum_j mu_j sin(theta_j) r^-3
  end type model_t

contains

  subroutine model_build(sc, m)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(out) :: m
    real(dp) :: v1, k, dk, eps, theta, phi, c, w
    integer :: s

    m%length_unit = sc%diameter
    m%time_unit = sqrt(sc%diameter/sc%gravity_si)
    v1 = pi*sc%diameter**2*sc%thickness/4.0_dp
    m%mass_unit = sc%density*v1
    m%force_unit = m%mass_unit*sc%gravity_si
    m%moment_unit = sc%remanence*v1/mu0
    m%big_f = mu0*m%moment_unit**2*m%time_unit**2/(pi*m%mass_unit*sc%diameter**5)
    m%big_g = sc%gravity_si*m%time_unit**2/sc%diameter
    m%k_pair = 0.75_dp*m%big_f

    select case (trim(sc%pair_law))
    case ('dipole'); m%pair_law = law_dipole
    case default;    m%pair_law = law_none
    end select
    select case (trim(sc%wall_law))
    case ('experimental'); m%wall_law = wall_experimental; m%k_wall = 0.5_dp*m%big_f
    case ('infinite');     m%wall_law = wall_infinite;     m%k_wall = m%big_f
    case ('slab');         m%wall_law = wall_slab;         m%k_wall = 0.75_dp*m%big_f
    case default;          m%wall_law = law_none;          m%k_wall = 0
    end select
    select case (trim(sc%integrator))
    case ('velocity_verlet'); m%integrator = int_velocity_verlet
    case ('euler');           m%integrator = int_euler
    case default;             m%integrator = int_stormer_verlet
    end select
    select case (trim(sc%piston))
    case ('fixed'); m%piston_mode = piston_fixed
    case ('none');  m%piston_mode = piston_none
    case ('free');  m%piston_mode = piston_free
    case default;   m%piston_mode = piston_prescribed
    end select
    select case (trim(sc%dry_friction))
    case ('first_order');  m%dry_order = 1
    case ('second_order'); m%dry_order = 2
    case default;          m%dry_order = 0
    end select
    m%piston_mass = sc%piston_mass
    m%piston_gamma = sc%piston_gamma
    m%gravity_on = sc%gravity
    m%gamma = sc%viscous_gamma
    m%viscous_on = sc%viscous_gamma > 0.0_dp
    m%friction_implicit = trim(sc%friction_velocity) == 'implicit'
    m%mu_s = sc%mu_static
    m%mu_d = sc%mu_dynamic
    m%v_t = sc%v_threshold
    select case (trim(sc%neighbour))
    case ('cells');  m%neighbour = 1
    case ('verlet'); m%neighbour = 2
    case ('thesis'); m%neighbour = 3
    case default;    m%neighbour = 0
    end select
    m%r_cut = sc%r_cut
    m%skin = sc%skin
    m%prune_skin = sc%prune_skin
    m%shift4 = 0
    if (m%neighbour /= 0 .and. trim(sc%truncation) == 'shifted_force') m%shift4 = sc%r_cut**(-4)
    m%tail_frozen = m%neighbour /= 0 .and. (trim(sc%tail) == 'frozen' .or. trim(sc%tail) == 'linear')
    m%tail_linear = m%tail_frozen .and. trim(sc%tail) == 'linear'
    if (m%tail_frozen) then
      w = sc%tail_switch
      if (w < 0) w = merge(1.0_dp, 0.0_dp, m%tail_linear)
      m%split = split_of(sc%r_cut, w)
    end if
    m%tail_every = sc%tail_every
    m%width = sc%width
    m%height = sc%height
    m%dt = sc%dt

    m%n_species = sc%n_species
    allocate(m%sp_diam(m%n_species), m%sp_mass(m%n_species), m%sp_mu(m%n_species), &
         m%sp_sin(m%n_species), m%sp_nfac(m%n_species))
    eps = sc%thickness/sc%diameter
    do s = 1, m%n_species
      dk = sc%species_diameter(s)
      m%sp_diam(s) = dk
      m%sp_mass(s) = dk**2
      m%sp_mu(s) = dk**2
      ! tilt of a magnet of diameter D_k in the gap E (thesis eq. 2.10, Fig. 2.5);
      ! &physics tilt = 'eq_4_10' drops the - phi as eq. 4.10 is printed
      phi = atan(eps/dk)
      k = (sc%gap/sc%diameter)/sqrt(dk**2 + eps**2)
      if (m%dry_order > 0) then
        theta = asin(k)
        if (trim(sc%tilt) /= 'eq_4_10') theta = theta - phi
      else
        theta = 0
      end if
      m%sp_sin(s) = sin(theta)
      ! c_k from the torque balance (eq. 2.14) in units of D1
      c = 0.75_dp*cos(theta)
      if (m%dry_order == 2) c = c + 0.25_dp   ! (3/4)(cos(theta) + 1/3), eq. 3.2
      if (m%dry_order > 0) then
        m%sp_nfac(s) = m%big_f*m%sp_mu(s)*c/(cos(phi + theta)*sqrt(dk**2 + eps**2))
      else
        m%sp_nfac(s) = 0
      end if
    end do
  end subroutine model_build

end module model
