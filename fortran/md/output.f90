!> Output files of a bed run: thesis-style text with a header naming every
!> column and its unit, written only at their cadence (run.json, checkpoints
!> and the run directory are the runner's, in fortran/core).
module output
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io
  use model, only: model_t
  use state, only: state_t
  implicit none
  private

  public :: output_t, output_open, output_close, write_piston, write_frame, &
       write_distance, write_energy, output_flush, output_sizes, output_names

  type :: output_t
    character(len=:), allocatable :: dir
    integer :: u_piston = -1, u_frame = -1, u_dist = -1, u_energy = -1  !< -1: not open (newunit never returns -1)
  end type output_t


  character(len=*), parameter :: rfmt = 'es24.16e3'
  character(len=*), parameter :: output_names(4) = [character(len=17) :: 'piston.dat', &
       'particles.dat', 'mean_distance.dat', 'energy.dat']

contains

  !> Open the output files: fresh with headers, or (append) continued after a
  !> resume, the files having been cut back to the checkpoint's sizes.
  subroutine output_open(o, dir, m, piston_on, frames_on, dist_on, energy_on, append, st)
    type(output_t), intent(inout) :: o
    character(len=*), intent(in) :: dir
    type(model_t), intent(in) :: m
    logical, intent(in) :: piston_on, frames_on, dist_on, energy_on, append
    type(status_t), intent(inout) :: st
    character(len=200) :: units
    o%dir = trim(dir)
    write(units, '(a,es10.4,a,es10.4,a,es10.4,a)') 'Units: D1 = ', m%length_unit, ' m, T = ', &
         m%time_unit, ' s, m1*g = ', m%force_unit, ' N'
    if (piston_on) call open1(o%u_piston, 'piston.dat', &
         '# piston.dat: piston history (force = push of all particles on the piston). '// &
         trim(units), '# step t[T] H[D1] F_piston[m1*g] phi[1] phase')
    if (frames_on) call open1(o%u_frame, 'particles.dat', &
         '# particles.dat: particle frames (f = total force; fm = magnetic force of pairs + walls). '// &
         trim(units), '# step t[T] id species x[D1] y[D1] vx[D1/T] vy[D1/T] fx[m1*g] fy[m1*g] '// &
         'fmag[m1*g] fmx[m1*g] fmy[m1*g]')
    if (dist_on) call open1(o%u_dist, 'mean_distance.dat', &
         '# mean_distance.dat: D_hat = sum_{i<j} |r_i - r_j|/(N(N-1)), the convention of '// &
         'thesis Table 3.1 (half the mean pair distance; eq. 2.1 as typeset is twice this). '// &
         trim(units), &
         '# step t[T] D_hat[D1]')
    if (energy_on) call open1(o%u_energy, 'energy.dat', &
         '# energy.dat: mechanical energy (gravity potential from y = 0). '//trim(units), &
         '# step t[T] E_kin[m1*g*D1] E_pair[m1*g*D1] E_wall[m1*g*D1] E_grav[m1*g*D1] '// &
         'E_piston[m1*g*D1] E_total[m1*g*D1]')
  contains
    subroutine open1(u, name, head1, head2)
      integer, intent(out) :: u
      character(len=*), intent(in) :: name, head1, head2
      integer :: ios
      if (append) then
        open(newunit=u, file=o%dir//'/'//name, status='old', position='append', &
             action='write', iostat=ios)
      else
        open(newunit=u, file=o%dir//'/'//name, status='replace', action='write', iostat=ios)
      end if
      if (ios /= 0) then
        call set_error(st, exit_io, o%dir//'/'//name//': cannot open for writing')
        u = -1
        return
      end if
      if (append) return
      write(u, '(a)') head1
      write(u, '(a)') head2
    end subroutine open1
  end subroutine output_open

  subroutine output_flush(o)
    type(output_t), intent(in) :: o
    if (o%u_piston /= -1) flush(o%u_piston)
    if (o%u_frame /= -1) flush(o%u_frame)
    if (o%u_dist /= -1) flush(o%u_dist)
    if (o%u_energy /= -1) flush(o%u_energy)
  end subroutine output_flush

  !> Flushed sizes [bytes] of the four files (0 when off), for checkpoints.
  subroutine output_sizes(o, sizes)
    type(output_t), intent(in) :: o
    integer(i8), intent(out) :: sizes(4)
    call output_flush(o)
    sizes = 0
    if (o%u_piston /= -1) inquire(unit=o%u_piston, size=sizes(1))
    if (o%u_frame /= -1) inquire(unit=o%u_frame, size=sizes(2))
    if (o%u_dist /= -1) inquire(unit=o%u_dist, size=sizes(3))
    if (o%u_energy /= -1) inquire(unit=o%u_energy, size=sizes(4))
  end subroutine output_sizes

  subroutine output_close(o)
    type(output_t), intent(inout) :: o
    if (o%u_piston /= -1) close(o%u_piston)
    if (o%u_frame /= -1) close(o%u_frame)
    if (o%u_dist /= -1) close(o%u_dist)
    if (o%u_energy /= -1) close(o%u_energy)
    o%u_piston = -1; o%u_frame = -1; o%u_dist = -1; o%u_energy = -1
  end subroutine output_close

  subroutine write_piston(o, s, phi)
    type(output_t), intent(in) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: phi
    write(o%u_piston, '(i0,4(1x,'//rfmt//'),1x,i0)') s%step, s%t, s%piston_h, &
         s%piston_force, phi, s%phase
  end subroutine write_piston

  subroutine write_frame(o, s)
    type(output_t), intent(in) :: o
    type(state_t), intent(in) :: s
    integer :: i, k
    integer :: at(s%n)
    at(s%id) = [(k, k = 1, s%n)]     ! rows in particle-id order
    do k = 1, s%n
      i = at(k)
      write(o%u_frame, '(i0,1x,'//rfmt//',1x,i0,1x,i0,9(1x,'//rfmt//'))') s%step, s%t, s%id(i), &
           s%species(i), s%x(i), s%y(i), s%vx(i), s%vy(i), s%fx(i), s%fy(i), s%fmag(i), &
           s%fmx(i), s%fmy(i)
    end do
  end subroutine write_frame

  subroutine write_distance(o, s, d)
    type(output_t), intent(in) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: d
    write(o%u_dist, '(i0,2(1x,'//rfmt//'))') s%step, s%t, d
  end subroutine write_distance

  subroutine write_energy(o, s, ek, ep, ew, eg, epis)
    type(output_t), intent(in) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: ek, ep, ew, eg, epis   !< epis: free piston kinetic + gravity
    write(o%u_energy, '(i0,7(1x,'//rfmt//'))') s%step, s%t, ek, ep, ew, eg, epis, &
         ek + ep + ew + eg + epis
  end subroutine write_energy

end module output
