!> Output files of a bed run: thesis-style text with a header naming every
!> column and its unit, written only at their cadence through the checked
!> files of core/files.f90 (run.json, checkpoints and the run directory are
!> the runner's, in fortran/core). The particle frames can also (or instead)
!> go to particles.bin, the binary frames of module frames (same columns,
!> float64 values as computed).
module output
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io, exit_ok
  use model, only: model_t
  use state, only: state_t
  use files, only: cfile_t, cf_open, cf_is_open, cf_line, cf_sync, cf_close
  use tables, only: row_guard
  use frames, only: frames_t, frames_open, frames_begin, frames_put, frames_end, frames_flush, &
       frames_close, json_real
  implicit none
  private

  public :: output_t, output_open, output_close, write_piston, write_frame, &
       write_distance, write_energy, output_flush, output_sizes, output_names, frames_name

  type :: output_t
    character(len=:), allocatable :: dir
    type(cfile_t) :: f(4)   !< piston, particles, mean_distance, energy (fp null: off)
    type(frames_t) :: fb    !< particles.bin (not open: off)
    type(status_t) :: st    !< first failed write (code exit_io), kept until the runner reads it
  end type output_t

  character(len=*), parameter :: rfmt = 'es24.16e3'
  character(len=*), parameter :: output_names(4) = [character(len=17) :: 'piston.dat', &
       'particles.dat', 'mean_distance.dat', 'energy.dat']
  character(len=*), parameter :: frames_name = 'particles.bin'
  !> columns of particles.dat and particles.bin (after step and t)
  character(len=*), parameter :: frame_cols(11) = [character(len=7) :: 'id', 'species', 'x', &
       'y', 'vx', 'vy', 'fx', 'fy', 'fmag', 'fmx', 'fmy']
  character(len=*), parameter :: frame_units(11) = [character(len=5) :: '', '', 'D1', 'D1', &
       'D1/T', 'D1/T', 'm1*g', 'm1*g', 'm1*g', 'm1*g', 'm1*g']

contains

  ! ---- the bed's files ------------------------------------------------------------

  !> Open the output files: fresh with headers, or (append) continued after a
  !> resume, the files having been cut back to the checkpoint's sizes.
  !> frames_on: particles.dat; binary_on: particles.bin (n particles).
  subroutine output_open(o, dir, m, piston_on, frames_on, dist_on, energy_on, append, st, &
       binary_on, n)
    type(output_t), intent(inout) :: o
    character(len=*), intent(in) :: dir
    type(model_t), intent(in) :: m
    logical, intent(in) :: piston_on, frames_on, dist_on, energy_on, append
    type(status_t), intent(inout) :: st
    logical, intent(in), optional :: binary_on
    integer, intent(in), optional :: n
    character(len=200) :: units
    integer :: k
    o%dir = trim(dir)
    o%st = status_t()
    write(units, '(a,es10.4,a,es10.4,a,es10.4,a)') 'Units: D1 = ', m%length_unit, ' m, T = ', &
         m%time_unit, ' s, m1*g = ', m%force_unit, ' N'
    if (piston_on) call open1(1, &
         '# piston.dat: piston history (force = push of all particles on the piston). '// &
         trim(units), '# step t[T] H[D1] F_piston[m1*g] phi[1] phase')
    if (frames_on) call open1(2, &
         '# particles.dat: particle frames (f = total force; fm = magnetic force of pairs + walls). '// &
         trim(units), '# step t[T]'//frame_header())
    if (dist_on) call open1(3, &
         '# mean_distance.dat: D_hat = sum_{i<j} |r_i - r_j|/(N(N-1)), the convention of '// &
         'thesis Table 3.1 (half the mean pair distance; eq. 2.1 as typeset is twice this). '// &
         trim(units), &
         '# step t[T] D_hat[D1]')
    if (energy_on) call open1(4, &
         '# energy.dat: mechanical energy (gravity potential from y = 0). '//trim(units), &
         '# step t[T] E_kin[m1*g*D1] E_pair[m1*g*D1] E_wall[m1*g*D1] E_grav[m1*g*D1] '// &
         'E_piston[m1*g*D1] E_total[m1*g*D1]')
    if (.not. present(binary_on) .or. st%code /= exit_ok) return
    if (.not. binary_on) return
    call frames_open(o%fb, o%dir//'/'//frames_name, n, frame_cols, frame_units, &
         [('i4', k = 1, 2), ('f8', k = 3, 11)], 'step', 'T', '"kind": "magnet_bed", '// &
         '"box": ['//json_real(m%width)//', '//json_real(m%height)//'], "units": '// &
         '{"length_m": '//json_real(m%length_unit)//', "time_s": '//json_real(m%time_unit)// &
         ', "mass_kg": '//json_real(m%mass_unit)//', "force_N": '//json_real(m%force_unit)// &
         '}', append, st)
  contains
    subroutine open1(k, head1, head2)
      integer, intent(in) :: k
      character(len=*), intent(in) :: head1, head2
      if (st%code /= exit_ok) return
      if (append) then
        call cf_open(o%f(k), o%dir//'/'//trim(output_names(k)), 'a', st)
        return
      end if
      call cf_open(o%f(k), o%dir//'/'//trim(output_names(k)), 'w', st)
      call cf_line(o%f(k), head1, st)
      call cf_line(o%f(k), head2, st)
    end subroutine open1
  end subroutine output_open

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

  !> Hand every open file's buffer to the OS; a failure is recorded in o%st.
  subroutine output_flush(o)
    type(output_t), intent(inout) :: o
    integer :: k
    do k = 1, 4
      call cf_sync(o%f(k), o%st, disk=.false.)
    end do
    call frames_flush(o%fb, o%st)
  end subroutine output_flush

  !> Sizes [bytes] of the four files (0 when off), for checkpoints. The
  !> files are flushed to the OS first (a killed process loses nothing
  !> before the checkpoint); they are not fsynced: after a power loss a file
  !> may be shorter than its checkpoint says, and the resume then refuses it
  !> (it never pads). Check o%st before trusting the sizes.
  subroutine output_sizes(o, sizes)
    type(output_t), intent(inout) :: o
    integer(i8), intent(out) :: sizes(4)
    integer :: k
    sizes = 0
    do k = 1, 4
      if (.not. cf_is_open(o%f(k))) cycle
      call cf_sync(o%f(k), o%st, disk=.false.)
      sizes(k) = o%f(k)%bytes
    end do
  end subroutine output_sizes

  !> Close every file (the last buffered data is checked into o%st).
  subroutine output_close(o)
    type(output_t), intent(inout) :: o
    integer :: k
    do k = 1, 4
      call cf_close(o%f(k), o%st, sync=.true.)
    end do
    call frames_close(o%fb, o%st)
  end subroutine output_close

  subroutine put(o, k, line)
    type(output_t), intent(inout) :: o
    integer, intent(in) :: k
    character(len=*), intent(in) :: line
    if (o%st%code /= exit_ok .or. .not. cf_is_open(o%f(k))) return
    call row_guard(o%f(k)%path, line, o%st)   ! a non-finite number: refused, not written
    if (o%st%code == exit_ok) call cf_line(o%f(k), line, o%st)
  end subroutine put

  subroutine write_piston(o, s, phi)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: phi
    character(len=160) :: line
    write(line, '(i0,4(1x,'//rfmt//'),1x,i0)') s%step, s%t, s%piston_h, s%piston_force, phi, &
         s%phase
    call put(o, 1, trim(line))
  end subroutine write_piston

  subroutine write_frame(o, s)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    integer :: i, k
    integer :: at(s%n)
    character(len=400) :: line
    at(s%id) = [(k, k = 1, s%n)]     ! rows in particle-id order
    call frames_begin(o%fb, s%step, s%t, o%st)
    call frames_put(o%fb, s%id(at), o%st)
    call frames_put(o%fb, s%species(at), o%st)
    call frames_put(o%fb, s%x(at), o%st)
    call frames_put(o%fb, s%y(at), o%st)
    call frames_put(o%fb, s%vx(at), o%st)
    call frames_put(o%fb, s%vy(at), o%st)
    call frames_put(o%fb, s%fx(at), o%st)
    call frames_put(o%fb, s%fy(at), o%st)
    call frames_put(o%fb, s%fmag(at), o%st)
    call frames_put(o%fb, s%fmx(at), o%st)
    call frames_put(o%fb, s%fmy(at), o%st)
    call frames_end(o%fb, o%st)
    if (.not. cf_is_open(o%f(2))) return
    do k = 1, s%n
      i = at(k)
      write(line, '(i0,1x,'//rfmt//',1x,i0,1x,i0,9(1x,'//rfmt//'))') s%step, s%t, s%id(i), &
           s%species(i), s%x(i), s%y(i), s%vx(i), s%vy(i), s%fx(i), s%fy(i), s%fmag(i), &
           s%fmx(i), s%fmy(i)
      call put(o, 2, trim(line))
    end do
  end subroutine write_frame

  subroutine write_distance(o, s, d)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: d
    character(len=100) :: line
    write(line, '(i0,2(1x,'//rfmt//'))') s%step, s%t, d
    call put(o, 3, trim(line))
  end subroutine write_distance

  subroutine write_energy(o, s, ek, ep, ew, eg, epis)
    type(output_t), intent(inout) :: o
    type(state_t), intent(in) :: s
    real(dp), intent(in) :: ek, ep, ew, eg, epis   !< epis: free piston kinetic + gravity
    character(len=260) :: line
    write(line, '(i0,7(1x,'//rfmt//'))') s%step, s%t, ek, ep, ew, eg, epis, &
         ek + ep + ew + eg + epis
    call put(o, 4, trim(line))
  end subroutine write_energy

end module output
