!> The pair laws' evaluations built and measured at load (not in any step): the r^2 tables
!> fitted to a requested error (table_fit, dipole_table, lj_table), and the largest and rms
!> relative errors of single and rsqrt measured on eval_samples points through the routines
!> the loops use (dipole_eval, lj_chunk of module pair_forces), which run.json reports.
!> ok = .false. when an evaluation cannot reach the scene's pair_table_error.
module pair_eval
  use kinds, only: dp
  use pair_table, only: pair_table_t, law_i, table_pieces, segment_bounds, max_bits, &
       eval_exact, eval_table
  use pair_forces, only: lj_law_t, split_t, dipole_kernel, lj_kernel, dipole_eval, lj_chunk, &
       table_values, pair_chunk, kernel_lj6
  implicit none
  private

  public :: dipole_table, lj_table, dipole_eval_build, lj_eval_build

  integer, parameter :: samples = 16   !< error samples inside each table segment (and its ends)
  !> a table is accepted when its measured error times this is within the request (the samples
  !> may miss a segment's largest error by a little; tests check a dense grid of r)
  real(dp), parameter :: margin = 1.05_dp
  !> points (uniform in log r^2, and both ends) at which single and rsqrt are measured at load
  integer, parameter :: eval_samples = 65536

contains

  !> The coarsest table of `law` (nq quantities, u = r^2 in [lo2, hi2]) whose largest
  !> relative error, measured against the law on samples + 1 points of every segment (and
  !> hi2), is <= requested/margin; ok = .false. when max_bits does not reach it (t: the finest).
  subroutine table_fit(law, nq, lo2, hi2, requested, t, ok)
    procedure(law_i) :: law
    integer, intent(in) :: nq
    real(dp), intent(in) :: lo2, hi2, requested
    type(pair_table_t), intent(out) :: t
    logical, intent(out) :: ok
    integer :: bits, k, j, q, ns
    real(dp) :: u0, u1, d, se, e
    real(dp) :: v(nq), dv(nq), mg(nq), got(nq)
    ok = .false.
    do bits = 1, max_bits
      call table_pieces(law, nq, lo2, hi2, bits, t)
      t%requested = requested
      se = 0
      ns = 0
      t%max_err = 0
      do k = 1, t%n
        call segment_bounds(t, k, u0, u1)
        u0 = max(lo2, u0)
        u1 = min(hi2, u1)
        do j = 0, samples
          d = real(j, dp)/real(samples + 1, dp)
          if (k == t%n .and. j == samples) d = 1      ! hi2 itself
          call law(u0 + d*(u1 - u0), v, dv, mg)
          call table_values(t, u0 + d*(u1 - u0), got)
          do q = 1, nq
            e = abs(got(q) - v(q))/mg(q)
            t%max_err = max(t%max_err, e)
            se = se + e*e
            ns = ns + 1
          end do
        end do
      end do
      t%rms_err = sqrt(se/max(1, ns))
      if (t%max_err*margin <= requested) then
        ok = .true.
        return
      end if
    end do
  end subroutine table_fit

  !> Table of the dipole law over r^2 in [lo2, hi2] [D1^2]: quantity 1 the force factor s5 =
  !> r^-5 - shift4 r^-1 (error relative to r^-5 + shift4 r^-1), quantity 2 r^-3 (friction
  !> sums); the reference is dipole_kernel. See table_fit for ok.
  subroutine dipole_table(shift4, lo2, hi2, requested, t, ok)
    real(dp), intent(in) :: shift4, lo2, hi2, requested
    type(pair_table_t), intent(out) :: t
    logical, intent(out) :: ok
    call table_fit(law, 2, lo2, hi2, requested, t, ok)
  contains
    subroutine law(u, v, dv, mag)
      real(dp), intent(in) :: u
      real(dp), intent(out) :: v(:), dv(:), mag(:)
      call dipole_kernel(u, shift4, v(1), v(2))
      dv(1) = -2.5_dp*u**(-3.5_dp) + 0.5_dp*shift4*u**(-1.5_dp)
      dv(2) = -1.5_dp*u**(-2.5_dp)
      mag(1) = u**(-2.5_dp) + shift4*u**(-0.5_dp)
      mag(2) = v(2)
    end subroutine law
  end subroutine dipole_table

  !> Table of the Lennard-Jones law l over r^2 in [r_m^2, R^2] [a^2] (the linear core below
  !> r_m and the zero beyond R stay exact in the loops): the force factor of lj_kernel, error
  !> relative to the magnitudes of its two terms, 4 p U0 r^-2 (2 q^2 + q) (the force itself
  !> vanishes at the well's bottom). See table_fit for ok.
  subroutine lj_table(l, requested, t, ok)
    type(lj_law_t), intent(in) :: l
    real(dp), intent(in) :: requested
    type(pair_table_t), intent(out) :: t
    logical, intent(out) :: ok
    call table_fit(law, 1, l%rm2, l%rc2, requested, t, ok)
  contains
    subroutine law(u, v, dv, mag)
      real(dp), intent(in) :: u
      real(dp), intent(out) :: v(:), dv(:), mag(:)
      real(dp) :: a, b, p
      type(lj_law_t) :: inside
      p = real(l%p, dp)
      inside = l
      inside%rm2 = 0          ! the power law at u = r_m^2 too (the piece's end)
      inside%rc2 = huge(1.0_dp)
      call lj_kernel(inside, u, v(1))
      a = 2*4.0_dp**p*u**(-p - 1)          ! s = c4p (a - b)
      b = 2.0_dp**p*u**(-p/2 - 1)
      dv(1) = l%c4p*((-p - 1)*a - (-p/2 - 1)*b)/u
      mag(1) = l%c4p*(a + b)
    end subroutine law
  end subroutine lj_table

  !> The dipole law's evaluation `code` (eval_*) over r^2 in [lo2, hi2] [D1^2] for a run: the
  !> exact law (t off), the table (dipole_table), or single / rsqrt, whose largest and rms
  !> relative errors (s5 relative to r^-5 + shift4 r^-1, and r^-3) are measured on
  !> eval_samples points uniform in log r^2 (and both ends) through dipole_eval, the routine
  !> the loops use; ok = .false. when the largest error times margin exceeds `requested`.
  subroutine dipole_eval_build(code, shift4, lo2, hi2, requested, t, ok)
    integer, intent(in) :: code
    real(dp), intent(in) :: shift4, lo2, hi2, requested
    type(pair_table_t), intent(out) :: t
    logical, intent(out) :: ok
    real(dp), allocatable :: u(:), v(:, :), ex(:, :), mag(:, :)
    integer :: m0
    ok = .true.
    if (code == eval_exact) return
    if (code == eval_table) then
      call dipole_table(shift4, lo2, hi2, requested, t, ok)
      return
    end if
    allocate(u(eval_samples), v(eval_samples, 2), ex(eval_samples, 2), mag(eval_samples, 2))
    call eval_grid(code, lo2, hi2, requested, t, u)
    v = 1
    do m0 = 1, eval_samples, pair_chunk
      call dipole_eval(min(pair_chunk, eval_samples - m0 + 1), u(m0:), shift4, split_t(), &
           huge(1.0_dp), 1.0_dp, 1.0_dp, v(m0:, 1), v(m0:, 2), t)
    end do
    call dipole_kernel(u, shift4, ex(:, 1), ex(:, 2))
    mag(:, 1) = u**(-2.5_dp) + shift4*u**(-0.5_dp)
    mag(:, 2) = ex(:, 2)
    call eval_errors(abs(v - ex)/mag, requested, t, ok)
  end subroutine dipole_eval_build

  !> The Lennard-Jones law's evaluation `code` for a run, as dipole_eval_build: over [r_m^2,
  !> R^2) [a^2] through lj_chunk, the error relative to the magnitudes of the law's two terms
  !> (as lj_table). single and rsqrt exist for p = 6 only (ok = .false. otherwise, max_err 0).
  subroutine lj_eval_build(code, l, requested, t, ok)
    integer, intent(in) :: code
    type(lj_law_t), intent(in) :: l
    real(dp), intent(in) :: requested
    type(pair_table_t), intent(out) :: t
    logical, intent(out) :: ok
    real(dp), allocatable :: u(:), v(:, :), ex(:, :), mag(:, :), q(:)
    type(lj_law_t) :: inside
    integer :: m0
    ok = .true.
    if (code == eval_exact) return
    if (code == eval_table) then
      call lj_table(l, requested, t, ok)
      return
    end if
    ok = l%kernel == kernel_lj6
    if (.not. ok) return
    allocate(u(eval_samples), v(eval_samples, 1), ex(eval_samples, 1), mag(eval_samples, 1), &
         q(eval_samples))
    ! [r_m^2, R^2): the power law's end at r_m is evaluated as the loops do (at r_m: not a core
    ! pair), R^2 itself is beyond the cut-off
    call eval_grid(code, l%rm2*(1 + epsilon(1.0_dp)), l%rc2*(1 - epsilon(1.0_dp)), requested, t, u)
    do m0 = 1, eval_samples, pair_chunk
      call lj_chunk(l, min(pair_chunk, eval_samples - m0 + 1), u(m0:), v(m0:, 1), t)
    end do
    inside = l
    inside%rm2 = 0
    inside%rc2 = huge(1.0_dp)
    call lj_kernel(inside, u, ex(:, 1))
    q = (4.0_dp/u)**(l%p/2)
    mag(:, 1) = l%c4p/u*(2*q*q + q)
    call eval_errors(abs(v - ex)/mag, requested, t, ok)
    t%lo2 = l%rm2
    t%hi2 = l%rc2
  end subroutine lj_eval_build

  !> Evaluation `code` over [lo2, hi2] (t: no table) and its error samples u: uniform in log u
  !> from lo2 to hi2, both ends included.
  pure subroutine eval_grid(code, lo2, hi2, requested, t, u)
    integer, intent(in) :: code
    real(dp), intent(in) :: lo2, hi2, requested
    type(pair_table_t), intent(out) :: t
    real(dp), intent(out) :: u(:)
    integer :: m
    t%eval = code
    t%lo2 = lo2
    t%hi2 = hi2
    t%requested = requested
    u = [(lo2*(hi2/lo2)**(real(m - 1, dp)/real(size(u) - 1, dp)), m = 1, size(u))]
    u(size(u)) = hi2
  end subroutine eval_grid

  !> t%max_err, t%rms_err from the relative errors e of every sample and quantity; ok when
  !> the largest times margin is within `requested`.
  pure subroutine eval_errors(e, requested, t, ok)
    real(dp), intent(in) :: e(:, :), requested
    type(pair_table_t), intent(inout) :: t
    logical, intent(out) :: ok
    t%max_err = maxval(e)
    t%rms_err = sqrt(sum(e*e)/real(size(e), dp))
    ok = t%max_err*margin <= requested .and. t%max_err == t%max_err
  end subroutine eval_errors

end module pair_eval
