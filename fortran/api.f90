!> Thin f2py door: plain scalars and arrays only. Every routine returns a
!> status code and message instead of stopping (a stop would end Python).
module api
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp
  use errors, only: status_t
  use api_state, only: the_sim
  use kinds, only: i8
  use engine, only: sim_t, sim_load, sim_forces, sim_step, sim_energy, piston_energy, &
       time_pair_pass
  use model, only: piston_free
  use runner, only: sim_execute, sim_resume, sim_check, sim_resolve, sim_describe, write_text
  use signals, only: install_handlers, restore_handlers
  use protocol, only: piston_at
  use pair_forces, only: dipole_kernel, dipole_eval, lj_chunk, lj_law, lj_law_t, lj_kernel, &
       pair_table_t, split_t
  use pair_eval, only: dipole_eval_build, lj_eval_build
  use neighbours, only: nlist_due
  use nlist_upkeep, only: nlist_prune_holds
  use integrators, only: estimate_velocity, finish_velocity
  implicit none
  private
  public :: run_scene, resume_run, check_scene, resolve_scene, describe_scene, load_scene, n_particles, get_state, &
       set_state, compute_forces, &
       advance_steps, piston_state, model_groups, energies, kernel, precision_probe, &
       set_threads, list_audit, prune_audit, protocol_times, set_piston, bench_pairs, write_guard_probe, &
       pair_eval_probe

