!> Mean-field potentials of the seed's four tests and the transport step.
!>
!> Transport (slides, "DSMC: transport"): characteristics d theta/dt = omega,
!> d omega/dt = V(theta, omega), by the first-order semi-implicit Euler
!>   omega^{n+1} = omega^n + dt (F(theta^n) - beta omega^{n+1}),
!>   theta^{n+1} = theta^n + dt omega^{n+1},
!> with F = -(1/I) dW/dtheta the torque per inertia [1/tau^2] (the slides'
!> V with m = I = 1) and the damping beta implicit.
!>
!> Potentials, one routine each (which form the slides' potentials take):
!> * 'none': F = 0 (Test 1, free rotation between collisions).
!> * 'quadratic': W = (alpha/2)(theta - theta_hat)^2 + beta (damping): the
!>   slides' W = (alpha/2)|nu - nu_hat|^2 + beta nu.zeta with the order
!>   parameter nu taken as the angle itself, so that the characteristics are
!>   the slide's linear ODE d/dt [theta, omega] = [[0, 1], [-alpha, -beta]]
!>   [theta, omega] + [0, alpha theta_hat]: fixed point (theta_hat, 0),
!>   eigenvalues (-beta +- sqrt(beta^2 - 4 alpha))/2 (Test 2). theta is not
!>   wrapped. With collisions at temperature T and beta = 0 the equilibrium
!>   is theta ~ Gaussian(theta_hat, T/alpha) (with beta > 0 it cools to 0).
!> * 'dipole': W = alpha sin(theta - theta_hat), F = -(alpha/I) cos(theta -
!>   theta_hat) (Test 3, a dipole in a field). The well is a cosine well with
!>   its minimum at theta_hat - pi/2: the equilibrium in theta is von Mises,
!>   f ~ exp(kappa cos(theta - theta_hat + pi/2)), kappa = alpha/T.
!> * 'onsager': W(theta_1, theta_2) = alpha L^2 |sin(theta_1 - theta_2)|
!>   (Test 4, slides: alpha = 1), mean field
!>   U(theta) = alpha L^2 <|sin(theta - theta_j)|>_j, F = -(1/I) dU/dtheta
!>   (the slide writes V = +L^2 int d|sin| f: a force is minus the gradient;
!>   with the minus sign the potential aligns, as Onsager's excluded volume
!>   does). Two forms:
!>   - 'exact': the O(N^2) pair sum (the reference);
!>   - 'fourier': |sin x| = 2/pi - (4/pi) sum_{k>=1} cos(2kx)/(4k^2 - 1)
!>     truncated at k = K, so U = alpha L^2 sum_k a_k (C_k cos 2k theta +
!>     S_k sin 2k theta), C_k, S_k = <cos 2k theta_j>, <sin 2k theta_j>:
!>     O(N K). Its force coefficients fall as 1/k (the kink of |sin|), the
!>     truncation error is measured in bench/rods_speed.py;
!>   - 'histogram': phi = theta mod pi (|sin| is pi-periodic) deposited on M grid
!>     points of [0, pi) with cloud-in-cell weights w_j, the torque tabulated
!>     exactly against them, F(phi_i) = -(alpha L^2/I) sum_j w_j sign(sin(phi_i -
!>     phi_j)) cos(phi_i - phi_j) (O(M^2), independent of N), and interpolated
!>     linearly at each sample: O(N) without trigonometric calls. Its error is
!>     O(pi/M) (the jump of the kernel's derivative at zero lag).
!>   Linear stability of the isotropic state: with f = (1 + eps cos 2theta)/(2pi)
!>   the field is U = const - eps (2 alpha L^2/(3 pi)) cos 2theta, and
!>   f ~ exp(-U/T) feeds back eps (2 alpha L^2/(3 pi T)): the isotropic state
!>   is unstable for alpha L^2 / T > 3 pi / 2.
!> The interaction energy per sample [m L^2/tau^2]: <W(theta_i)> for the
!> one-body wells, (1/2) <U(theta_i)> for Onsager (pairs counted once).
!
! glibc's vector cos/sin (libmvec; see dsmc_collisions) for the Fourier form and the dipole.
!GCC$ builtin (cos) attributes simd (notinbranch) if('x86_64')
!GCC$ builtin (sin) attributes simd (notinbranch) if('x86_64')
module dsmc_mean_field
  use kinds, only: dp, i8, pi
  use parallel, only: par_min_loop
  implicit none
  private

  public :: field_t, transport, interaction_energy, onsager_modes, onsager_coefficient

  integer, parameter :: chunk = 256   !< samples per vectorised block of the Fourier form
  integer(i8), parameter :: span = 16384   !< samples per chunk of the transport's loops

  type :: field_t
    character(len=16) :: potential = 'none'   !< none | quadratic | dipole | onsager
    character(len=16) :: force = 'fourier'    !< Onsager: exact | fourier | histogram
    real(dp) :: alpha = 0.0_dp                !< strength [m L^2/tau^2]
    real(dp) :: beta = 0.0_dp                 !< damping of 'quadratic' [1/tau]
    real(dp) :: theta_hat = 0.0_dp            !< alignment direction [rad]
    real(dp) :: inertia = 1.0_dp              !< I [m L^2]
    real(dp) :: length = 1.0_dp               !< L [L]
    integer :: modes = 16                     !< Fourier modes K of 'fourier'
    integer :: bins = 512                     !< grid points M of 'histogram'
  end type field_t

contains

  !> a_k of |sin x| = sum_{k>=0} a_k cos(2 k x): a_0 = 2/pi, a_k = -4/(pi (4k^2 - 1)).
  pure function onsager_coefficient(k) result(a)
    integer, intent(in) :: k
    real(dp) :: a
    a = -4.0_dp/(pi*real(4*k*k - 1, dp))
  end function onsager_coefficient

  !> C_k = <cos 2k theta>, S_k = <sin 2k theta>, k = 1..K (powers of e^{2i theta}, by
  !> chunks of samples so that the loops over a chunk vectorise).
  subroutine onsager_modes(theta, kmax, ck, sk)
    real(dp), intent(in) :: theta(:)
    integer, intent(in) :: kmax
    real(dp), intent(out) :: ck(kmax), sk(kmax)
    real(dp), allocatable :: c2(:), s2(:)
    allocate(c2(size(theta)), s2(size(theta)))
    c2 = cos(2.0_dp*theta)
    s2 = sin(2.0_dp*theta)
    call modes_of(c2, s2, kmax, ck, sk)
  end subroutine onsager_modes

  !> The same from z = e^{2 i theta} = c2 + i s2. Partial sums per span of samples (on the
  !> threads), added in span order: the same bits for any thread count.
  subroutine modes_of(c2, s2, kmax, ck, sk)
    real(dp), contiguous, intent(in) :: c2(:), s2(:)
    integer, intent(in) :: kmax
    real(dp), intent(out) :: ck(kmax), sk(kmax)
    real(dp), allocatable :: part(:, :, :)
    integer(i8) :: c, n, ns, k0, k1
    n = size(c2, kind=i8)
    ns = (n + span - 1)/span
    allocate(part(kmax, 2, ns))
    !$omp parallel do schedule(static) if(n >= par_min_loop) private(k0, k1)
    do c = 1, ns
      k0 = (c - 1)*span + 1
      k1 = min(n, c*span)
      call span_modes(k1 - k0 + 1, c2(k0:k1), s2(k0:k1), kmax, part(:, 1, c), part(:, 2, c))
    end do
    !$omp end parallel do
    ck = 0.0_dp
    sk = 0.0_dp
    do c = 1, ns
      ck = ck + part(:, 1, c)
      sk = sk + part(:, 2, c)
    end do
    ck = ck/real(n, dp)
    sk = sk/real(n, dp)
  end subroutine modes_of

  !> sum z^k (real and imaginary parts), k = 1..kmax, over the n samples of one span, by chunks
  !> (the powers of a chunk stay in L1; the sums are vectorised reductions).
  pure subroutine span_modes(n, c2, s2, kmax, ck, sk)
    integer(i8), intent(in) :: n
    real(dp), intent(in) :: c2(n), s2(n)
    integer, intent(in) :: kmax
    real(dp), intent(out) :: ck(kmax), sk(kmax)
    real(dp) :: zr(chunk), zi(chunk), pr(chunk), pi_(chunk), tmp, sc, ss
    integer(i8) :: i0
    integer :: k, m, b
    ck = 0.0_dp
    sk = 0.0_dp
    do i0 = 1, n, chunk
      m = int(min(int(chunk, i8), n - i0 + 1))
      do b = 1, m
        zr(b) = c2(i0 + b - 1)
        zi(b) = s2(i0 + b - 1)
        pr(b) = zr(b)
        pi_(b) = zi(b)
      end do
      do k = 1, kmax
        sc = 0.0_dp
        ss = 0.0_dp
        !$omp simd reduction(+: sc, ss) private(tmp)
        do b = 1, m
          sc = sc + pr(b)
          ss = ss + pi_(b)
          tmp = pr(b)*zr(b) - pi_(b)*zi(b)
          pi_(b) = pr(b)*zi(b) + pi_(b)*zr(b)
          pr(b) = tmp
        end do
        ck(k) = ck(k) + sc
        sk(k) = sk(k) + ss
      end do
    end do
  end subroutine span_modes

  !> One transport step of all samples (semi-implicit Euler, header), and the guard's sums of
  !> the new state from the same pass: absum = sum |theta| + |omega| (NaN and Inf propagate
  !> into it), thmax = max |theta| [rad]. The one-body wells kick and drift in one loop; the
  !> loops run by chunks of `span` samples (on the threads), each a vectorised kernel.
  subroutine transport(f, dt, theta, omega, absum, thmax)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: dt
    real(dp), contiguous, intent(inout) :: theta(:), omega(:)
    real(dp), intent(out) :: absum, thmax
    real(dp) :: g, damp, s, tm
    integer(i8) :: c, k0, k1, n
    integer :: form
    n = size(theta, kind=i8)
    select case (trim(f%potential))
    case ('quadratic')
      form = 1
    case ('dipole')
      form = 2
    case ('onsager')
      form = 0
      select case (trim(f%force))
      case ('exact')
        call kick_onsager_exact(f, dt, theta, omega)
      case ('histogram')
        call kick_onsager_histogram(f, dt, theta, omega)
      case default
        call kick_onsager_fourier(f, dt, theta, omega)
      end select
    case default
      form = 0
    end select
    g = dt*(f%alpha/f%inertia)
    damp = 1.0_dp + dt*f%beta
    absum = 0.0_dp
    thmax = 0.0_dp
    !$omp parallel do schedule(static) if(n >= par_min_loop) private(k0, k1, s, tm) &
    !$omp reduction(+: absum) reduction(max: thmax)
    do c = 1, (n + span - 1)/span
      k0 = (c - 1)*span + 1
      k1 = min(n, c*span)
      select case (form)
      case (1)
        call step_quadratic(k1 - k0 + 1, dt, g, f%theta_hat, damp, theta(k0:k1), omega(k0:k1), &
             s, tm)
      case (2)
        call step_dipole(k1 - k0 + 1, dt, g, f%theta_hat, theta(k0:k1), omega(k0:k1), s, tm)
      case default
        call drift(k1 - k0 + 1, dt, theta(k0:k1), omega(k0:k1), s, tm)
      end select
      absum = absum + s
      thmax = max(thmax, tm)
    end do
    !$omp end parallel do
  end subroutine transport

  !> theta += dt omega on n samples; s = sum |theta| + |omega|, tm = max |theta| after.
  pure subroutine drift(n, dt, theta, omega, s, tm)
    integer(i8), intent(in) :: n
    real(dp), intent(in) :: dt
    real(dp), intent(inout) :: theta(n)
    real(dp), intent(in) :: omega(n)
    real(dp), intent(out) :: s, tm
    integer(i8) :: k
    s = 0.0_dp
    tm = 0.0_dp
    !$omp simd reduction(+: s) reduction(max: tm)
    do k = 1, n
      theta(k) = theta(k) + dt*omega(k)
      s = s + abs(theta(k)) + abs(omega(k))
      tm = max(tm, abs(theta(k)))
    end do
  end subroutine drift

  !> 'quadratic': omega = (omega - g (theta - theta_hat))/damp, g = dt alpha/I,
  !> damp = 1 + dt beta, then the drift; s, tm as in drift.
  pure subroutine step_quadratic(n, dt, g, theta_hat, damp, theta, omega, s, tm)
    integer(i8), intent(in) :: n
    real(dp), intent(in) :: dt, g, theta_hat, damp
    real(dp), intent(inout) :: theta(n), omega(n)
    real(dp), intent(out) :: s, tm
    integer(i8) :: k
    s = 0.0_dp
    tm = 0.0_dp
    !$omp simd reduction(+: s) reduction(max: tm)
    do k = 1, n
      omega(k) = (omega(k) - g*(theta(k) - theta_hat))/damp
      theta(k) = theta(k) + dt*omega(k)
      s = s + abs(theta(k)) + abs(omega(k))
      tm = max(tm, abs(theta(k)))
    end do
  end subroutine step_quadratic

  !> 'dipole': omega -= g cos(theta - theta_hat), g = dt alpha/I, then the drift.
  pure subroutine step_dipole(n, dt, g, theta_hat, theta, omega, s, tm)
    integer(i8), intent(in) :: n
    real(dp), intent(in) :: dt, g, theta_hat
    real(dp), intent(inout) :: theta(n), omega(n)
    real(dp), intent(out) :: s, tm
    integer(i8) :: k
    s = 0.0_dp
    tm = 0.0_dp
    !$omp simd reduction(+: s) reduction(max: tm)
    do k = 1, n
      omega(k) = omega(k) - g*cos(theta(k) - theta_hat)
      theta(k) = theta(k) + dt*omega(k)
      s = s + abs(theta(k)) + abs(omega(k))
      tm = max(tm, abs(theta(k)))
    end do
  end subroutine step_dipole

  !> omega += dt F, F_i = -(alpha L^2/I) (1/N) sum_j sign(sin(th_i - th_j)) cos(th_i - th_j).
  subroutine kick_onsager_exact(f, dt, theta, omega)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: dt
    real(dp), intent(in) :: theta(:)
    real(dp), intent(inout) :: omega(:)
    real(dp), allocatable :: c(:), s(:)
    real(dp) :: acc, sn, cs, g
    integer(i8) :: i, j, n
    n = size(theta, kind=i8)
    allocate(c(n), s(n))
    c = cos(theta)
    s = sin(theta)
    g = dt*f%alpha*f%length**2/(f%inertia*real(n, dp))
    do i = 1, n
      acc = 0.0_dp
      do j = 1, n
        sn = s(i)*c(j) - c(i)*s(j)     ! sin(th_i - th_j)
        cs = c(i)*c(j) + s(i)*s(j)     ! cos(th_i - th_j)
        acc = acc + sign(1.0_dp, sn)*cs*merge(0.0_dp, 1.0_dp, sn == 0.0_dp)
      end do
      omega(i) = omega(i) - g*acc
    end do
  end subroutine kick_onsager_exact

  !> omega += dt F with U truncated at K modes:
  !> F = -(alpha L^2/I) sum_k a_k 2k (S_k cos 2k th - C_k sin 2k th) = -(alpha L^2/I) Re sum_k b_k z^k,
  !> b_k = a_k 2k (S_k + i C_k), z = e^{2 i th}.
  subroutine kick_onsager_fourier(f, dt, theta, omega)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: dt
    real(dp), contiguous, intent(in) :: theta(:)
    real(dp), contiguous, intent(inout) :: omega(:)
    real(dp) :: ck(f%modes), sk(f%modes), br(f%modes), bi(f%modes), g
    real(dp) :: pr(chunk), pi_(chunk), acc(chunk), tmp
    real(dp), allocatable :: c2(:), s2(:)
    integer(i8) :: i0, n
    integer :: k, m, b
    allocate(c2(size(theta)), s2(size(theta)))
    c2 = cos(2.0_dp*theta)
    s2 = sin(2.0_dp*theta)
    call modes_of(c2, s2, f%modes, ck, sk)
    do k = 1, f%modes
      br(k) = onsager_coefficient(k)*real(2*k, dp)*sk(k)
      bi(k) = onsager_coefficient(k)*real(2*k, dp)*ck(k)
    end do
    g = dt*f%alpha*f%length**2/f%inertia
    n = size(theta, kind=i8)
    !$omp parallel do schedule(static) if(n >= par_min_loop) &
    !$omp private(m, k, b, pr, pi_, tmp, acc)
    do i0 = 1, n, chunk
      m = int(min(int(chunk, i8), n - i0 + 1))
      do b = 1, m
        pr(b) = c2(i0 + b - 1)
        pi_(b) = s2(i0 + b - 1)
        acc(b) = 0.0_dp
      end do
      do k = 1, f%modes
        do b = 1, m
          acc(b) = acc(b) + br(k)*pr(b) - bi(k)*pi_(b)
          tmp = pr(b)*c2(i0 + b - 1) - pi_(b)*s2(i0 + b - 1)
          pi_(b) = pr(b)*s2(i0 + b - 1) + pi_(b)*c2(i0 + b - 1)
          pr(b) = tmp
        end do
      end do
      do b = 1, m
        omega(i0 + b - 1) = omega(i0 + b - 1) - g*acc(b)
      end do
    end do
    !$omp end parallel do
  end subroutine kick_onsager_fourier

  !> Cloud-in-cell weights of phi = theta mod pi on the M points phi_i = (i-1) pi/M
  !> (periodic), normalised to sum 1.
  subroutine deposit(theta, m, w)
    real(dp), intent(in) :: theta(:)
    integer, intent(in) :: m
    real(dp), intent(out) :: w(m)
    real(dp) :: wx(m + 1), fr
    integer(i8) :: k
    integer :: c
    wx = 0.0_dp
    do k = 1, size(theta, kind=i8)
      call locate(theta(k), m, c, fr)
      wx(c + 1) = wx(c + 1) + (1.0_dp - fr)
      wx(c + 2) = wx(c + 2) + fr            ! slot m + 1 is grid point 1 (periodic)
    end do
    w = wx(1:m)
    w(1) = w(1) + wx(m + 1)
    w = w/real(size(theta), dp)
  end subroutine deposit

  !> Grid cell c in 0..m-1 and fraction fr in [0, 1) of phi = theta mod pi.
  pure subroutine locate(theta, m, c, fr)
    real(dp), intent(in) :: theta
    integer, intent(in) :: m
    integer, intent(out) :: c
    real(dp), intent(out) :: fr
    real(dp) :: y, x
    y = theta*(1.0_dp/pi)
    x = y - real(int(y, i8), dp)                 ! truncation: a plain conversion, no libm call
    x = (x + merge(1.0_dp, 0.0_dp, x < 0.0_dp))*real(m, dp)   ! in [0, m], branch-free

    c = min(int(x), m - 1)
    fr = x - real(c, dp)
  end subroutine locate

  !> omega += dt F with F tabulated on the grid against the deposited weights and
  !> interpolated linearly (header, 'histogram').
  subroutine kick_onsager_histogram(f, dt, theta, omega)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: dt
    real(dp), intent(in) :: theta(:)
    real(dp), intent(inout) :: omega(:)
    real(dp) :: w(f%bins), tab(f%bins + 1), kern(0:f%bins - 1), g, lag, fr
    integer :: i, j, m, c
    integer(i8) :: k
    m = f%bins
    call deposit(theta, m, w)
    ! d|sin x|/dx = sign(sin x) cos x at lag x = l pi/M, l = 0..M-1 (zero at l = 0)
    kern(0) = 0.0_dp
    do i = 1, m - 1
      lag = real(i, dp)*pi/real(m, dp)
      kern(i) = cos(lag)
    end do
    do i = 1, m
      g = 0.0_dp
      do j = 1, m
        g = g + w(j)*kern(modulo(i - j, m))
      end do
      tab(i) = g
    end do
    tab(m + 1) = tab(1)
    g = dt*f%alpha*f%length**2/f%inertia
    !$omp parallel do schedule(static) if(size(theta) >= par_min_loop) private(c, fr)
    do k = 1, size(theta, kind=i8)
      call locate(theta(k), m, c, fr)
      omega(k) = omega(k) - g*((1.0_dp - fr)*tab(c + 1) + fr*tab(c + 2))
    end do
    !$omp end parallel do
  end subroutine kick_onsager_histogram

  !> Interaction energy per sample [m L^2/tau^2] of the same form as the force.
  function interaction_energy(f, theta) result(e)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: theta(:)
    real(dp) :: e
    real(dp), allocatable :: ck(:), sk(:)
    integer(i8) :: i, j, n
    integer :: k
    n = size(theta, kind=i8)
    e = 0.0_dp
    select case (trim(f%potential))
    case ('quadratic')
      e = 0.5_dp*f%alpha*sum((theta - f%theta_hat)**2)/real(n, dp)
    case ('dipole')
      e = f%alpha*sum(sin(theta - f%theta_hat))/real(n, dp)
    case ('onsager')
      if (trim(f%force) == 'histogram') then
        e = histogram_pair_mean(theta, f%bins)
      else if (trim(f%force) == 'exact') then
        do i = 1, n
          do j = 1, n
            e = e + abs(sin(theta(i) - theta(j)))
          end do
        end do
        e = e/real(n, dp)**2
      else
        allocate(ck(f%modes), sk(f%modes))
        call onsager_modes(theta, f%modes, ck, sk)
        e = 2.0_dp/pi
        do k = 1, f%modes
          e = e + onsager_coefficient(k)*(ck(k)**2 + sk(k)**2)
        end do
      end if
      e = 0.5_dp*f%alpha*f%length**2*e
    end select
  end function interaction_energy

  !> <|sin(theta_i - theta_j)|> of the deposited weights (O(M^2)).
  function histogram_pair_mean(theta, m) result(e)
    real(dp), intent(in) :: theta(:)
    integer, intent(in) :: m
    real(dp) :: e, w(m)
    integer :: i, j
    call deposit(theta, m, w)
    e = 0.0_dp
    do i = 1, m
      do j = 1, m
        e = e + w(i)*w(j)*abs(sin(real(i - j, dp)*pi/real(m, dp)))
      end do
    end do
  end function histogram_pair_mean

end module dsmc_mean_field
