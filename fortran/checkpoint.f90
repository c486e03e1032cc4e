!> Checkpoints: the complete dynamic state (particles, integrator history,
!> frozen far field, neighbour list with its reference positions, step,
!> RNG state, output file sizes, wall time), written to a temporary file and
!> renamed into place, so a checkpoint on disk is always whole.
module checkpoint
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_long
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io
  use state, only: state_t
  use neighbours, only: nlist_t
  use output, only: rename_into_place
  implicit none
  private

  public :: checkpoint_write, checkpoint_read, truncate_file

  integer, parameter :: magic = 20261122   !< format tag
  integer, parameter :: version = 4

  interface
    integer(c_int) function c_truncate(path, length) bind(C, name='truncate')
      import :: c_int, c_char, c_long
      character(kind=c_char), intent(in) :: path(*)
      integer(c_long), value :: length
    end function c_truncate
  end interface

contains

  subroutine checkpoint_write(path, s, nl, sizes, wall, pst, st)
    character(len=*), intent(in) :: path
    type(state_t), intent(in) :: s
    type(state_t), intent(in) :: pst      !< free piston (unallocated otherwise)
    type(nlist_t), intent(in) :: nl
    integer(i8), intent(in) :: sizes(4)   !< bytes of piston, particles, distance, energy files
    real(dp), intent(in) :: wall          !< wall time so far [s]
    type(status_t), intent(inout) :: st
    integer :: u, ios, k
    integer, allocatable :: rng(:)
    character(len=:), allocatable :: tmp
    tmp = trim(path)//'.tmp'
    call random_seed(size=k)
    allocate(rng(k))
    call random_seed(get=rng)
    open(newunit=u, file=tmp, access='stream', form='unformatted', status='replace', &
         action='write', iostat=ios)
    if (ios /= 0) then
      call set_error(st, exit_io, tmp//': cannot write checkpoint')
      return
    end if
    write(u) magic, version, s%n, s%step, s%t, s%piston_h, s%piston_force, s%phase, &
         s%has_previous, s%tail_ready, sizes, wall, k
    write(u) rng
    write(u) s%x, s%y, s%vx, s%vy, s%xp, s%yp, s%fx, s%fy, s%fmag, s%s3, &
         s%fx_far, s%fy_far, s%s3_far, s%id, s%species, s%mass, s%mu, s%wsin, s%nfac
    write(u) nl%valid, nl%builds, nl%pairs, nl%evaluated, allocated(nl%start)
    if (allocated(nl%start)) then
      write(u) size(nl%cell_start), size(nl%nbr)
      write(u) nl%cell_start, nl%cell_part, nl%start, nl%nbr, nl%xref, nl%yref
    end if
    write(u) allocated(pst%y)
    if (allocated(pst%y)) write(u) pst%y, pst%yp, pst%vy, pst%fy, pst%has_previous, &
         pst%nudge_step, pst%calm_since
    close(u)
    call rename_into_place(tmp, trim(path), st)
  end subroutine checkpoint_write

  subroutine checkpoint_read(path, s, nl, sizes, wall, pst, st)
    character(len=*), intent(in) :: path
    type(state_t), intent(inout) :: s      !< allocated for the scene's n
    type(state_t), intent(inout) :: pst    !< free piston, allocated when the scene has one
    type(nlist_t), intent(inout) :: nl     !< set up for the scene's strategy
    integer(i8), intent(out) :: sizes(4)
    real(dp), intent(out) :: wall
    type(status_t), intent(inout) :: st
    integer :: u, ios, mg, ver, n, k, ncs, nnb
    integer, allocatable :: rng(:)
    logical :: has_list, has_piston
    open(newunit=u, file=path, access='stream', form='unformatted', status='old', &
         action='read', iostat=ios)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot open checkpoint')
      return
    end if
    read(u, iostat=ios) mg, ver, n
    if (ios /= 0 .or. mg /= magic .or. ver /= version) then
      call set_error(st, exit_io, trim(path)//': not a magbed checkpoint of this version')
      close(u); return
    end if
    if (n /= s%n) then
      call set_error(st, exit_io, trim(path)//': checkpoint particle count differs from the scene')
      close(u); return
    end if
    read(u, iostat=ios) s%step, s%t, s%piston_h, s%piston_force, s%phase, s%has_previous, &
         s%tail_ready, sizes, wall, k
    if (ios == 0) then
      allocate(rng(k))
      read(u, iostat=ios) rng
      if (ios == 0) call random_seed(put=rng)
    end if
    if (ios == 0) read(u, iostat=ios) s%x, s%y, s%vx, s%vy, s%xp, s%yp, s%fx, s%fy, s%fmag, &
         s%s3, s%fx_far, s%fy_far, s%s3_far, s%id, s%species, s%mass, s%mu, s%wsin, s%nfac
    if (ios == 0) read(u, iostat=ios) nl%valid, nl%builds, nl%pairs, nl%evaluated, has_list
    if (ios == 0 .and. has_list) then
      read(u, iostat=ios) ncs, nnb
      if (ios == 0 .and. allocated(nl%cell_start)) then
        if (size(nl%cell_start) /= ncs) ios = 1
      end if
      if (ios == 0) then
        if (allocated(nl%nbr)) deallocate(nl%nbr)
        allocate(nl%nbr(nnb))
        read(u, iostat=ios) nl%cell_start, nl%cell_part, nl%start, nl%nbr, nl%xref, nl%yref
      end if
    end if
    if (ios == 0) read(u, iostat=ios) has_piston
    if (ios == 0 .and. has_piston .neqv. allocated(pst%y)) ios = 1
    if (ios == 0 .and. has_piston) read(u, iostat=ios) pst%y, pst%yp, pst%vy, pst%fy, &
         pst%has_previous, pst%nudge_step, pst%calm_since
    close(u)
    if (ios /= 0) call set_error(st, exit_io, trim(path)//': checkpoint is truncated or '// &
         'does not match the scene')
  end subroutine checkpoint_read

  !> Cut a file back to `length` bytes (drops rows written after a checkpoint).
  subroutine truncate_file(path, length, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: length
    type(status_t), intent(inout) :: st
    logical :: there
    inquire(file=path, exist=there)
    if (.not. there) then
      if (length > 0) call set_error(st, exit_io, trim(path)//': missing output file to resume')
      return
    end if
    if (c_truncate(trim(path)//c_null_char, int(length, c_long)) /= 0) &
         call set_error(st, exit_io, trim(path)//': cannot truncate to the checkpoint')
  end subroutine truncate_file

end module checkpoint