contains

  !> Run a scene exactly as the executable does, writing run directory
  !> `outdir` (overwrite /= 0: replace a run found there). SIGINT/SIGTERM
  !> during the run stop it at the next step with a checkpoint (code 5);
  !> Python's handlers are restored afterwards.
  subroutine run_scene(path, outdir, overwrite, code, message)
    character(len=*), intent(in) :: path, outdir
    integer, intent(in) :: overwrite
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st
    call install_handlers()
    call sim_execute(path, outdir, .false., -1_i8, overwrite /= 0, st)
    call restore_handlers()
    code = st%code
    message = st%msg
  end subroutine run_scene

  !> Continue run directory `rundir` from its checkpoint, as partsim --resume does.
  subroutine resume_run(rundir, code, message)
    character(len=*), intent(in) :: rundir
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st
    call install_handlers()
    call sim_resume(rundir, .false., -1_i8, st)
    call restore_handlers()
    code = st%code
    message = st%msg
  end subroutine resume_run

  !> Validate a scene of any kind (writes nothing); n_steps: units of work of the run.
  subroutine check_scene(path, code, message, n_steps)
    character(len=*), intent(in) :: path
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    integer(i8), intent(out) :: n_steps
    type(status_t) :: st
    call sim_check(path, n_steps, st)
    code = st%code
    message = st%msg
  end subroutine check_scene

  !> The engine's one reading of a scene file, for pyorch: read `path`
  !> (file-level and type checks, no range validation) and write every key
  !> as the engine understood it to `outpath` (the resolved-scene format).
  subroutine resolve_scene(path, outpath, code, message)
    character(len=*), intent(in) :: path, outpath
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st
    call sim_resolve(path, outpath, st)
    code = st%code
    message = st%msg
  end subroutine resolve_scene

  !> The declaration of scene kind `kind` written to `outpath`: JSON (as_json /= 0,
  !> what pyorch checks --set and sweep keys with) or a Markdown table of every key.
  subroutine describe_scene(kind, as_json, outpath, code, message)
    character(len=*), intent(in) :: kind, outpath
    integer, intent(in) :: as_json
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st
    character(len=:), allocatable :: text
    call sim_describe(kind, as_json /= 0, text, st)
    if (st%code == 0) call write_text(outpath, text, st)
    code = st%code
    message = st%msg
  end subroutine describe_scene

  !> Load and validate a bed scene into the in-memory simulation (writes nothing).
  subroutine load_scene(path, code, message)
    character(len=*), intent(in) :: path
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st
    type(sim_t) :: fresh
    the_sim = fresh
    call sim_load(the_sim, path, st)
    code = st%code
    message = st%msg
  end subroutine load_scene

  subroutine n_particles(n)
    integer, intent(out) :: n
    n = the_sim%s%n
  end subroutine n_particles

  !> Current state: positions [D1], velocities [D1/T], forces [m1 g], species.
  subroutine get_state(n, x, y, vx, vy, fx, fy, species, step, t)
    integer, intent(in) :: n
    real(dp), intent(out) :: x(n), y(n), vx(n), vy(n), fx(n), fy(n)
    integer, intent(out) :: species(n)
    integer, intent(out) :: step
    real(dp), intent(out) :: t
    ! arrays are kept re-sorted by cell inside the engine: return them by id
    x(the_sim%s%id) = the_sim%s%x; y(the_sim%s%id) = the_sim%s%y
    vx(the_sim%s%id) = the_sim%s%vx; vy(the_sim%s%id) = the_sim%s%vy
    fx(the_sim%s%id) = the_sim%s%fx; fy(the_sim%s%id) = the_sim%s%fy
    species(the_sim%s%id) = the_sim%s%species
    step = int(the_sim%s%step)
    t = the_sim%s%t
  end subroutine get_state

  !> Replace positions and velocities (restarts the integrator history).
  subroutine set_state(n, x, y, vx, vy, code, message)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), vx(n), vy(n)
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    code = 0
    message = ''
    if (n /= the_sim%s%n) then
      code = 2
      write(message, '(a,i0,a,i0)') 'set_state: got ', n, ' particles, the scene has ', the_sim%s%n
      return
    end if
    if (.not. (all(ieee_is_finite(x)) .and. all(ieee_is_finite(y)) .and. &
         all(ieee_is_finite(vx)) .and. all(ieee_is_finite(vy)))) then
      code = 2
      message = 'set_state: positions and velocities must be finite numbers'
      return
    end if
    the_sim%s%x = x(the_sim%s%id); the_sim%s%y = y(the_sim%s%id)
    the_sim%s%vx = vx(the_sim%s%id); the_sim%s%vy = vy(the_sim%s%id)
    the_sim%s%xp = the_sim%s%x; the_sim%s%yp = the_sim%s%y
    the_sim%s%has_previous = .false.
    the_sim%s%tail_ready = .false.
    the_sim%nl%valid = .false.
  end subroutine set_state

  !> Forces at the current state and time, and the velocities v_n that go
  !> with them (both via get_state; advance_steps alone leaves the
  !> velocity arrays at the integrator's internal stage).
  subroutine compute_forces(code, message)
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st
    call piston_at(the_sim%p, the_sim%s%t, the_sim%s%piston_h, the_sim%s%phase)
    if (the_sim%m%piston_mode == piston_free) the_sim%s%piston_h = the_sim%pst%y(1)
    if (the_sim%need_velocity) call estimate_velocity(the_sim%m%integrator, the_sim%m%dt, &
         the_sim%s)
    call sim_forces(the_sim, .false., st)
    if (st%code == 0) call finish_velocity(the_sim%m%integrator, the_sim%m%dt, the_sim%s)
    code = st%code
    message = st%msg
  end subroutine compute_forces

  !> Advance nsteps steps in memory (no files).
  subroutine advance_steps(nsteps, code, message)
    integer, intent(in) :: nsteps
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st
    integer :: k
    do k = 1, nsteps
      call sim_step(the_sim, st)
      if (st%code /= 0) exit
    end do
    code = st%code
    message = st%msg
  end subroutine advance_steps

  subroutine piston_state(h, force, phase, n_steps)
    real(dp), intent(out) :: h, force
    integer, intent(out) :: phase
    integer(i8), intent(out) :: n_steps   !< 64-bit: long runs exceed 2^31 steps
    h = the_sim%s%piston_h
    force = the_sim%s%piston_force
    phase = the_sim%s%phase
    n_steps = the_sim%p%n_steps
  end subroutine piston_state

  !> Dimensionless groups and SI unit scales of the loaded scene.
  subroutine model_groups(big_f, big_g, k_pair, k_wall, length_m, time_s, force_n)
    real(dp), intent(out) :: big_f, big_g, k_pair, k_wall, length_m, time_s, force_n
    big_f = the_sim%m%big_f; big_g = the_sim%m%big_g
    k_pair = the_sim%m%k_pair; k_wall = the_sim%m%k_wall
    length_m = the_sim%m%length_unit; time_s = the_sim%m%time_unit
    force_n = the_sim%m%force_unit
  end subroutine model_groups

  !> Kinetic, pair, wall, gravitational energy of the particles and the free
  !> piston's kinetic + gravitational energy [m1 g D1] of the current state.
  subroutine energies(ek, ep, ew, eg, epis)
    real(dp), intent(out) :: ek, ep, ew, eg, epis
    call sim_energy(the_sim, ek, ep, ew, eg)
    epis = piston_energy(the_sim)
  end subroutine energies

  !> Free piston: place it at height h [D1] with velocity v [D1/T].
  subroutine set_piston(h, v, code, message)
    real(dp), intent(in) :: h, v
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    code = 0
    message = ''
    if (the_sim%m%piston_mode /= piston_free) then
      code = 2
      message = 'set_piston: the scene has no free piston (&protocol piston = ''free'')'
      return
    end if
    if (.not. (ieee_is_finite(h) .and. ieee_is_finite(v))) then
      code = 2
      message = 'set_piston: h and v must be finite numbers'
      return
    end if
    the_sim%pst%y = h
    the_sim%pst%vy = v
    the_sim%pst%has_previous = .false.
    the_sim%s%piston_h = h
  end subroutine set_piston

  !> The pair kernel itself: r^-5 and r^-3 for a separation (dx, dy).
  subroutine kernel(dx, dy, s5, s3)
    real(dp), intent(in) :: dx, dy
    real(dp), intent(out) :: s5, s3
    call dipole_kernel(dx*dx + dy*dy, 0.0_dp, s5, s3)
  end subroutine kernel

  !> A pair evaluation (&integration / &steric pair_eval; ev: 2 table, 3 single, 4 rsqrt) built
  !> and measured as a run builds it, and evaluated at the n distances r through the routines
  !> the pair loops use: law 1 = dipole over [r_lo, r_hi] with shift a (r_c^-4 or 0): tab(:, 1)
  !> the force factor r^-5 - a r^-1, tab(:, 2) r^-3, ex the exact kernel's, mag the scales of
  !> the relative error (r^-5 + a r^-1, r^-3); law 2 = Lennard-Jones with exponent p (u0 1,
  !> r_m = r_lo, R = r_hi) and only column 1 (mag: its terms' magnitudes). code 0, or 2 when the
  !> requested error is not reached (max_err, rms_err: the errors measured at load; segments:
  !> the table's, 0 for the others).
  subroutine pair_eval_probe(ev, law, p, a, r_lo, r_hi, requested, n, r, tab, ex, mag, max_err, &
       rms_err, segments, code)
    integer, intent(in) :: ev, law, p, n
    real(dp), intent(in) :: a, r_lo, r_hi, requested, r(n)
    real(dp), intent(out) :: tab(n, 2), ex(n, 2), mag(n, 2), max_err, rms_err
    integer, intent(out) :: segments, code
    type(pair_table_t) :: t
    type(lj_law_t) :: l, inside
    logical :: ok
    integer :: i
    real(dp) :: u(n), q
    tab = 0; ex = 0; mag = 1
    u = r**2
    if (law == 1) then
      call dipole_eval_build(ev, a, r_lo**2, r_hi**2, requested, t, ok)
      tab = 1   ! the weights dipole_eval multiplies
      do i = 1, n, 256
        call dipole_eval(min(256, n - i + 1), u(i:), a, split_t(), huge(1.0_dp), 1.0_dp, 1.0_dp, &
             tab(i:, 1), tab(i:, 2), t)
      end do
    else
      l = lj_law(p, 1.0_dp, r_lo, r_hi)
      call lj_eval_build(ev, l, requested, t, ok)
      do i = 1, n, 256
        call lj_chunk(l, min(256, n - i + 1), u(i:), tab(i:, 1), t)
      end do
      inside = l
      inside%rm2 = 0
      inside%rc2 = huge(1.0_dp)
    end if
    code = merge(0, 2, ok)
    max_err = t%max_err
    rms_err = t%rms_err
    segments = t%n
    do i = 1, n
      if (law == 1) then
        call dipole_kernel(u(i), a, ex(i, 1), ex(i, 2))
        mag(i, 1) = u(i)**(-2.5_dp) + a*u(i)**(-0.5_dp)
        mag(i, 2) = ex(i, 2)
      else
        call lj_kernel(inside, u(i), ex(i, 1))
        q = (2.0_dp/r(i))**p
        mag(i, 1) = l%c4p/u(i)*(2*q*q + q)
      end if
    end do
  end subroutine pair_eval_probe

  !> Protocol of the loaded scene: heights [D1] and phase durations [T].
  subroutine protocol_times(h_start, h0, hf, t_relax, t_comp, t_total)
    real(dp), intent(out) :: h_start, h0, hf, t_relax, t_comp, t_total
    h_start = the_sim%p%h_start; h0 = the_sim%p%h0; hf = the_sim%p%hf
    t_relax = the_sim%p%t_relax; t_comp = the_sim%p%t_comp; t_total = the_sim%p%t_total
  end subroutine protocol_times

  !> Time nrep pair passes at the current positions: seconds, pairs per pass.
  subroutine bench_pairs(nrep, seconds, pairs)
    integer, intent(in) :: nrep
    real(dp), intent(out) :: seconds
    integer, intent(out) :: pairs
    integer(i8) :: p8
    call time_pair_pass(the_sim, nrep, seconds, p8)
    pairs = int(p8)
  end subroutine bench_pairs

  !> Number of OpenMP threads for the force loops (no-op without OpenMP).
  subroutine set_threads(n)
    use parallel, only: choose_threads
    integer, intent(in) :: n
    call choose_threads(n)
  end subroutine set_threads

  !> Audit of the neighbour list against brute force at the current positions:
  !> pairs closer than r_c missing from the list (must be 0), list builds so
  !> far and pairs in the list. A strategy without list reports zeros.
  subroutine list_audit(missing, builds, pairs)
    integer, intent(out) :: missing, builds, pairs
    missing = 0
    builds = int(the_sim%nl%builds)
    pairs = int(the_sim%nl%pairs)
    if (.not. the_sim%nl%valid) return
    ! a due rebuild happens before the next force evaluation: nothing can be missed
    if (nlist_due(the_sim%nl, the_sim%s%n, the_sim%s%x, the_sim%s%y)) return
    missing = missing_pairs(the_sim%nl%start, the_sim%nl%nbr)
  end subroutine list_audit

  !> Audit of the pruned list (nlist_t) the next force evaluation would use as it is (one
  !> that no longer holds is taken again first: then nothing can be missed): pairs closer than
  !> r_c missing from it (must be 0), prunes so far and pairs in it. No pruned list: zeros.
  subroutine prune_audit(missing, prunes, pairs)
    integer, intent(out) :: missing, prunes, pairs
    missing = 0
    prunes = int(the_sim%nl%prunes)
    pairs = int(the_sim%nl%ppairs)
    if (nlist_due(the_sim%nl, the_sim%s%n, the_sim%s%x, the_sim%s%y)) return   ! rebuilt first
    if (.not. nlist_prune_holds(the_sim%nl, the_sim%s%n, the_sim%s%x, the_sim%s%y)) return
    missing = missing_pairs(the_sim%nl%pstart, the_sim%nl%pnbr)
  end subroutine prune_audit

  !> Pairs i < j closer than r_c at the current positions that the half list (start, nbr)
  !> lacks (brute force over all pairs).
  integer function missing_pairs(start, nbr) result(missing)
    integer, intent(in) :: start(:), nbr(:)
    integer :: i, j
    real(dp) :: rc2
    missing = 0
    rc2 = the_sim%m%r_cut**2
    associate (s => the_sim%s)
      do i = 1, s%n - 1
        do j = i + 1, s%n
          if ((s%x(i) - s%x(j))**2 + (s%y(i) - s%y(j))**2 >= rc2) cycle
          if (.not. any(nbr(start(i):start(i + 1) - 1) == j)) missing = missing + 1
        end do
      end do
    end associate
  end function missing_pairs

  !> The shared write guards of every kind's outputs, exercised directly:
  !> write `dir/name` fresh with one row at `step` (as_frames = 0: a text
  !> table through module tables, the step then the values) or one frame
  !> record (as_frames = 1: binary frames through module frames, one column
  !> 'x' of the n values). A NaN/Infinity value is refused (code 3, the
  !> message names the file and the step) and its row or record is not written.
  subroutine write_guard_probe(dir, name, as_frames, n, values, step, code, message)
    use tables, only: table_t, table_open, table_line, table_close, rfmt
    use frames, only: frames_t, frames_open, frames_begin, frames_put, frames_end, frames_close
    character(len=*), intent(in) :: dir, name
    integer, intent(in) :: as_frames, n
    real(dp), intent(in) :: values(n)
    integer(i8), intent(in) :: step
    integer, intent(out) :: code
    character(len=1024), intent(out) :: message
    type(status_t) :: st, st2
    type(table_t) :: tb
    type(frames_t) :: fr
    character(len=:), allocatable :: line
    character(len=32) :: buf
    integer :: k
    if (as_frames /= 0) then
      call frames_open(fr, trim(dir)//'/'//trim(name), n, ['x'], [''], ['f8'], 'step', 'T', '', &
           .false., st)
      call frames_begin(fr, step, real(step, dp), st)
      call frames_put(fr, values, st)
      call frames_end(fr, st)
      st2 = st
      call frames_close(fr, st2)
    else
      call table_open(tb, dir, name, '# probe table', '# step values', .false., st)
      write(buf, '(i0)') step
      line = trim(buf)
      do k = 1, n
        write(buf, '('//rfmt//')') values(k)
        line = line//' '//trim(buf)
      end do
      call table_line(tb, line, st)
      st2 = st
      call table_close(tb, st2)
    end if
    if (st%code == 0) st = st2
    code = st%code
    message = st%msg
  end subroutine write_guard_probe

  !> 1 + 2^-40 survives only in double precision (a check of the f2py kind map).
  subroutine precision_probe(x, y)
    real(dp), intent(in) :: x
    real(dp), intent(out) :: y
    y = x + 2.0_dp**(-40)
  end subroutine precision_probe

end module api
