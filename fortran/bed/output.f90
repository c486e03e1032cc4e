!> Output files of a bed run: thesis-style text with a header naming every
!> column and its unit, written only at their cadence through the checked
!> files of core/files.f90 (run.json, checkpoints and the run directory are
!> the runner's, in fortran/core). The particle frames can also (or instead)
!> go to particles.bin, the binary frames of module frames (same columns,
!> float64 values as computed). The files are a set of module output_set: the
!> method opens, flushes, closes and lists them through o%set.
module output
  use kinds, only: dp
  use errors, only: status_t
  use model, only: model_t
  use state, only: state_t
  use scene_input, only: json_real
  use output_set, only: output_set_t
  implicit none
  private

  public :: output_t, output_declare, write_piston, write_frame, write_distance, write_energy

  !> The bed's outputs (module output_set) and the first failed write of a step.
  type :: output_t
    type(output_set_t) :: set
    integer :: piston = 0, frames = 0, distance = 0, energy = 0, bin = 0   !< ids (0: off)
    type(status_t) :: st    !< first failed write (code exit_io), kept until the runner reads it
  end type output_t

  character(len=*), parameter :: rfmt = 'es24.16e3'
  !> columns of particles.dat and particles.bin (after step and t)
  character(len=*), parameter :: frame_cols(11) = [character(len=7) :: 'id', 'species', 'x', &
       'y', 'vx', 'vy', 'fx', 'fy', 'fmag', 'fmx', 'fmy']
  character(len=*), parameter :: frame_units(11) = [character(len=5) :: '', '', 'D1', 'D1', &
       'D1/T', 'D1/T', 'm1*g', 'm1*g', 'm1*g', 'm1*g', 'm1*g']

contains

  ! ---- the bed's files ------------------------------------------------------------

  !> Register the bed's outputs (opened, flushed, closed and listed by the set):
  !> piston.dat, particles.dat (frames_on), mean_distance.dat, energy.dat and
  !> particles.bin (binary_on: n particles), each when on.
  subroutine output_declare(o, m, piston_on, frames_on, dist_on, energy_on, binary_on, n)
    type(output_t), intent(inout) :: o
    type(model_t), intent(in) :: m
    logical, intent(in) :: piston_on, frames_on, dist_on, energy_on, binary_on
    integer, intent(in) :: n
    character(len=200) :: units
    integer :: k
    o%set = output_set_t()     ! a load again registers the outputs afresh
    write(units, '(a,es10.4,a,es10.4,a,es10.4,a)') 'Units: D1 = ', m%length_unit, ' m, T = ', &
         m%time_unit, ' s, m1*g = ', m%force_unit, ' N'
    call o%set%table(o%piston, 'piston.dat', &
         '# piston.dat: piston history (force = push of all particles on the piston). '// &
         trim(units), '# step t[T] H[D1] F_piston[m1*g] phi[1] phase', on=piston_on)
    call o%set%table(o%frames, 'particles.dat', &
         '# particles.dat: particle frames (f = total force; fm = magnetic force of pairs + walls). '// &
         trim(units), '# step t[T]'//frame_header(), on=frames_on)
    call o%set%table(o%distance, 'mean_distance.dat', &
         '# mean_distance.dat: D_hat = sum_{i<j} |r_i - r_j|/(N(N-1)), the convention of '// &
         'thesis Table 3.1 (half the mean pair distance; eq. 2.1 as typeset is twice this). '// &
         trim(units), &
         '# step t[T] D_hat[D1]', on=dist_on)
    call o%set%table(o%energy, 'energy.dat', &
         '# energy.dat: mechanical energy (gravity potential from y = 0). '//trim(units), &
         '# step t[T] E_kin[m1*g*D1] E_pair[m1*g*D1] E_wall[m1*g*D1] E_grav[m1*g*D1] '// &
         'E_piston[m1*g*D1] E_total[m1*g*D1]', on=energy_on)
    call o%set%frames(o%bin, 'particles.bin', n, frame_cols, frame_units, &
         [('i4', k = 1, 2), ('f8', k = 3, 11)], 'step', 'T', '"kind": "magnet_bed", '// &
         '"box": ['//json_real(m%width)//', '//json_real(m%height)//'], "units": '// &
         '{"length_m": '//json_real(m%length_unit)//', "time_s": '//json_real(m%time_unit)// &
         ', "mass_kg": '//json_real(m%mass_unit)//', "force_N": '//json_real(m%force_unit)// &
         '}', on=binary_on)
  end subroutine output_declare

  !> The column names of particles.dat after step and t: ' name[unit]' ...
  function frame_header() result(h)
    character(len=:), allocatable :: h
    integer :: k
    h = ''
    do k = 1, size(frame_cols)
      h = h//' '//trim(frame_cols(k))
      if (len_trim(frame_units(k)) > 0) h = h//'['//trim(frame_units(k))//']'
    end do
  end function frame_header

  subroutine write_piston(o, s, phi)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: phi
    character(len=160) :: line
    write(line, '(i0,4(1x,'//rfmt//'),1x,i0)') s%step, s%t, s%piston_h, s%piston_force, phi, &
         s%phase
    call o%set%line(o%piston, trim(line), o%st)
  end subroutine write_piston

  subroutine write_frame(o, s)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    integer :: i, k
    integer :: at(s%n)
    character(len=400) :: line
    at(s%id) = [(k, k = 1, s%n)]     ! rows in particle-id order
    call o%set%frame_begin(o%bin, s%step, s%t, o%st)
    call o%set%frame_put(o%bin, s%id(at), o%st)
    call o%set%frame_put(o%bin, s%species(at), o%st)
    call o%set%frame_put(o%bin, s%x(at), o%st)
    call o%set%frame_put(o%bin, s%y(at), o%st)
    call o%set%frame_put(o%bin, s%vx(at), o%st)
    call o%set%frame_put(o%bin, s%vy(at), o%st)
    call o%set%frame_put(o%bin, s%fx(at), o%st)
    call o%set%frame_put(o%bin, s%fy(at), o%st)
    call o%set%frame_put(o%bin, s%fmag(at), o%st)
    call o%set%frame_put(o%bin, s%fmx(at), o%st)
    call o%set%frame_put(o%bin, s%fmy(at), o%st)
    call o%set%frame_end(o%bin, o%st)
    if (o%frames == 0) return
    do k = 1, s%n
      i = at(k)
      write(line, '(i0,1x,'//rfmt//',1x,i0,1x,i0,9(1x,'//rfmt//'))') s%step, s%t, s%id(i), &
           s%species(i), s%x(i), s%y(i), s%vx(i), s%vy(i), s%fx(i), s%fy(i), s%fmag(i), &
           s%fmx(i), s%fmy(i)
      call o%set%line(o%frames, trim(line), o%st)
    end do
  end subroutine write_frame

  subroutine write_distance(o, s, d)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: d
    character(len=100) :: line
    write(line, '(i0,2(1x,'//rfmt//'))') s%step, s%t, d
    call o%set%line(o%distance, trim(line), o%st)
  end subroutine write_distance

  subroutine write_energy(o, s, ek, ep, ew, eg, epis)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: ek, ep, ew, eg, epis   !< epis: free piston kinetic + gravity
    character(len=260) :: line
    write(line, '(i0,7(1x,'//rfmt//'))') s%step, s%t, ek, ep, ew, eg, epis, &
         ek + ep + ew + eg + epis
    call o%set%line(o%energy, trim(line), o%st)
  end subroutine write_energy

end module output
