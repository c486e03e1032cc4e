!> The engine: load a scene, compute forces (with the runtime guards), step.
!> Longer than 600 lines because the step and the guards that stop it (a crush, the piston
!> leaving, a failed settle, non-finite forces) are one sequence over the same state; the
!> guards' diagnostics (~150 lines) are the part to move to a submodule if it grows.
!> Running a whole scene into a run directory is module runner's job.
module engine
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kinds, only: dp, i8, pi
  use errors, only: status_t, set_error, exit_numerical, exit_ok, exit_bad_input
  use scene, only: scene_t, scene_read, scene_validate
  use model, only: model_t, model_build, law_dipole, piston_none, piston_prescribed, piston_free
  use state, only: state_t, state_allocate
  use protocol, only: protocol_t, protocol_build, piston_at, phase_names
  use initial, only: place_particles
  use start_file, only: start_t
  use pair_forces, only: pair_forces_all, pair_forces_list, pair_forces_far, pair_energy_all, &
       max_bits, list_takes_pruned, long_row_pairs
  use pair_eval, only: dipole_eval_build
  use pair_table, only: eval_code, eval_exact, eval_table
  use scene_input, only: real_str, int_str
  use parallel, only: init_threads, par_min_loop, my_share
  use neighbours, only: nlist_t, nlist_setup, nb_all_pairs, nb_verlet
  use nlist_upkeep, only: nlist_refresh, nlist_pruned, nlist_set_prune, nlist_force_start, &
       nlist_force_done
  use walls, only: wall_block, wall_energy, wall_chunk
  use friction, only: gravity_force, viscous_friction, dry_friction, friction_at_vn
  use integrators, only: estimate_velocity, finish_velocity, advance
  use model, only: int_stormer_verlet, int_velocity_verlet
  use observables, only: mean_distance, packing_fraction, kinetic_energy
  use output, only: output_t, write_piston, write_frame, write_distance, write_energy
  implicit none
  private

  public :: sim_t, sim_load, sim_forces, sim_step, sim_energy, pairs_per_step, piston_energy, &
       time_pair_pass, sim_note_mu

  type :: sim_t
    type(scene_t) :: sc
    type(model_t) :: m
    type(state_t) :: s
    type(protocol_t) :: p
    type(output_t) :: o
    type(nlist_t) :: nl
    type(state_t) :: pst                !< free piston as a one-body state (y = height)
    character(len=:), allocatable :: scene_path
    logical :: writing = .false.        !< a run directory is open
    logical :: need_velocity = .false.  !< some force depends on velocity
    logical :: mu_one = .false.         !< every moment factor mu(i) equal (one species)
    real(dp) :: area = 0                !< total particle area [D1^2]
    type(start_t) :: start              !< &particles start_file as read (n = 0: the grid)
  end type sim_t

