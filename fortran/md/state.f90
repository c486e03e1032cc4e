!> Dynamic state of the particle system, structure of arrays.
module state
  use kinds, only: dp, i8
  implicit none
  private

  public :: state_t, state_allocate, state_permute

  type :: state_t
    integer :: n = 0                       !< number of particles
    real(dp), allocatable :: x(:), y(:)    !< positions at the current step [D1] (n)
    real(dp), allocatable :: vx(:), vy(:)  !< velocities [D1/T] (n); meaning per integrator, see integrators
    real(dp), allocatable :: xp(:), yp(:)  !< Stormer-Verlet: positions at step n-1; velocity Verlet: v_{n-1/2} (n)
    real(dp), allocatable :: fx(:), fy(:)  !< total force at the current step [m1 g] (n)
    real(dp), allocatable :: fmag(:)       !< |magnetic force| (pair + walls) [m1 g] (n), filled on demand
    real(dp), allocatable :: fmx(:), fmy(:)  !< magnetic force (pair + walls) [m1 g] (n), on demand
    real(dp), allocatable :: s3(:)         !< sum_j mu_j sin(theta_j) r_ij^-3 (n), dry friction only
    real(dp), allocatable :: fx_far(:), fy_far(:), s3_far(:)  !< far field at its last evaluation (n)
    real(dp), allocatable :: dfx_far(:), dfy_far(:), ds3_far(:)  !< its change per step between the
                                           !< last two evaluations (tail = 'linear'; else 0) (n)
    integer, allocatable :: id(:)          !< particle id 1..n (arrays are re-sorted by cell) (n)
    integer, allocatable :: species(:)     !< species index (n)
    real(dp), allocatable :: mass(:)       !< m_i/m1 (n)
    real(dp), allocatable :: mu(:)         !< mu_i/mu1 (n)
    real(dp), allocatable :: wsin(:)       !< mu_i sin(theta_i) (n)
    real(dp), allocatable :: nfac(:)       !< normal-force factor (n)
    integer(i8) :: step = 0                !< steps done
    real(dp) :: t = 0                      !< time of the current step [T]
    real(dp) :: piston_h = 0               !< piston height at the current step [D1]
    real(dp) :: piston_force = 0           !< force of the particles on the piston [m1 g]
    real(dp) :: piston_hp = 0              !< free piston: height at step n-1 (SV) or v_{n-1/2} (VV)
    real(dp) :: piston_v = 0               !< free piston: velocity at the current step [D1/T]
    real(dp) :: piston_f = 0               !< free piston: total force on it [m1 g]
    integer :: phase = 0                   !< protocol phase of the current step
    integer(i8) :: nudge_step = -1         !< free piston state: step of the nudge (-1: not yet)
    real(dp) :: calm_since = -1            !< free piston state: settling criterion holds since [T] (-1: not)
    logical :: has_previous = .false.      !< xp, yp valid
    !> which optional arrays hold values in this run (a kind switches off those it never
    !> writes: they stay 0 and state_permute leaves them alone): s3 and its far-field parts;
    !> fx_far, fy_far (+ s3_far); dfx_far, dfy_far (+ ds3_far)
    logical :: with_s3 = .true., with_far = .true., with_far_slope = .true.
    logical :: tail_ready = .false.        !< fx_far, fy_far, s3_far computed
    integer(i8) :: tail_step = 0           !< step of their last evaluation
  end type state_t

contains

  subroutine state_allocate(s, n)
    type(state_t), intent(inout) :: s
    integer, intent(in) :: n
    integer :: i
    s%n = n
    allocate(s%x(n), s%y(n), s%vx(n), s%vy(n), s%xp(n), s%yp(n), s%fx(n), s%fy(n), &
         s%fmag(n), s%s3(n), s%species(n), s%mass(n), s%mu(n), s%wsin(n), s%nfac(n), &
         s%fx_far(n), s%fy_far(n), s%s3_far(n), s%dfx_far(n), s%dfy_far(n), s%ds3_far(n), &
         s%id(n), s%fmx(n), s%fmy(n))
    s%x = 0; s%y = 0; s%vx = 0; s%vy = 0; s%xp = 0; s%yp = 0
    s%fx = 0; s%fy = 0; s%fmag = 0; s%s3 = 0
    s%species = 1; s%mass = 1; s%mu = 1; s%wsin = 0; s%nfac = 0
    s%fx_far = 0; s%fy_far = 0; s%s3_far = 0; s%fmx = 0; s%fmy = 0
    s%dfx_far = 0; s%dfy_far = 0; s%ds3_far = 0
    s%id = [(i, i = 1, n)]
  end subroutine state_allocate

  !> Reorder every per-particle array: new index k holds old particle perm(k) (but for the
  !> optional ones switched off: with_s3, with_far, with_far_slope).
  subroutine state_permute(s, perm)
    type(state_t), intent(inout) :: s
    integer, intent(in) :: perm(:)
    s%x = s%x(perm); s%y = s%y(perm); s%vx = s%vx(perm); s%vy = s%vy(perm)
    s%xp = s%xp(perm); s%yp = s%yp(perm); s%fx = s%fx(perm); s%fy = s%fy(perm)
    s%fmag = s%fmag(perm); s%fmx = s%fmx(perm); s%fmy = s%fmy(perm)
    if (s%with_s3) s%s3 = s%s3(perm)
    if (s%with_far) then
      s%fx_far = s%fx_far(perm); s%fy_far = s%fy_far(perm)
      if (s%with_s3) s%s3_far = s%s3_far(perm)
    end if
    if (s%with_far_slope) then
      s%dfx_far = s%dfx_far(perm); s%dfy_far = s%dfy_far(perm)
      if (s%with_s3) s%ds3_far = s%ds3_far(perm)
    end if
    s%id = s%id(perm); s%species = s%species(perm); s%mass = s%mass(perm)
    s%mu = s%mu(perm); s%wsin = s%wsin(perm); s%nfac = s%nfac(perm)
  end subroutine state_permute

end module state
