!> External force fields F_ext(x, t) of seed 000 ("known as functions of time and space"),
!> kind 'lj_box'. Units: length a, time T = sqrt(a/g), force m g (unit mass).
!>
!> Shapes (dx = x - x0, dy = y - y0, r = |(dx, dy)|, A = amplitude,
!> e = (ux, uy) = (ex, ey)/|(ex, ey)|: set by the kind, ex and ey kept as the scene gives them):
!>   uniform          F = (f0x, f0y)
!>   gradient         F = (f0x + gxx dx + gxy dy,  f0y + gyx dx + gyy dy)
!>   standing_wave    F = A e sin(kx x + ky y + phase) cos(omega t)
!>   travelling_wave  F = A e sin(kx x + ky y - omega t + phase)
!>   point            F = A (r0/r)^power r_hat for r >= r_core, A (r0/r_core)^power (r/r_core) r_hat
!>                    inside (linear, finite at the centre); A > 0 a source, A < 0 a sink
!>   vortex           F = A (-dy, dx)/(r^2 + r_core^2)
!>   table            bilinear on a regular grid, linear in time between frames (first and
!>                    last frame held outside their times); file format in field_read_table
!> times a modulation m(t): none 1 | cos cos(mod_omega t + mod_phase) | ramp min(1, t/mod_time).
!> Potentials U with F = -grad U (field_potential) exist for uniform, symmetric gradients
!> (gxy = gyx), longitudinal waves (e parallel to k) and point fields; m(t) U otherwise 0
!> (field_has_potential tells which).
module fields
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_bad_input, msg_len
  use scene_input, only: int_str, printable
  use text_table, only: next_values, ints, reals
  implicit none
  private

  public :: field_t, field_add, field_potential, field_has_potential, field_read_table, &
       field_static
  public :: field_shapes, field_modulations

  integer, parameter :: fk_none = 0, fk_uniform = 1, fk_gradient = 2, fk_standing = 3, &
       fk_travelling = 4, fk_point = 5, fk_vortex = 6, fk_table = 7
  integer, parameter :: md_none = 0, md_cos = 1, md_ramp = 2
  character(len=16), parameter :: field_shapes(0:7) = [character(len=16) :: 'none', 'uniform', &
       'gradient', 'standing_wave', 'travelling_wave', 'point', 'vortex', 'table']
  character(len=16), parameter :: field_modulations(0:2) = [character(len=16) :: 'none', &
       'cos', 'ramp']

  type :: field_t
    integer :: shape = fk_none            !< index into field_shapes
    integer :: modulation = md_none       !< index into field_modulations
    real(dp) :: f0x = 0, f0y = 0          !< uniform part [m g]
    real(dp) :: gxx = 0, gxy = 0, gyx = 0, gyy = 0   !< gradient [m g/a]
    real(dp) :: x0 = 0, y0 = 0            !< reference point [a]
    real(dp) :: amplitude = 0             !< A [m g] (vortex: [m g a])
    real(dp) :: ex = 1, ey = 0            !< wave force direction as given (any length) [1]
    real(dp) :: ux = 1, uy = 0            !< (ex, ey) normalised: the direction in use [1]
    real(dp) :: kx = 0, ky = 0            !< wave vector [1/a]
    real(dp) :: omega = 0, phase = 0      !< wave angular frequency [1/T], phase [rad]
    real(dp) :: power = 2, r0 = 1, r_core = 0.5_dp   !< point/vortex: exponent [1], r0, core [a]
    real(dp) :: mod_omega = 0, mod_phase = 0, mod_time = 1   !< [1/T], [rad], [T]
    ! table
    integer :: nx = 0, ny = 0, nt = 0
    real(dp) :: gx0 = 0, gy0 = 0, gdx = 1, gdy = 1, gt0 = 0, gdt = 1   !< grid [a], frames [T]
    real(dp), allocatable :: tab(:, :, :, :)   !< (2, nx, ny, nt) force [m g]
  end type field_t

