!> Moments, histograms and the entropy estimate of a DSMC sample set.
!>
!> Per sample: T_trans = (m/2) <|v - u|^2> (2 degrees of freedom),
!> T_rot = I <(w - <w>)^2> (1 degree), T = (2 T_trans + T_rot)/3, kinetic
!> energy <m|v|^2/2 + I w^2/2>, momentum m <v>, spin I <w>, order parameters
!> S1 = |<e^{i theta}>|, S2 = |<e^{2 i theta}>|, M4 = <|v|^4> (BKW). Boltzmann's H of the
!> (v_x, v_y, w) marginal from a B^3 histogram on [-v_max, v_max]^2 x
!> [-w_max, w_max] with the Miller-Madow bias correction (- (B_occupied - 1)/(2N)).
module dsmc_moments
  use kinds, only: dp, i8, pi
  implicit none
  private

  public :: moments_t, sample_moments, h_estimate, histogram, wrap_angle

  type :: moments_t
    real(dp) :: t_trans = 0, t_rot = 0, t_all = 0, e_kin = 0, px = 0, py = 0, spin = 0
    real(dp) :: s1 = 0, s2 = 0, m4 = 0
  end type moments_t

contains

  function sample_moments(m, inertia, rotation, v, theta, omega) result(r)
    real(dp), intent(in) :: m, inertia
    logical, intent(in) :: rotation
    real(dp), intent(in) :: v(:, :), theta(:), omega(:)
    type(moments_t) :: r
    real(dp) :: rn, ux, uy, wm, c1, s1, c2, s2
    rn = real(size(theta), dp)
    ux = sum(v(1, :))/rn
    uy = sum(v(2, :))/rn
    wm = sum(omega)/rn
    r%px = m*ux
    r%py = m*uy
    r%spin = inertia*wm
    r%t_trans = 0.5_dp*m*(sum((v(1, :) - ux)**2) + sum((v(2, :) - uy)**2))/rn
    r%t_rot = inertia*sum((omega - wm)**2)/rn
    r%e_kin = 0.5_dp*m*sum(v**2)/rn
    r%m4 = sum((v(1, :)**2 + v(2, :)**2)**2)/rn
    if (rotation) then
      r%e_kin = r%e_kin + 0.5_dp*inertia*sum(omega**2)/rn
      r%t_all = (2.0_dp*r%t_trans + r%t_rot)/3.0_dp
    else
      r%t_all = r%t_trans
    end if
    c1 = sum(cos(theta))/rn; s1 = sum(sin(theta))/rn
    c2 = sum(cos(2.0_dp*theta))/rn; s2 = sum(sin(2.0_dp*theta))/rn
    r%s1 = sqrt(c1*c1 + s1*s1)
    r%s2 = sqrt(c2*c2 + s2*s2)
  end function sample_moments

  !> H = sum p ln(p/dV) - (B_occupied - 1)/(2N) of the (v_x, v_y, w) histogram [1].
  function h_estimate(nb, v_max, w_max, v, omega) result(h)
    integer, intent(in) :: nb
    real(dp), intent(in) :: v_max, w_max
    real(dp), intent(in) :: v(:, :), omega(:)
    real(dp) :: h
    integer, allocatable :: cnt(:, :, :)
    integer(i8) :: i, n
    integer :: ix, iy, iw, occ
    real(dp) :: dv, dw, p, vol
    allocate(cnt(nb, nb, nb))
    cnt = 0
    n = size(omega, kind=i8)
    dv = 2.0_dp*v_max/nb
    dw = 2.0_dp*w_max/nb
    do i = 1, n
      ix = floor((v(1, i) + v_max)/dv) + 1
      iy = floor((v(2, i) + v_max)/dv) + 1
      iw = floor((omega(i) + w_max)/dw) + 1
      if (min(ix, iy, iw) < 1 .or. max(ix, iy) > nb .or. iw > nb) cycle
      cnt(ix, iy, iw) = cnt(ix, iy, iw) + 1
    end do
    vol = dv*dv*dw
    h = 0.0_dp
    occ = 0
    do iw = 1, nb
      do iy = 1, nb
        do ix = 1, nb
          if (cnt(ix, iy, iw) == 0) cycle
          occ = occ + 1
          p = real(cnt(ix, iy, iw), dp)/real(n, dp)
          h = h + p*log(p/vol)
        end do
      end do
    end do
    h = h - real(occ - 1, dp)/(2.0_dp*real(n, dp))
  end function h_estimate

  !> Density [1/unit of x] of x on nb bins of [lo, hi] (counts / (N width)).
  pure function histogram(x, lo, hi, nb) result(f)
    real(dp), intent(in) :: x(:), lo, hi
    integer, intent(in) :: nb
    real(dp) :: f(nb)
    integer(i8) :: i
    integer :: b
    real(dp) :: w
    w = (hi - lo)/nb
    f = 0.0_dp
    do i = 1, size(x, kind=i8)
      b = floor((x(i) - lo)/w) + 1
      if (b >= 1 .and. b <= nb) f(b) = f(b) + 1.0_dp
    end do
    f = f/(real(size(x), dp)*w)
  end function histogram

  !> theta wrapped into [-pi, pi).
  elemental function wrap_angle(theta) result(t)
    real(dp), intent(in) :: theta
    real(dp) :: t
    t = theta - 2.0_dp*pi*floor((theta + pi)/(2.0_dp*pi))
  end function wrap_angle

end module dsmc_moments
