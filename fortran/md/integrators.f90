!> Time integrators. Each step is: velocity estimate (only when a force
!> depends on velocity) -> forces f_n -> velocities v_n (only when output is
!> due) -> advance to step n+1.
!>
!> Stormer-Verlet (thesis eqs. 2.16-2.17): x_1 = x_0 + h v_0 + h^2 a_0/2,
!>   x_{n+1} = 2 x_n - x_{n-1} + h^2 a_n,  v_n = (x_{n+1} - x_{n-1})/(2h)
!>   (computed before the update as (x_n - x_{n-1})/h + h a_n/2, the same number).
!> Velocity Verlet (leapfrog form): v_{n+1/2} = v_{n-1/2} + h a_n,
!>   x_{n+1} = x_n + h v_{n+1/2}, v_n = v_{n-1/2} + h a_n/2.
!> Explicit Euler (seed 000): x_{n+1} = x_n + h v_n, v_{n+1} = v_n + h a_n.
!> Semi-implicit (symplectic) Euler: v_{n+1} = v_n + h a_n, x_{n+1} = x_n + h v_{n+1};
!>   hence x_{n+1} - 2 x_n + x_{n-1} = h^2 a_n exactly (what a GNS learns from frames).
!> Velocity-dependent forces (friction) use v_n ~ v_{n-1/2} + h a_{n-1}/2,
!> which makes the Verlet schemes first order in v for those forces only.
module integrators
  use kinds, only: dp
  use parallel, only: par_min_loop, my_share
  use state, only: state_t
  implicit none
  private

  public :: estimate_velocity, finish_velocity, advance
  public :: int_stormer_verlet, int_velocity_verlet, int_euler, int_semi_euler

  !> integrator codes (the systems map their scene's choice onto them)
  integer, parameter :: int_stormer_verlet = 1, int_velocity_verlet = 2, int_euler = 3
  integer, parameter :: int_semi_euler = 4

contains

  !> Before the forces: fx, fy still hold f_{n-1}. Below par_min_loop particles the loop
  !> runs without an OpenMP region (an inactive region still costs ~0.3 us: several per step).
  !> half: v_{n-1/2} only (friction then solved at v_n, friction_at_vn), not v_n ~ v_{n-1/2} +
  !> h a_{n-1}/2.
  subroutine estimate_velocity(method, h, s, half)
    integer, intent(in) :: method
    real(dp), intent(in) :: h
    type(state_t), intent(inout) :: s
    logical, intent(in), optional :: half
    integer :: t, nt
    real(dp) :: ka
    if (.not. s%has_previous) return       ! v_0 is in vx, vy
    if (method /= int_stormer_verlet .and. method /= int_velocity_verlet) return
    ka = 0.5_dp*h
    if (present(half)) then
      if (half) ka = 0
    end if
    if (s%n < par_min_loop) then
      call estimate_range(method, h, ka, s, 1, s%n)
      return
    end if
    !$omp parallel default(shared) private(t, nt)
    call my_share(s%n, t, nt)
    call estimate_range(method, h, ka, s, 1 + ((t - 1)*s%n)/nt, (t*s%n)/nt)
    !$omp end parallel
  end subroutine estimate_velocity

  !> Particles lo..hi of estimate_velocity.
  subroutine estimate_range(method, h, ka, s, lo, hi)
    integer, intent(in) :: method, lo, hi
    real(dp), intent(in) :: h, ka   !< step; weight of a_{n-1} (h/2, or 0 for v_{n-1/2})
    type(state_t), intent(inout) :: s
    integer :: i
    real(dp) :: rh, c
    rh = 1.0_dp/h                    ! one division per particle (c), none per component
    select case (method)
    case (int_stormer_verlet)
      do i = lo, hi
        c = ka/s%mass(i)
        s%vx(i) = (s%x(i) - s%xp(i))*rh + c*s%fx(i)
        s%vy(i) = (s%y(i) - s%yp(i))*rh + c*s%fy(i)
      end do
    case (int_velocity_verlet)
      do i = lo, hi
        c = ka/s%mass(i)
        s%vx(i) = s%xp(i) + c*s%fx(i)   ! xp, yp hold v_{n-1/2} here
        s%vy(i) = s%yp(i) + c*s%fy(i)
      end do
    end select
  end subroutine estimate_range

  !> After the forces f_n: v_n for output.
  subroutine finish_velocity(method, h, s)
    integer, intent(in) :: method
    real(dp), intent(in) :: h
    type(state_t), intent(inout) :: s
    if (.not. s%has_previous) return
    select case (method)
    case (int_stormer_verlet)
      s%vx = (s%x - s%xp)/h + 0.5_dp*h*s%fx/s%mass
      s%vy = (s%y - s%yp)/h + 0.5_dp*h*s%fy/s%mass
    case (int_velocity_verlet)
      s%vx = s%xp + 0.5_dp*h*s%fx/s%mass
      s%vy = s%yp + 0.5_dp*h*s%fy/s%mass
    end select
  end subroutine finish_velocity

  !> x_n -> x_{n+1} using f_n (serial below par_min_loop particles, as estimate_velocity).
  subroutine advance(method, h, s)
    integer, intent(in) :: method
    real(dp), intent(in) :: h
    type(state_t), intent(inout) :: s
    integer :: t, nt
    if (s%n < par_min_loop .or. .not. (method == int_velocity_verlet .or. &
         (method == int_stormer_verlet .and. s%has_previous))) then
      call advance_range(method, h, s, 1, s%n)
    else
      !$omp parallel default(shared) private(t, nt)
      call my_share(s%n, t, nt)
      call advance_range(method, h, s, 1 + ((t - 1)*s%n)/nt, (t*s%n)/nt)
      !$omp end parallel
    end if
    s%has_previous = .true.
  end subroutine advance

  !> Particles lo..hi of advance (has_previous is set by the caller afterwards).
  subroutine advance_range(method, h, s, lo, hi)
    integer, intent(in) :: method, lo, hi
    real(dp), intent(in) :: h
    type(state_t), intent(inout) :: s
    integer :: i
    real(dp) :: xn, yn, ax, ay, c
    select case (method)
    case (int_stormer_verlet)
      if (s%has_previous) then
        do i = lo, hi
          c = h*h/s%mass(i)
          xn = 2*s%x(i) - s%xp(i) + c*s%fx(i)
          yn = 2*s%y(i) - s%yp(i) + c*s%fy(i)
          s%xp(i) = s%x(i); s%yp(i) = s%y(i)
          s%x(i) = xn; s%y(i) = yn
        end do
      else
        do i = lo, hi
          s%xp(i) = s%x(i); s%yp(i) = s%y(i)
          s%x(i) = s%x(i) + h*s%vx(i) + 0.5_dp*h*h*s%fx(i)/s%mass(i)
          s%y(i) = s%y(i) + h*s%vy(i) + 0.5_dp*h*h*s%fy(i)/s%mass(i)
        end do
      end if
    case (int_velocity_verlet)
      do i = lo, hi
        ax = s%fx(i)/s%mass(i); ay = s%fy(i)/s%mass(i)
        if (s%has_previous) then
          s%xp(i) = s%xp(i) + h*ax
          s%yp(i) = s%yp(i) + h*ay
        else
          s%xp(i) = s%vx(i) + 0.5_dp*h*ax
          s%yp(i) = s%vy(i) + 0.5_dp*h*ay
        end if
        s%x(i) = s%x(i) + h*s%xp(i)
        s%y(i) = s%y(i) + h*s%yp(i)
      end do
    case (int_euler)
      do i = lo, hi
        s%x(i) = s%x(i) + h*s%vx(i)
        s%y(i) = s%y(i) + h*s%vy(i)
        s%vx(i) = s%vx(i) + h*s%fx(i)/s%mass(i)
        s%vy(i) = s%vy(i) + h*s%fy(i)/s%mass(i)
      end do
    case (int_semi_euler)
      do i = lo, hi
        s%vx(i) = s%vx(i) + h*s%fx(i)/s%mass(i)
        s%vy(i) = s%vy(i) + h*s%fy(i)/s%mass(i)
        s%x(i) = s%x(i) + h*s%vx(i)
        s%y(i) = s%y(i) + h*s%vy(i)
      end do
    end select
  end subroutine advance_range

end module integrators