contains

  pure real(dp) function modulation(f, t) result(m)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: t
    select case (f%modulation)
    case (md_cos)
      m = cos(f%mod_omega*t + f%mod_phase)
    case (md_ramp)
      m = min(1.0_dp, t/f%mod_time)
    case default
      m = 1
    end select
  end function modulation

  !> fx, fy += F_ext(x, y, t) [m g] for every particle.
  subroutine field_add(f, t, n, x, y, fx, fy)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: t
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    real(dp), intent(inout) :: fx(n), fy(n)
    integer :: i
    real(dp) :: m, gx, gy
    if (f%shape == fk_none) return
    m = modulation(f, t)
    do i = 1, n
      call force_at(f, t, x(i), y(i), gx, gy)
      fx(i) = fx(i) + m*gx
      fy(i) = fy(i) + m*gy
    end do
  end subroutine field_add

  !> The unmodulated force at one point.
  pure subroutine force_at(f, t, x, y, gx, gy)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: t, x, y
    real(dp), intent(out) :: gx, gy
    real(dp) :: dx, dy, r, c
    dx = x - f%x0
    dy = y - f%y0
    select case (f%shape)
    case (fk_uniform)
      gx = f%f0x; gy = f%f0y
    case (fk_gradient)
      gx = f%f0x + f%gxx*dx + f%gxy*dy
      gy = f%f0y + f%gyx*dx + f%gyy*dy
    case (fk_standing)
      c = f%amplitude*sin(f%kx*x + f%ky*y + f%phase)*cos(f%omega*t)
      gx = c*f%ux; gy = c*f%uy
    case (fk_travelling)
      c = f%amplitude*sin(f%kx*x + f%ky*y - f%omega*t + f%phase)
      gx = c*f%ux; gy = c*f%uy
    case (fk_point)
      r = sqrt(dx*dx + dy*dy)
      if (r >= f%r_core) then
        c = f%amplitude*(f%r0/r)**f%power/r
      else
        c = f%amplitude*(f%r0/f%r_core)**f%power/f%r_core
      end if
      gx = c*dx; gy = c*dy
    case (fk_vortex)
      c = f%amplitude/(dx*dx + dy*dy + f%r_core**2)
      gx = -c*dy; gy = c*dx
    case (fk_table)
      call table_at(f, t, x, y, gx, gy)
    case default
      gx = 0; gy = 0
    end select
  end subroutine force_at

  !> Bilinear in space (clamped to the grid), linear in time between frames.
  pure subroutine table_at(f, t, x, y, gx, gy)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: t, x, y
    real(dp), intent(out) :: gx, gy
    real(dp) :: u, v, w, g(2)
    integer :: i, j, k
    call cell(x, f%gx0, f%gdx, f%nx, i, u)
    call cell(y, f%gy0, f%gdy, f%ny, j, v)
    call cell(t, f%gt0, f%gdt, f%nt, k, w)
    g = (1 - w)*bilinear(k) + w*bilinear(min(k + 1, f%nt))
    gx = g(1); gy = g(2)
  contains
    pure function bilinear(kk) result(b)
      integer, intent(in) :: kk
      real(dp) :: b(2)
      integer :: i1, j1
      i1 = min(i + 1, f%nx); j1 = min(j + 1, f%ny)
      b = (1 - u)*(1 - v)*f%tab(:, i, j, kk) + u*(1 - v)*f%tab(:, i1, j, kk) + &
           (1 - u)*v*f%tab(:, i, j1, kk) + u*v*f%tab(:, i1, j1, kk)
    end function bilinear
  end subroutine table_at

  !> Node index i (1-based, lower node) and fraction u in [0, 1] of coordinate s on a grid
  !> of m nodes from s0 with spacing ds; clamped at both ends.
  pure subroutine cell(s, s0, ds, m, i, u)
    real(dp), intent(in) :: s, s0, ds
    integer, intent(in) :: m
    integer, intent(out) :: i
    real(dp), intent(out) :: u
    real(dp) :: q
    if (m <= 1) then
      i = 1; u = 0
      return
    end if
    q = min(max((s - s0)/ds, 0.0_dp), real(m - 1, dp))
    i = min(int(q) + 1, m - 1)
    u = q - real(i - 1, dp)
  end subroutine cell

  !> Whether the field does not depend on time.
  pure logical function field_static(f) result(yes)
    type(field_t), intent(in) :: f
    yes = f%modulation == md_none
    select case (f%shape)
    case (fk_standing, fk_travelling)
      yes = yes .and. f%omega == 0
    case (fk_table)
      yes = yes .and. f%nt == 1
    end select
  end function field_static

  !> Whether F = -grad U holds for this field (see the module header).
  pure logical function field_has_potential(f) result(yes)
    type(field_t), intent(in) :: f
    select case (f%shape)
    case (fk_none, fk_uniform, fk_point)
      yes = .true.
    case (fk_gradient)
      yes = f%gxy == f%gyx
    case (fk_standing, fk_travelling)
      yes = abs(f%ux*f%ky - f%uy*f%kx) <= 1.0e-14_dp*sqrt(f%kx**2 + f%ky**2) .and. &
           (f%kx /= 0 .or. f%ky /= 0)
    case default
      yes = .false.
    end select
  end function field_has_potential

  !> sum_i m(t) U(x_i, t) [m g a] (0 for fields without a potential). Point field: U = 0
  !> at r = r_core.
  real(dp) function field_potential(f, t, n, x, y) result(e)
    type(field_t), intent(in) :: f
    real(dp), intent(in) :: t
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    integer :: i
    real(dp) :: dx, dy, r, kk, ek, a, ph
    e = 0
    if (.not. field_has_potential(f) .or. f%shape == fk_none) return
    do i = 1, n
      dx = x(i) - f%x0
      dy = y(i) - f%y0
      select case (f%shape)
      case (fk_uniform)
        e = e - (f%f0x*dx + f%f0y*dy)
      case (fk_gradient)
        e = e - (f%f0x*dx + f%f0y*dy + 0.5_dp*(f%gxx*dx*dx + 2*f%gxy*dx*dy + f%gyy*dy*dy))
      case (fk_standing, fk_travelling)
        kk = sqrt(f%kx**2 + f%ky**2)
        ek = (f%ux*f%kx + f%uy*f%ky)/kk
        if (f%shape == fk_standing) then
          a = f%amplitude*cos(f%omega*t)
          ph = f%kx*x(i) + f%ky*y(i) + f%phase
        else
          a = f%amplitude
          ph = f%kx*x(i) + f%ky*y(i) - f%omega*t + f%phase
        end if
        e = e + a*ek/kk*cos(ph)
      case (fk_point)
        r = sqrt(dx*dx + dy*dy)
        a = f%amplitude*(f%r0/f%r_core)**f%power
        if (r < f%r_core) then
          e = e - a*(r*r - f%r_core**2)/(2*f%r_core)
        else if (f%power == 1) then
          e = e - a*f%r_core*log(r/f%r_core)
        else
          e = e - a*f%r_core*((r/f%r_core)**(1 - f%power) - 1)/(1 - f%power)
        end if
      end select
    end do
    e = e*modulation(f, t)
  end function field_potential

  !> Read a tabulated field. Text; '#' starts a comment; blank lines are skipped; values
  !> are separated by blanks and each line holds exactly the values named:
  !>   nx ny nt                  grid nodes in x and y (>= 2 each), frames (>= 1): integers
  !>   x0 y0 dx dy               first node [a], spacings [a] (> 0)
  !>   t0 dt                     time of the first frame [T], between frames [T] (> 0)
  !>   fx fy                     nx*ny*nt lines [m g]: x fastest, then y, then the frame
  !> Exactly nx*ny*nt value lines: fewer or more are refused (never padded or cut), and so
  !> is a line with another number of values (never read in part).
  subroutine field_read_table(f, path, st)
    type(field_t), intent(inout) :: f
    character(len=*), intent(in) :: path
    type(status_t), intent(inout) :: st
    integer :: u, ios, line_no, got, need, i, j, k, stage, nv
    integer :: iv(3)
    real(dp) :: v(4)
    character(len=:), allocatable :: line
    character(len=msg_len) :: iom
    logical :: ok
    open(newunit=u, file=path, status='old', action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call fail('cannot open the field table: '//trim(iom))
      return
    end if
    stage = 0; got = 0; need = 0; line_no = 0; nv = 0
    i = 1; j = 1; k = 1
    do
      call next_values(u, line, line_no, nv, ios)
      if (ios /= 0) exit
      stage = stage + 1
      select case (stage)
      case (1)
        ok = nv == 3
        if (ok) call ints(line, iv, ok)
        if (ok) ok = all(iv >= [2, 2, 1]) .and. all(iv <= 100000)
        if (.not. ok) then
          call fail(at()//'expected "nx ny nt": 3 integers with nx, ny in [2, 100000], nt in '// &
               '[1, 100000]'//found())
          exit
        end if
        if (real(iv(1), dp)*iv(2)*iv(3) > 5.0e7_dp) then
          call fail(at()//'nx*ny*nt > 5e7 nodes')
          exit
        end if
        f%nx = iv(1); f%ny = iv(2); f%nt = iv(3)
        need = f%nx*f%ny*f%nt
        if (allocated(f%tab)) deallocate(f%tab)
        allocate(f%tab(2, f%nx, f%ny, f%nt))
      case (2)
        ok = nv == 4
        if (ok) call reals(line, v(1:4), ok)
        if (ok) ok = v(3) > 0 .and. v(4) > 0
        if (.not. ok) then
          call fail(at()//'expected "x0 y0 dx dy": 4 finite reals with dx, dy > 0 [a]'//found())
          exit
        end if
        f%gx0 = v(1); f%gy0 = v(2); f%gdx = v(3); f%gdy = v(4)
      case (3)
        ok = nv == 2
        if (ok) call reals(line, v(1:2), ok)
        if (ok) ok = v(2) > 0
        if (.not. ok) then
          call fail(at()//'expected "t0 dt": 2 finite reals with dt > 0 [T]'//found())
          exit
        end if
        f%gt0 = v(1); f%gdt = v(2)
      case default
        got = got + 1
        if (got > need) then
          call fail(at()//'more than nx*ny*nt = '//istr(need)//' value lines')
          exit
        end if
        ok = nv == 2
        if (ok) call reals(line, v(1:2), ok)
        if (ok) ok = abs(v(1)) < 1.0e30_dp .and. abs(v(2)) < 1.0e30_dp
        if (.not. ok) then
          call fail(at()//'expected two finite reals "fx fy" [m g] (|f| < 1e30)'//found())
          exit
        end if
        f%tab(:, i, j, k) = v(1:2)
        i = i + 1
        if (i > f%nx) then
          i = 1; j = j + 1
        end if
        if (j > f%ny) then
          j = 1; k = k + 1
        end if
      end select
    end do
    close(u)
    if (st%code /= 0) return
    if (stage < 3) then
      call fail('incomplete header: "nx ny nt", "x0 y0 dx dy", "t0 dt" expected')
    else if (got < need) then
      call fail('only '//istr(got)//' value lines, nx*ny*nt = '//istr(need)//' needed')
    end if
  contains
    subroutine fail(msg)
      character(len=*), intent(in) :: msg
      call set_error(st, exit_bad_input, '&field file = '''//trim(path)//''': '//msg)
    end subroutine fail
    function at() result(s)
      character(len=:), allocatable :: s
      s = 'line '//istr(line_no)//': '
    end function at
    !> ", found N values: 'the line'" (messages; the line cut at 60 characters).
    function found() result(s)
      character(len=:), allocatable :: s
      character(len=:), allocatable :: shown
      shown = trim(adjustl(line))
      if (len(shown) > 60) shown = shown(:57)//'...'
      s = ', found '//istr(nv)//' value'//trim(merge('s', ' ', nv /= 1))//': '''// &
           printable(shown)//''''
    end function found
    function istr(q) result(s)
      integer, intent(in) :: q
      character(len=:), allocatable :: s
      s = int_str(int(q, i8))
    end function istr
  end subroutine field_read_table

end module fields
