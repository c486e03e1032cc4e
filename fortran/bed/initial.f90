!> Initial condition (thesis §2.3.2, §4.2.2): particles on a perturbed grid
!> filling the cell below the piston, random velocity directions, species
!> assigned by the thesis' interleaving rule or at random. Seeded RNG.
!> Or, with &particles start_file, the frame of a start file (module start_file).
module initial
  use kinds, only: dp, pi, i8
  use errors, only: status_t, set_error, exit_bad_input
  use scene_input, only: real_str, int_str
  use scene, only: scene_t
  use model, only: model_t
  use state, only: state_t, state_allocate
  use rng, only: seed_rng
  use start_file, only: start_t, start_read, start_check_region, start_check_distances, &
       start_release
  implicit none
  private

  public :: place_particles, species_of

  real(dp), parameter :: margin = 1.0_dp   !< clearance from walls and piston [D1]

contains

  !> Species of particle k (1-based) by the interleaving rule, thesis §4.2.2.
  pure integer function species_of(k, r) result(s)
    integer, intent(in) :: k
    real(dp), intent(in) :: r       !< mixing ratio R (fraction of species 2)
    integer :: every
    if (r <= 0.0_dp) then
      s = 1
    else if (r >= 1.0_dp) then
      s = 2
    else if (r == 0.5_dp) then
      s = merge(1, 2, mod(k, 2) == 1)
    else if (r < 0.5_dp) then
      every = int(1.0_dp/r*(1.0_dp + 1.0e-12_dp))   ! R = 1/3 written in binary: floor 3, not 2
      s = merge(2, 1, mod(k, every) == 0)
    else
      every = int(1.0_dp/(1.0_dp - r)*(1.0_dp + 1.0e-12_dp))
      s = merge(1, 2, mod(k, every) == 0)
    end if
  end function species_of

  !> Counts per species summing to n (largest remainder of f_k n).
  subroutine counts_of(frac, n, cnt)
    real(dp), intent(in) :: frac(:)
    integer, intent(in) :: n
    integer, allocatable, intent(out) :: cnt(:)
    real(dp), allocatable :: rest(:)
    integer :: k
    allocate(cnt(size(frac)), rest(size(frac)))
    cnt = int(frac*n)
    rest = frac*n - cnt
    do while (sum(cnt) < n)
      k = maxloc(rest, dim=1)
      cnt(k) = cnt(k) + 1
      rest(k) = -1
    end do
  end subroutine counts_of

  !> r-species interleaving (generalises the thesis' two-species rule): slot k
  !> gets the species furthest behind its target count f_s k.
  subroutine interleave(frac, species)
    real(dp), intent(in) :: frac(:)
    integer, intent(out) :: species(:)
    integer :: k, s
    integer :: got(size(frac))
    got = 0
    do k = 1, size(species)
      s = maxloc(frac*k - got, dim=1)
      species(k) = s
      got(s) = got(s) + 1
    end do
  end subroutine interleave

  subroutine place_particles(sc, m, top, path, s, sf, st)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: m
    real(dp), intent(in) :: top            !< piston height at t = 0 [D1]
    character(len=*), intent(in) :: path   !< scene file, for messages
    type(state_t), intent(inout) :: s
    type(start_t), intent(inout) :: sf     !< the start file read (n = 0: the grid)
    type(status_t), intent(inout) :: st
    real(dp) :: wa, ha, sx, sy, u(2), ymax, dmax
    integer :: nc, nr, i, k, j, tmp
    integer, allocatable :: perm(:), cnt(:)
    real(dp), allocatable :: frac(:)
    character(len=800) :: buf

    call state_allocate(s, sc%n)
    call seed_rng(sc%seed)
    frac = fractions(sc)
    if (len_trim(sc%start_file) > 0) then
      call place_from_file(sc, m, top, path, frac, s, sf, st)
      return
    end if
    if (trim(sc%placement) == 'random' .and. sc%n_species > 1) then
      ! exact counts (largest remainder), then a Fisher-Yates shuffle of the grid slots
      call counts_of(frac, sc%n, cnt)
      k = 0
      do j = 1, sc%n_species
        s%species(k + 1:k + cnt(j)) = j
        k = k + cnt(j)
      end do
      allocate(perm(sc%n))
      perm = s%species
      do i = sc%n, 2, -1
        call random_number(u(1))
        j = 1 + int(u(1)*i)
        tmp = perm(i); perm(i) = perm(j); perm(j) = tmp
      end do
      s%species = perm
    else if (sc%n_species == 2) then
      s%species = [(species_of(k, sc%mix_ratio), k = 1, sc%n)]   ! thesis rule, §4.2.2
      call check_realised_ratio(sc, count(s%species == 2), path, st)
      if (st%code /= 0) return
    else if (sc%n_species > 2) then
      call interleave(frac, s%species)
    else
      s%species = 1
    end if
    s%mass = m%sp_mass(s%species)
    s%mu = m%sp_mu(s%species)
    s%wsin = s%mu*m%sp_sin(s%species)
    s%nfac = m%sp_nfac(s%species)

    ! grid in [margin, W - margin] x [margin, ymax - margin]
    ymax = top
    if (sc%fill_height > 0) ymax = sc%fill_height
    if (ymax > m%height) ymax = m%height
    wa = m%width - 2*margin
    ha = ymax - 2*margin
    dmax = maxval(m%sp_diam(1:m%n_species))
    if (wa <= 0 .or. ha <= 0) then
      call set_error(st, exit_bad_input, trim(path)//': &cell width/height: cell too small '// &
           'for a wall clearance of 1 D1 on each side')
      return
    end if
    nc = max(1, nint(sqrt(real(sc%n, dp)*wa/ha)))
    nc = min(nc, sc%n)
    nr = (sc%n + nc - 1)/nc
    sx = wa/nc
    sy = ha/nr
    if (min(sx, sy) < 1.05_dp*dmax) then
      write(buf, '(a,i0,a,f0.3,a,f0.3,a)') ': &particles n = ', sc%n, &
           ': particles cannot fit in the cell below the piston (grid spacing ', &
           min(sx, sy), ' D1 < 1.05 * largest diameter ', dmax, &
           ' D1): lower n or raise &cell width/height, &protocol h_start or &particles fill_height'
      call set_error(st, exit_bad_input, trim(path)//trim(buf))
      return
    end if
    do k = 1, sc%n
      i = mod(k - 1, nc)
      j = (k - 1)/nc
      call random_number(u)
      s%x(k) = margin + (i + 0.5_dp)*sx + sc%jitter*sx*(2*u(1) - 1)
      s%y(k) = margin + (j + 0.5_dp)*sy + sc%jitter*sy*(2*u(2) - 1)
    end do
    call check_grid_distances(sc, s, nc, sx, sy, path, st)
    if (st%code /= 0) return
    call random_velocities(sc, s)
    s%xp = s%x
    s%yp = s%y
    s%has_previous = .false.
  end subroutine place_particles

  !> Number fractions f_k of the species (mix_ratio R for two species).
  function fractions(sc) result(frac)
    type(scene_t), intent(in) :: sc
    real(dp), allocatable :: frac(:)
    if (sc%n_species == 2) then
      frac = [1 - sc%mix_ratio, sc%mix_ratio]
    else if (sc%n_species > 2) then
      frac = sc%species_fraction(1:sc%n_species)
    else
      frac = [1.0_dp]
    end if
  end function fractions

  !> Speed speed_init in uniformly random directions (the RNG as seeded).
  subroutine random_velocities(sc, s)
    type(scene_t), intent(in) :: sc
    type(state_t), intent(inout) :: s
    integer :: k
    real(dp) :: u, ang
    do k = 1, sc%n
      call random_number(u)
      ang = 2*pi*u
      s%vx(k) = sc%speed_init*cos(ang)
      s%vy(k) = sc%speed_init*sin(ang)
    end do
  end subroutine random_velocities

  !> &particles start_file: positions, species and (if the file has them) velocities of its
  !> rows, particle k = row k. Refused, naming the line: what start_read refuses; a centre
  !> closer than min_distance/2 to a wall or the piston at t = 0 (as close as a pair at
  !> min_distance would be to each other; at least a rounding away with min_distance 0);
  !> two centres closer than &physics min_distance; no species column with n_species > 1;
  !> a composition other than the scene's (mix_ratio / species_fraction: within one
  !> particle of f_k n, the value to set is named). Without velocities: speed_init in random
  !> directions from seed, as on the grid.
  subroutine place_from_file(sc, m, top, path, frac, s, sf, st)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: m
    real(dp), intent(in) :: top, frac(:)
    character(len=*), intent(in) :: path
    type(state_t), intent(inout) :: s
    type(start_t), intent(inout) :: sf
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: where
    real(dp) :: wmin
    where = trim(path)//': &particles start_file = '''//trim(sc%start_file)//''''
    call start_read(where, trim(sc%start_file), 'magnet_bed', 'D1', 'D1/T', sc%n, &
         [m%width, m%height], '&cell width, height', sc%n_species, 1.0e3_dp, &
         '&particles speed_init', sf, st)
    if (st%code /= 0) return
    if (sc%n_species > 1 .and. .not. sf%has_species) then
      call set_error(st, exit_bad_input, where//': no species column, and the scene has '// &
           '&particles n_species = '//int_str(int(sc%n_species, i8))//' (add the column '// &
           '"species", 1 .. n_species)')
      return
    end if
    wmin = max(0.5_dp*sc%min_distance, epsilon(1.0_dp)*max(m%width, top))
    call start_check_region(sf, [wmin, wmin], [m%width - wmin, top - wmin], 'D1', &
         'the cell below the piston at t = 0 (H = '//real_str(top)//' D1) with '// &
         'min_distance/2 = '//real_str(wmin)//' D1 to each wall (&physics min_distance, '// &
         '&cell width, &protocol h_start)', st)
    if (st%code /= 0) return
    call start_check_distances(sf, sc%min_distance, 'D1', '&physics min_distance', st)
    if (st%code /= 0) return
    call check_composition(sc, frac, sf, where, st)
    if (st%code /= 0) return
    s%x = sf%x
    s%y = sf%y
    s%species = sf%species
    if (sf%has_velocity) then
      s%vx = sf%vx
      s%vy = sf%vy
    else
      call random_velocities(sc, s)
    end if
    call start_release(sf)
    s%mass = m%sp_mass(s%species)
    s%mu = m%sp_mu(s%species)
    s%wsin = s%mu*m%sp_sin(s%species)
    s%nfac = m%sp_nfac(s%species)
    s%xp = s%x
    s%yp = s%y
    s%has_previous = .false.
  end subroutine place_from_file

  !> The file's species counts must be the scene's composition (within one particle of
  !> f_k n): the scene states what runs (issue 30, 1). The message gives the value to set.
  subroutine check_composition(sc, frac, sf, where, st)
    type(scene_t), intent(in) :: sc
    real(dp), intent(in) :: frac(:)
    type(start_t), intent(in) :: sf
    character(len=*), intent(in) :: where
    type(status_t), intent(inout) :: st
    integer :: k, j, cnt(size(frac))
    character(len=:), allocatable :: want, key
    do k = 1, size(frac)
      cnt(k) = count(sf%species == k)
    end do
    k = 0
    if (any(abs(cnt - frac*sc%n) >= 1.0_dp)) k = maxloc(abs(cnt - frac*sc%n), dim=1)
    if (k == 0) return
    if (size(frac) == 2) then
      k = 2       ! R is the fraction of species 2
      key = 'mix_ratio = '//real_str(sc%mix_ratio)
      want = 'mix_ratio = '//real_str(real(cnt(2), dp)/sc%n)
    else
      key = 'species_fraction('//int_str(int(k, i8))//') = '//real_str(frac(k))
      want = 'species_fraction = '//real_str(real(cnt(1), dp)/sc%n)
      do j = 2, size(frac)
        want = want//', '//real_str(real(cnt(j), dp)/sc%n)
      end do
    end if
    call set_error(st, exit_bad_input, where//': holds '//int_str(int(cnt(k), i8))//' of '// &
         int_str(int(sc%n, i8))//' particles of species '//int_str(int(k, i8))//', the '// &
         'scene''s &particles '//key//' asks for '//r4(frac(k)*sc%n)//' (the scene states '// &
         'the composition that runs): set &particles '//want)
  end subroutine check_composition

  !> The thesis' interleaving rule (every floor(1/R)-th particle of species 2) reaches only
  !> R = 1/k and 1 - 1/k: a mix_ratio it cannot realise (e.g. 0.4 -> 0.5) is refused naming the
  !> nearest reachable ratios, instead of running another composition than the scene states.
  subroutine check_realised_ratio(sc, n2, path, st)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: n2               !< particles of species 2 placed
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: r, lo, hi
    integer :: k
    r = sc%mix_ratio
    if (abs(real(n2, dp) - r*sc%n) <= 1.0_dp) return
    if (r < 0.5_dp) then
      k = int(1.0_dp/r*(1.0_dp + 1.0e-12_dp))
      lo = 1.0_dp/real(k + 1, dp)
      hi = 1.0_dp/real(k, dp)
    else
      k = int(1.0_dp/(1.0_dp - r)*(1.0_dp + 1.0e-12_dp))
      lo = 1.0_dp - 1.0_dp/real(k, dp)
      hi = 1.0_dp - 1.0_dp/real(k + 1, dp)
    end if
    call set_error(st, exit_bad_input, trim(path)//': &particles mix_ratio = '//real_str(r)// &
         ': placement = ''interleave'' (the thesis'' rule, every floor(1/R)-th particle small, '// &
         '4.2.2) would place '//int_str(int(n2, i8))//' of '//int_str(int(sc%n, i8))//' particles of species 2 (R = '// &
         r4(real(n2, dp)/sc%n)//'); it reaches R = 1/k and 1 - 1/k: nearest '//r4(lo)//' and '// &
         r4(hi)//'; placement = ''random'' places exactly round(R n) for any R')
  end subroutine check_realised_ratio

  !> The start grid must respect the closest-approach guard (&physics min_distance): a jittered
  !> slot's near neighbours are the slots next to it (same row, row above), so the closest pair
  !> is found in O(N). Refused naming the placement keys and the largest jitter that is safe
  !> for this grid (spacing (1 - 2 jitter) >= min_distance), instead of a crush at step 0.
  subroutine check_grid_distances(sc, s, nc, sx, sy, path, st)
    type(scene_t), intent(in) :: sc
    type(state_t), intent(in) :: s
    integer, intent(in) :: nc
    real(dp), intent(in) :: sx, sy     !< grid spacing [D1]
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: k, l, m, ia, ib
    real(dp) :: d2, best, jmax
    integer, parameter :: offs(4) = [1, 0, 1, 2]   ! (slot + 1), row above: -1, 0, +1
    character(len=100) :: buf
    if (sc%min_distance <= 0) return
    best = huge(1.0_dp)
    ia = 0
    ib = 0
    do k = 1, sc%n
      do m = 1, 4
        if (m == 1) then
          if (mod(k, nc) == 0) cycle          ! last slot of its row
          l = k + 1
        else
          l = k + nc + offs(m) - 1
          if (offs(m) == 0 .and. mod(k - 1, nc) == 0) cycle   ! no slot to the left
          if (offs(m) == 2 .and. mod(k, nc) == 0) cycle       ! no slot to the right
        end if
        if (l > sc%n) cycle
        d2 = (s%x(k) - s%x(l))**2 + (s%y(k) - s%y(l))**2
        if (d2 < best) then
          best = d2
          ia = k
          ib = l
        end if
      end do
    end do
    if (ia == 0) return
    if (sqrt(best) >= sc%min_distance) return
    jmax = max(0.0_dp, 0.5_dp*(1.0_dp - sc%min_distance/min(sx, sy)))
    write(buf, '(a,i0,a,i0,a)') ': the start grid places particles ', ia, ' and ', ib, ' '
    call set_error(st, exit_bad_input, trim(path)//': &particles jitter = '// &
         real_str(sc%jitter)//trim(buf)//' '//r4(sqrt(best))//' D1 apart, closer than '// &
         '&physics min_distance = '//r4(sc%min_distance)//' D1 (grid spacing '//r4(sx)//' x '// &
         r4(sy)//' D1): with this n and cell, jitter <= '//r4(jmax)//' keeps every pair '// &
         'apart; or lower &particles n, raise &cell width/height, &protocol h_start or '// &
         '&particles fill_height')
  end subroutine check_grid_distances

  !> x rounded to 4 decimals, as messages show it.
  function r4(x) result(t)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: t
    t = real_str(anint(x*1.0e4_dp)/1.0e4_dp)
  end function r4

end module initial