contains

  !> Read, validate, build the model and the initial condition. Writes nothing.
  subroutine sim_load(sim, path, st)
    type(sim_t), intent(inout) :: sim
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    sim%scene_path = trim(path)
    call init_threads()
    call scene_read(path, sim%sc, st)
    if (st%code /= 0) return
    call scene_validate(sim%sc, path, st)
    if (st%code /= 0) return
    call model_build(sim%sc, sim%m)
    call build_pair_table(sim, path, st)
    if (st%code /= 0) return
    call build_rest(sim, st)
  end subroutine sim_load

  !> &integration pair_eval /= 'exact': the dipole law's evaluation (table, single, rsqrt) over
  !> r in [min_distance, r_hi] (r_hi: the cell's diagonal with all pairs or a far field, else
  !> r_c + skin, the farthest listed pair), measured at load against the exact law; refused
  !> when its largest error exceeds pair_table_error (a table: when the finest one does).
  subroutine build_pair_table(sim, path, st)
    type(sim_t), intent(inout) :: sim
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    real(dp) :: r_lo, r_hi
    logical :: ok
    integer :: code
    character(len=:), allocatable :: what
    associate (sc => sim%sc, m => sim%m)
      code = eval_code(sc%pair_eval)
      if (code == eval_exact .or. m%pair_law /= law_dipole) return
      r_lo = sc%min_distance
      if (r_lo <= 0) then
        call set_error(st, exit_bad_input, trim(path)//': &integration pair_eval = '''// &
             trim(sc%pair_eval)//''': needs &physics min_distance in (0, 1] D1 (the lower end '// &
             'of the range its error is measured over; it is 0)')
        return
      end if
      if (m%neighbour == nb_all_pairs .or. m%tail_frozen) then
        r_hi = 1.01_dp*sqrt(m%width**2 + m%height**2)
      else
        r_hi = m%r_cut + m%skin
      end if
      call dipole_eval_build(code, m%shift4, r_lo**2, r_hi**2, sc%pair_table_error, m%tab, ok)
      what = 'pair_eval = '''//trim(sc%pair_eval)//''''
      if (code == eval_table) what = 'the finest table, '//int_str(2_i8**max_bits)// &
           ' segments per octave of r^2,'
      if (.not. ok) call set_error(st, exit_bad_input, trim(path)//': &integration '// &
           'pair_table_error = '//real_str(sc%pair_table_error)//': not reached over r in ['// &
           real_str(r_lo)//', '//real_str(r_hi)//'] D1 ('//what//' reaches '// &
           real_str(m%tab%max_err)//'); allowed ['//real_str(m%tab%max_err)//', 1e-2]')
    end associate
  end subroutine build_pair_table

  !> sim%mu_one from the state's moment factors (every mu(i) equal: one species). mu follows the
  !> species (initial.f90) and no step changes it: called after placing and after a restore.
  subroutine sim_note_mu(sim)
    type(sim_t), intent(inout) :: sim
    sim%mu_one = sim%s%n > 0
    if (sim%mu_one) sim%mu_one = all(sim%s%mu == sim%s%mu(1))
  end subroutine sim_note_mu

  subroutine build_rest(sim, st)
    type(sim_t), intent(inout) :: sim
    type(status_t), intent(inout) :: st
    real(dp) :: h
    integer :: phase, k
    real(dp) :: area
    area = 0
    ! area needs species counts: place first with the start height, then build
    call protocol_build(sim%sc, sim%m, 1.0_dp, sim%p)
    call place_particles(sim%sc, sim%m, sim%p%h_start, sim%scene_path, sim%s, sim%start, &
         st)
    if (st%code /= 0) return
    do k = 1, sim%s%n
      area = area + 0.25_dp*pi*sim%m%sp_diam(sim%s%species(k))**2
    end do
    sim%area = area
    call sim_note_mu(sim)
    call protocol_build(sim%sc, sim%m, area, sim%p)
    if (sim%m%piston_mode == piston_prescribed .and. sim%p%hf <= 1.0_dp) then
      call set_error(st, exit_bad_input, sim%scene_path//': &protocol phi_final: gives hf <= 1 D1')
      return
    end if
    if (sim%m%piston_mode == piston_prescribed .and. sim%p%hf >= sim%p%h0) then
      call set_error(st, exit_bad_input, sim%scene_path//': &protocol phi_final: gives hf >= h0 '// &
           '(the bed would not be compressed)')
      return
    end if
    sim%need_velocity = sim%m%dry_order > 0 .or. sim%m%viscous_on
    ! the optional arrays this scene writes (the others stay 0: not permuted at list builds)
    sim%s%with_s3 = sim%m%dry_order > 0
    sim%s%with_far = sim%m%tail_frozen
    sim%s%with_far_slope = sim%m%tail_linear
    if (sim%m%piston_mode == piston_free) then
      call state_allocate(sim%pst, 1)
      sim%pst%x = 0
      sim%pst%y = sim%p%h_start
      sim%pst%mass = sim%m%piston_mass
      sim%pst%vx = 0
      sim%pst%vy = 0
      sim%pst%nudge_step = -1
      sim%pst%calm_since = -1
    end if
    if (sim%m%neighbour /= nb_all_pairs) then
      sim%nl%with_owner = .true.      ! the flat pair loop (pair_forces_list) needs own
      sim%nl%with_ranges = .true.     ! and the long rows their ranges (verlet only)
      sim%nl%ranges_from = long_row_pairs
      call nlist_setup(sim%nl, sim%m%neighbour, sim%m%r_cut, sim%m%skin, sim%m%width, &
           sim%m%height, sim%s%n)
      if (sim%m%neighbour == nb_verlet) call nlist_set_prune(sim%nl, sim%m%prune_skin)
    end if
    sim%s%step = 0
    call piston_at(sim%p, 0.0_dp, h, phase)
    sim%s%piston_h = h
    sim%s%phase = phase
  end subroutine build_rest

  !> Forces at the current positions (and velocity estimate). need_fmag also
  !> fills |magnetic force| per particle. Guards: particle outside the cell.
  subroutine sim_forces(sim, need_fmag, st)
    type(sim_t), intent(inout) :: sim
    logical, intent(in) :: need_fmag
    type(status_t), intent(inout) :: st
    integer :: bad, badf, i, j, bi, bj
    character(len=800) :: buf
    real(dp) :: r2min, d2
    associate (s => sim%s, m => sim%m)
      if (m%pair_law == law_dipole) then
        call pair_pass(sim, r2min)      ! sets fx, fy, s3
        if (r2min < sim%sc%min_distance**2) then
          ! rare: find the pair by brute force for the message
          r2min = huge(1.0_dp); bi = 1; bj = 1
          do i = 1, s%n - 1
            do j = i + 1, s%n
              d2 = (s%x(i) - s%x(j))**2 + (s%y(i) - s%y(j))**2
              if (d2 < r2min) then
                r2min = d2; bi = i; bj = j
              end if
            end do
          end do
          write(buf, '(a,i0,a,es12.5,a,i0,a,i0,a,es12.5,a,2(es12.5,1x),a,2(es12.5,1x),a,f6.3,a)') &
               'step ', s%step, ' t = ', s%t, ' T: particles ', s%id(bi), ' and ', s%id(bj), &
               ' are ', sqrt(r2min), ' D1 apart (at ', s%x(bi), s%y(bi), 'and ', s%x(bj), &
               s%y(bj), ') < min_distance = ', sim%sc%min_distance, ' D1: '
          call set_error(st, exit_numerical, trim(buf)//' '//crush_cause(sim, bi, bj))
          return
        end if
      else
        call init_forces(sim, .false.)
      end if
      if (m%piston_mode == piston_free .and. .not. (s%piston_h > 0 .and. &
           s%piston_h <= m%height)) then
        write(buf, '(a,i0,a,es12.5,a,es12.5,a)') 'step ', s%step, ' t = ', s%t, &
             ' T: the free piston left the cell (H = ', s%piston_h, ' D1): '
        call set_error(st, exit_numerical, trim(buf)//' '//piston_exit_cause(sim))
        return
      end if
      call body_forces(sim, need_fmag, bad, badf)
      if (bad /= 0) then
        write(buf, '(a,i0,a,es12.5,a,i0,a,es12.5,a,es12.5,a,es12.5,a)') 'step ', s%step, &
             ' t = ', s%t, ' T: particle ', s%id(bad), ' left the cell or became non-finite (x = ', &
             s%x(bad), ', y = ', s%y(bad), ' D1; piston at ', s%piston_h, &
             ' D1): reduce dt or check the scene'
        call set_error(st, exit_numerical, trim(buf))
        return
      end if
      if (badf /= 0) then
        i = badf
        write(buf, '(a,i0,a,es12.5,a,i0,a,es12.5,1x,es12.5,a,es12.5,1x,es12.5,a)') 'step ', &
             s%step, ' t = ', s%t, ' T: non-finite force on particle ', s%id(i), ' (f = ', &
             s%fx(i), s%fy(i), ' at ', s%x(i), s%y(i), '): reduce dt or check the scene'
        call set_error(st, exit_numerical, trim(buf))
        return
      end if
    end associate
  end subroutine sim_forces

  !> Pair forces through the scene's neighbour strategy (+ frozen far field): sets fx, fy,
  !> s3 (the far field, when frozen, is their starting value: no separate addition pass).
  subroutine pair_pass(sim, r2min)
    type(sim_t), intent(inout) :: sim
    real(dp), intent(out) :: r2min   !< smallest squared pair distance seen [D1^2]
    logical :: r3, pruned
    associate (s => sim%s, m => sim%m, nl => sim%nl)
      r3 = m%dry_order > 0
      if (m%neighbour == nb_all_pairs) then
        call init_forces(sim, .false.)
        call pair_forces_all(s%n, s%x, s%y, s%mu, s%wsin, m%k_pair, r3, s%fx, s%fy, s%s3, r2min, &
             tab=m%tab)
        nl%evaluated = nl%evaluated + int(s%n, i8)*int(s%n - 1, i8)/2
        return
      end if
      ! the pruned list where the kernel takes it (nlist_t; the same bits as the whole list)
      pruned = nl%prune > 0 .and. list_takes_pruned(.false., s%n, int(nl%pairs))
      call nlist_refresh(nl, s, pruned)
      pruned = pruned .and. nlist_pruned(nl)
      if (m%tail_frozen) then
        if (mod(s%step, int(m%tail_every, i8)) == 0 .or. .not. s%tail_ready) call far_field(sim)
      end if
      call init_forces(sim, m%tail_frozen)
      if (pruned) then
        call nlist_force_start(nl)
        call pair_forces_list(s%n, s%x, s%y, s%mu, s%wsin, m%k_pair, m%r_cut**2, m%shift4, &
             nl%check, r3, nl%start, nl%nbr, s%fx, s%fy, s%s3, r2min, own=nl%own, &
             split=m%split, rstart=nl%rstart, rlo=nl%rlo, rhi=nl%rhi, tab=m%tab, &
             mu_one=sim%mu_one, pstart=nl%pstart, pnbr=nl%pnbr, pown=nl%pown, &
             rowmax=nl%rowmax)   ! (the ranges absent when not built: nlist_t ranges_from)
        call nlist_force_done(nl)
      else if (nl%strategy == nb_verlet) then   ! (the ranges absent when not built)
        call pair_forces_list(s%n, s%x, s%y, s%mu, s%wsin, m%k_pair, m%r_cut**2, m%shift4, &
             nl%check, r3, nl%start, nl%nbr, s%fx, s%fy, s%s3, r2min, own=nl%own, &
             split=m%split, rstart=nl%rstart, rlo=nl%rlo, rhi=nl%rhi, tab=m%tab, &
             mu_one=sim%mu_one, rowmax=nl%rowmax)
      else
        call pair_forces_list(s%n, s%x, s%y, s%mu, s%wsin, m%k_pair, m%r_cut**2, m%shift4, &
             nl%check, r3, nl%start, nl%nbr, s%fx, s%fy, s%s3, r2min, own=nl%own, split=m%split, &
             tab=m%tab, mu_one=sim%mu_one)
      end if
      nl%evaluated = nl%evaluated + nl%pairs
    end associate
  end subroutine pair_pass

  !> The far field (pairs beyond r_c) at the current step; for tail = 'linear' also its change
  !> per step since the previous evaluation (zero until there is one: the first interval is frozen).
  subroutine far_field(sim)
    type(sim_t), intent(inout) :: sim
    real(dp) :: per_step
    associate (s => sim%s, m => sim%m)
      if (m%tail_linear .and. s%tail_ready .and. s%step > s%tail_step) then
        s%dfx_far = s%fx_far; s%dfy_far = s%fy_far; s%ds3_far = s%s3_far
      end if
      call pair_forces_far(s%n, s%x, s%y, s%mu, s%wsin, m%k_pair, m%r_cut**2, m%dry_order > 0, &
           s%fx_far, s%fy_far, s%s3_far, m%split, tab=m%tab)
      if (m%tail_linear .and. s%tail_ready .and. s%step > s%tail_step) then
        per_step = 1.0_dp/real(s%step - s%tail_step, dp)
        s%dfx_far = (s%fx_far - s%dfx_far)*per_step
        s%dfy_far = (s%fy_far - s%dfy_far)*per_step
        s%ds3_far = (s%s3_far - s%ds3_far)*per_step
      else
        s%dfx_far = 0; s%dfy_far = 0; s%ds3_far = 0
      end if
      s%tail_ready = .true.
      s%tail_step = s%step
    end associate
  end subroutine far_field

  !> fx, fy, s3 = the far field (far: frozen, or extrapolated linearly from its last two
  !> evaluations for tail = 'linear') or 0; serial below par_min_loop particles. s3 (the
  !> friction's r^-3 sums) only with dry friction: without, they stay 0.
  subroutine init_forces(sim, far)
    type(sim_t), intent(inout) :: sim
    logical, intent(in) :: far
    integer :: t, nt, lo, hi
    associate (s => sim%s)
      if (s%n < par_min_loop) then
        call init_range(1, s%n)
      else
        !$omp parallel default(shared) private(t, nt, lo, hi)
        call my_share(s%n, t, nt)
        lo = 1 + ((t - 1)*s%n)/nt
        hi = (t*s%n)/nt
        call init_range(lo, hi)
        !$omp end parallel
      end if
    end associate
  contains
    subroutine init_range(lo, hi)
      integer, intent(in) :: lo, hi
      real(dp) :: a
      logical :: r3
      associate (s => sim%s)
        r3 = s%with_s3   ! else nothing adds to s3 (friction weighs it by 0): 0 from state_allocate
        if (far .and. sim%m%tail_linear) then
          a = real(s%step - s%tail_step, dp)
          s%fx(lo:hi) = s%fx_far(lo:hi) + a*s%dfx_far(lo:hi)
          s%fy(lo:hi) = s%fy_far(lo:hi) + a*s%dfy_far(lo:hi)
          if (r3) s%s3(lo:hi) = s%s3_far(lo:hi) + a*s%ds3_far(lo:hi)
        else if (far) then
          s%fx(lo:hi) = s%fx_far(lo:hi)
          s%fy(lo:hi) = s%fy_far(lo:hi)
          if (r3) s%s3(lo:hi) = s%s3_far(lo:hi)
        else
          s%fx(lo:hi) = 0
          s%fy(lo:hi) = 0
          if (r3) s%s3(lo:hi) = 0
        end if
      end associate
    end subroutine init_range
  end subroutine init_forces

  !> Every force on the particles but the pairs, in one pass over blocks of wall_chunk
  !> particles (on the threads from par_min_loop particles, else without an OpenMP region):
  !> walls (and the push on the piston, summed in block order), |magnetic force| (need_fmag),
  !> gravity, dry and viscous friction; then the check for non-finite forces.
  !> outside / nonfinite: the first particle outside the cell / with a non-finite force, or 0.
  subroutine body_forces(sim, need_fmag, outside, nonfinite)
    type(sim_t), intent(inout) :: sim
    logical, intent(in) :: need_fmag
    integer, intent(out) :: outside, nonfinite
    integer :: nb, b
    real(dp) :: part((sim%s%n + wall_chunk - 1)/wall_chunk)
    integer :: outb(size(part)), badb(size(part))
    nb = size(part)
    if (sim%s%n < par_min_loop) then
      do b = 1, nb
        call body_block(sim, b, need_fmag, part(b), outb(b), badb(b))
      end do
    else
      !$omp parallel do schedule(static) default(shared)
      do b = 1, nb
        call body_block(sim, b, need_fmag, part(b), outb(b), badb(b))
      end do
      !$omp end parallel do
    end if
    sim%s%piston_force = sum(part)   ! fixed blocks summed in order: the same bits for any thread count
    outside = 0
    nonfinite = 0
    do b = nb, 1, -1
      if (outb(b) /= 0) outside = outb(b)
      if (badb(b) /= 0) nonfinite = badb(b)
    end do
  end subroutine body_forces

  !> Block b of body_forces (particles lo..hi).
  subroutine body_block(sim, b, need_fmag, f_piston, outside, nonfinite)
    type(sim_t), intent(inout) :: sim
    integer, intent(in) :: b
    logical, intent(in) :: need_fmag
    real(dp), intent(out) :: f_piston
    integer, intent(out) :: outside, nonfinite
    integer :: lo, hi, mb, i
    real(dp) :: bad
    associate (s => sim%s, m => sim%m)
      lo = 1 + (b - 1)*wall_chunk
      hi = min(s%n, b*wall_chunk)
      mb = hi - lo + 1
      call wall_block(mb, s%x(lo:hi), s%y(lo:hi), s%mu(lo:hi), m%wall_law, m%k_wall, m%width, &
           m%height, s%piston_h, m%piston_mode /= piston_none, s%fx(lo:hi), s%fy(lo:hi), &
           f_piston, outside)
      if (outside /= 0) outside = lo + outside - 1
      if (need_fmag) then
        s%fmx(lo:hi) = s%fx(lo:hi)
        s%fmy(lo:hi) = s%fy(lo:hi)
        s%fmag(lo:hi) = sqrt(s%fx(lo:hi)**2 + s%fy(lo:hi)**2)
      end if
      if (m%gravity_on) call gravity_force(mb, s%mass(lo:hi), m%big_g, s%fy(lo:hi))
      if (m%friction_implicit .and. s%has_previous) then
        if (m%dry_order > 0 .or. m%viscous_on) call friction_at_vn(mb, s%mass(lo:hi), &
             s%nfac(lo:hi), s%s3(lo:hi), m%dry_order > 0, m%mu_s, m%mu_d, m%v_t, &
             merge(m%gamma, 0.0_dp, m%viscous_on), m%dt, s%vx(lo:hi), s%vy(lo:hi), &
             s%fx(lo:hi), s%fy(lo:hi))
      else
        if (m%dry_order > 0) call dry_friction(mb, s%nfac(lo:hi), s%s3(lo:hi), m%mu_s, &
             m%mu_d, m%v_t, s%vx(lo:hi), s%vy(lo:hi), s%fx(lo:hi), s%fy(lo:hi))
        if (m%viscous_on) call viscous_friction(mb, s%mass(lo:hi), m%gamma, s%vx(lo:hi), &
             s%vy(lo:hi), s%fx(lo:hi), s%fy(lo:hi))
      end if
      nonfinite = 0
      bad = 0
      do i = lo, hi     ! flagged first (vectorises: no .and., no integers), searched only if any
        bad = max(bad, merge(0.0_dp, 1.0_dp, abs(s%fx(i)) <= huge(1.0_dp)), &
             merge(0.0_dp, 1.0_dp, abs(s%fy(i)) <= huge(1.0_dp)))
      end do
      if (bad > 0) then
        do i = hi, lo, -1
          if (.not. (abs(s%fx(i)) <= huge(1.0_dp) .and. abs(s%fy(i)) <= huge(1.0_dp))) &
               nonfinite = i
        end do
      end if
    end associate
  end subroutine body_block

  !> Micro-benchmark: nrep pair passes (strategy of the scene) at the current
  !> positions; wall-clock seconds and pairs evaluated per pass.
  subroutine time_pair_pass(sim, nrep, seconds, pairs)
    type(sim_t), intent(inout) :: sim
    integer, intent(in) :: nrep
    real(dp), intent(out) :: seconds
    integer(i8), intent(out) :: pairs
    integer(i8) :: c0, c1, rate, e0
    integer :: k
    real(dp) :: r2min
    call pair_pass(sim, r2min)        ! builds the list if needed
    e0 = sim%nl%evaluated
    call system_clock(c0, rate)
    do k = 1, nrep
      call pair_pass(sim, r2min)
    end do
    call system_clock(c1)
    seconds = real(c1 - c0, dp)/real(rate, dp)
    pairs = (sim%nl%evaluated - e0)/max(1, nrep)
  end subroutine time_pair_pass

  !> Free piston at the start of a step: held during the relaxation, nudged
  !> (lifted and stopped) at the start of the recorded phase, otherwise a body
  !> integrated with the particles' integrator. Sets the wall height.
  subroutine free_piston_begin(sim, moving)
    type(sim_t), intent(inout) :: sim
    logical, intent(out) :: moving
    associate (pst => sim%pst, s => sim%s)
      if (s%phase == 1) then
        pst%y = sim%p%h_start
        pst%vy = 0
        pst%has_previous = .false.
      end if
      if (s%step == pst%nudge_step) then
        pst%y = pst%y + sim%p%nudge
        pst%vy = 0
        pst%has_previous = .false.
      end if
      moving = s%phase /= 1
      if (moving .and. sim%m%piston_gamma > 0) call estimate_velocity(sim%m%integrator, &
           sim%m%dt, pst)
      s%piston_h = pst%y(1)
    end associate
  end subroutine free_piston_begin

  !> Nudge experiment: is the bed settled? Piston speed below settle_speed and
  !> bed kinetic energy per particle below settle_ekin, without a break for
  !> settle_hold; then the nudge is due at the next step and the run ends
  !> t_record later. Not settled t_settle after the release: a clear failure.
  !> Velocities are the finished ones of this step (as written to energy.dat);
  !> computing them does not change the trajectory.
  subroutine settle_check(sim, st)
    type(sim_t), intent(inout) :: sim
    type(status_t), intent(inout) :: st
    real(dp) :: v, ek
    character(len=800) :: buf
    associate (s => sim%s, m => sim%m, p => sim%p, pst => sim%pst)
      call finish_velocity(m%integrator, m%dt, s)
      call finish_velocity(m%integrator, m%dt, pst)
      v = abs(pst%vy(1))
      ek = kinetic_energy(s%n, s%mass, s%vx, s%vy)/real(max(1, s%n), dp)
      if (v < p%settle_speed .and. ek < p%settle_ekin) then
        if (pst%calm_since < 0) pst%calm_since = s%t
        if (s%t - pst%calm_since >= p%settle_hold - 0.5_dp*m%dt) then
          pst%nudge_step = s%step + 1
          p%n_steps = pst%nudge_step + p%record_steps
        end if
      else
        pst%calm_since = -1
      end if
      if (pst%nudge_step < 0 .and. s%t >= p%t_relax + p%t_settle - 0.5_dp*m%dt) then
        write(buf, '(a,i0,a,es12.5,a,es10.3,a,es10.3,a,es10.3,a,es10.3,a,es10.3,a,es10.3,a)') &
             'step ', s%step, ' t = ', s%t, ' T: the bed did not settle within t_settle = ', p%t_settle, &
             ' T of the release: piston speed ', v, ' D1/T (settle_speed ', p%settle_speed, &
             '), bed kinetic energy ', ek, ' m1 g D1 per particle (settle_ekin ', p%settle_ekin, &
             '), both needed for settle_hold = ', p%settle_hold, ' T; raise t_settle or the '// &
             'thresholds, or damp more (viscous_gamma)'
        call set_error(st, exit_numerical, trim(buf))
      end if
    end associate
  end subroutine settle_check

  !> Velocity of particle k [D1/T] as far as the state tells at a guard
  !> (Stormer-Verlet: the last step's displacement / dt).
  subroutine guard_velocity(sim, k, vx, vy)
    type(sim_t), intent(in) :: sim
    integer, intent(in) :: k
    real(dp), intent(out) :: vx, vy
    associate (s => sim%s)
      if (.not. s%has_previous) then
        vx = s%vx(k); vy = s%vy(k)
      else if (sim%m%integrator == int_stormer_verlet) then
        vx = (s%x(k) - s%xp(k))/sim%m%dt; vy = (s%y(k) - s%yp(k))/sim%m%dt
      else if (sim%m%integrator == int_velocity_verlet) then
        vx = s%xp(k); vy = s%yp(k)
      else
        vx = s%vx(k); vy = s%vy(k)
      end if
    end associate
  end subroutine guard_velocity

  !> The likely cause of a pair closer than min_distance, from what the state
  !> shows: if the pair closed half of its distance or more within the last
  !> step, the step does not resolve the approach (dt); otherwise the crush is
  !> most likely physical (measured on the damper: heavy pistons crush the bed
  !> at the same time for dt = 5e-4 .. 2e-2 T, closing 1 .. 32 % per step), and
  !> the message says how to confirm it (dt/2 stops at the same time) and, for a
  !> free piston, compares its weight with the bed's push on it (weight larger:
  !> the bed cannot hold it; push larger: the impact).
  function crush_cause(sim, bi, bj) result(text)
    type(sim_t), intent(in) :: sim
    integer, intent(in) :: bi, bj
    character(len=:), allocatable :: text
    character(len=600) :: buf, head
    real(dp) :: dx, dy, d, vix, viy, vjx, vjy, closing, w, v
    associate (s => sim%s, m => sim%m)
      dx = s%x(bi) - s%x(bj); dy = s%y(bi) - s%y(bj)
      d = max(sqrt(dx*dx + dy*dy), tiny(1.0_dp))
      call guard_velocity(sim, bi, vix, viy)
      call guard_velocity(sim, bj, vjx, vjy)
      closing = -((vix - vjx)*dx + (viy - vjy)*dy)/d*m%dt   ! [D1 per step]
      if (closing > 0.5_dp*d) then
        write(buf, '(a,es10.3,a,f6.1,a)') 'the pair closed ', closing, ' D1 in the last step (', &
             100*closing/d, ' % of its distance): the time step does not resolve this approach; '// &
             'reduce dt'
        text = trim(buf)
        return
      end if
      write(head, '(a,es10.3,a,f5.1,a)') 'physical crush (the pair closed ', closing, ' D1, ', &
           100*closing/d, ' % of its distance, in the last step: the step resolves the '// &
           'approach, dt is not the likely cause; a run at dt/2 stopping at the same time confirms it)'
      if (m%piston_mode == piston_free) then
        w = m%piston_mass*merge(m%big_g, 0.0_dp, m%gravity_on)
        v = sim%pst%vy(1)
        if (sim%pst%has_previous .and. m%integrator == int_stormer_verlet) &
             v = (sim%pst%y(1) - sim%pst%yp(1))/m%dt
        if (sim%pst%has_previous .and. m%integrator == int_velocity_verlet) v = sim%pst%yp(1)
        if (s%piston_force < w) then
          write(buf, '(a,es10.3,a,es10.3,a)') ': the piston''s weight (', w, &
               ' m1 g) exceeds what the bed can hold at min_distance (its push on the piston is ', &
               s%piston_force, ' m1 g); use a lighter piston or a wider bed'
        else
          write(buf, '(a,es10.3,a,es10.3,a,es10.3,a)') ': the impact of the piston (speed ', v, &
               ' D1/T, weight ', w, ' m1 g) squeezes the bed below min_distance although its '// &
               'push (', s%piston_force, ' m1 g) exceeds the weight; use a lighter piston, '// &
               'a lower h_start or more damping'
        end if
      else if (m%piston_mode == piston_prescribed) then
        write(buf, '(a,es10.3,a)') ': the piston pushes with ', s%piston_force, &
             ' m1 g and squeezes a pair below min_distance; compress less (hf, phi_final)'
      else
        buf = ': the pair is pushed below min_distance by the bed''s own load; check the scene'
      end if
    end associate
    text = trim(head)//trim(buf)
  end function crush_cause

  !> The likely cause of a free piston outside (0, height]: launched upwards
  !> (too light or too fast for the bed's push) or pushed through the floor.
  function piston_exit_cause(sim) result(text)
    type(sim_t), intent(in) :: sim
    character(len=:), allocatable :: text
    character(len=500) :: buf
    real(dp) :: v, w
    associate (s => sim%s, m => sim%m, pst => sim%pst)
      v = pst%vy(1)
      if (pst%has_previous .and. m%integrator == int_stormer_verlet) v = (pst%y(1) - pst%yp(1))/m%dt
      if (pst%has_previous .and. m%integrator == int_velocity_verlet) v = pst%yp(1)
      w = m%piston_mass*merge(m%big_g, 0.0_dp, m%gravity_on)
      if (s%piston_h > m%height) then
        write(buf, '(a,es10.3,a,es10.3,a,es10.3,a)') 'it left upwards at ', v, &
             ' D1/T: the bed launched it, the piston is too light (weight ', w, &
             ' m1 g; the bed pushed it with ', s%piston_force, ' m1 g at the last step) or '// &
             'too fast; raise piston_mass, lower h_start or make the cell taller'
      else if (s%piston_h <= 0) then
        write(buf, '(a,es10.3,a,es10.3,a)') 'it went through the floor at ', v, &
             ' D1/T: too heavy for the bed (weight ', w, ' m1 g); lower piston_mass'
      else
        write(buf, '(a,es10.3,a)') 'its height is not finite (speed ', v, &
             ' D1/T); check the scene'
      end if
    end associate
    text = trim(buf)
  end function piston_exit_cause

  !> Kinetic + gravitational energy of a free piston [m1 g D1] (0 otherwise).
  real(dp) function piston_energy(sim) result(e)
    type(sim_t), intent(in) :: sim
    e = 0
    if (sim%m%piston_mode /= piston_free) return
    e = 0.5_dp*sim%m%piston_mass*sim%pst%vy(1)**2
    if (sim%m%gravity_on) e = e + sim%m%big_g*sim%m%piston_mass*sim%pst%y(1)
  end function piston_energy

  !> Pairs the kernel evaluates per step (current list, or all pairs).
  integer(i8) function pairs_per_step(sim)
    type(sim_t), intent(in) :: sim
    if (sim%m%neighbour == nb_all_pairs .or. .not. sim%nl%valid) then
      pairs_per_step = int(sim%s%n, i8)*int(sim%s%n - 1, i8)/2
    else
      pairs_per_step = sim%nl%pairs
    end if
  end function pairs_per_step

  !> Energies [m1 g D1]: kinetic, pair, wall, gravity.
  subroutine sim_energy(sim, ek, ep, ew, eg)
    type(sim_t), intent(in) :: sim
    real(dp), intent(out) :: ek, ep, ew, eg
    associate (s => sim%s, m => sim%m)
      ek = kinetic_energy(s%n, s%mass, s%vx, s%vy)
      ep = 0
      if (m%pair_law == law_dipole) ep = pair_energy_all(s%n, s%x, s%y, s%mu, m%k_pair)
      ew = wall_energy(s%n, s%x, s%y, s%mu, m%wall_law, m%k_wall, m%width, s%piston_h, &
           m%piston_mode /= piston_none)
      eg = 0
      if (m%gravity_on) eg = m%big_g*sum(s%mass*s%y)
    end associate
  end subroutine sim_energy

  logical function due(every, step, force)
    integer, intent(in) :: every
    integer(i8), intent(in) :: step
    logical, intent(in) :: force
    due = every > 0 .and. (force .or. mod(step, int(every, i8)) == 0)
  end function due

  !> One step: forces at step n, outputs of step n, advance to n+1.
  !> final = .true. evaluates and writes the last state without advancing.
  subroutine sim_step(sim, st, final)
    type(sim_t), intent(inout) :: sim
    type(status_t), intent(inout) :: st
    logical, intent(in), optional :: final
    logical :: last, o_pis, o_frm, o_dst, o_en, moving
    real(dp) :: ek, ep, ew, eg
    last = .false.
    if (present(final)) last = final
    associate (s => sim%s, m => sim%m)
      s%t = real(s%step, dp)*m%dt
      call piston_at(sim%p, s%t, s%piston_h, s%phase)
      moving = .false.
      if (m%piston_mode == piston_free) then
        if (sim%pst%nudge_step >= 0) then   ! (also after a resume: the nudge step is state)
          sim%p%n_steps = sim%pst%nudge_step + sim%p%record_steps
          if (s%step >= sim%pst%nudge_step) s%phase = 7
        end if
        call free_piston_begin(sim, moving)
      end if
      o_pis = sim%writing .and. due(sim%sc%piston_every, s%step, last)
      o_frm = sim%writing .and. due(sim%sc%frame_every, s%step, last)
      o_dst = sim%writing .and. due(sim%sc%distance_every, s%step, last)
      o_en = sim%writing .and. due(sim%sc%energy_every, s%step, last)
      if (sim%need_velocity) call estimate_velocity(m%integrator, m%dt, s, m%friction_implicit)
      call sim_forces(sim, o_frm, st)
      if (st%code /= 0) return
      if (moving) then   ! Newton's third law: the particles' push, weight, drag
        sim%pst%fx = 0
        sim%pst%fy = s%piston_force - m%big_g*m%piston_mass*merge(1, 0, m%gravity_on) &
             - m%piston_gamma*m%piston_mass*sim%pst%vy
        if (sim%p%nudge > 0 .and. sim%pst%nudge_step < 0) call settle_check(sim, st)
        if (st%code /= 0) return
      end if
      if (o_frm .or. o_en .or. last) then
        call finish_velocity(m%integrator, m%dt, s)
        if (moving) call finish_velocity(m%integrator, m%dt, sim%pst)
      end if
      if (o_pis) call write_piston(sim%o, s, packing_fraction(sim%area, m%width, s%piston_h))
      if (o_frm) call write_frame(sim%o, s)
      if (o_dst) call write_distance(sim%o, s, mean_distance(s%n, s%x, s%y))
      if (o_en) then
        call sim_energy(sim, ek, ep, ew, eg)
        call write_energy(sim%o, s, ek, ep, ew, eg, piston_energy(sim))
      end if
      if (last) return
      call advance(m%integrator, m%dt, s)
      if (moving) call advance(m%integrator, m%dt, sim%pst)
      s%step = s%step + 1
      s%t = real(s%step, dp)*m%dt
    end associate
  end subroutine sim_step

end module engine
