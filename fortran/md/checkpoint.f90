!> The bed's checkpoint payload: the complete dynamic state (particles,
!> integrator history, frozen far field, neighbour list with its reference
!> positions, step, RNG state, free piston). The container around it (header,
!> scene binding, checksum, atomic rename) is core/ckpt.f90's; the output
!> sizes and wall time are the runner's record.
module checkpoint
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io, msg_len
  use state, only: state_t
  use neighbours, only: nlist_t, nlist_owners
  use ckpt, only: ckpt_writer_t, ckpt_put
  use, intrinsic :: iso_fortran_env, only: int8
  implicit none
  private

  public :: checkpoint_save, checkpoint_restore

contains

  subroutine checkpoint_save(w, s, nl, pst)
    type(ckpt_writer_t), intent(inout) :: w
    type(state_t), intent(in) :: s
    type(state_t), intent(in) :: pst      !< free piston (unallocated otherwise)
    type(nlist_t), intent(in) :: nl
    integer :: k
    integer, allocatable :: rng(:)
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    call random_seed(size=k)
    allocate(rng(k))
    call random_seed(get=rng)
    call ckpt_put(w, [transfer(s%n, b), transfer(s%step, b), transfer(s%t, b), &
         transfer(s%piston_h, b), transfer(s%piston_force, b), transfer(s%phase, b), &
         transfer(s%has_previous, b), transfer(s%tail_ready, b), transfer(s%tail_step, b), &
         transfer(k, b)])
    call ckpt_put(w, transfer(rng, b))
    call ckpt_put(w, transfer(s%x, b)); call ckpt_put(w, transfer(s%y, b))
    call ckpt_put(w, transfer(s%vx, b)); call ckpt_put(w, transfer(s%vy, b))
    call ckpt_put(w, transfer(s%xp, b)); call ckpt_put(w, transfer(s%yp, b))
    call ckpt_put(w, transfer(s%fx, b)); call ckpt_put(w, transfer(s%fy, b))
    call ckpt_put(w, transfer(s%fmag, b)); call ckpt_put(w, transfer(s%s3, b))
    call ckpt_put(w, transfer(s%fx_far, b)); call ckpt_put(w, transfer(s%fy_far, b))
    call ckpt_put(w, transfer(s%s3_far, b))
    call ckpt_put(w, transfer(s%dfx_far, b)); call ckpt_put(w, transfer(s%dfy_far, b))
    call ckpt_put(w, transfer(s%ds3_far, b)); call ckpt_put(w, transfer(s%id, b))
    call ckpt_put(w, transfer(s%species, b)); call ckpt_put(w, transfer(s%mass, b))
    call ckpt_put(w, transfer(s%mu, b)); call ckpt_put(w, transfer(s%wsin, b))
    call ckpt_put(w, transfer(s%nfac, b))
    call ckpt_put(w, [transfer(nl%valid, b), transfer(nl%builds, b), transfer(nl%pairs, b), &
         transfer(nl%evaluated, b), transfer(allocated(nl%start), b)])
    if (allocated(nl%start)) then
      call ckpt_put(w, [transfer(size(nl%cell_start), b), transfer(size(nl%nbr), b)])
      call ckpt_put(w, transfer(nl%cell_start, b)); call ckpt_put(w, transfer(nl%cell_part, b))
      call ckpt_put(w, transfer(nl%start, b)); call ckpt_put(w, transfer(nl%nbr, b))
      call ckpt_put(w, transfer(nl%xref, b)); call ckpt_put(w, transfer(nl%yref, b))
    end if
    call ckpt_put(w, transfer(allocated(pst%y), b))
    if (allocated(pst%y)) then
      call ckpt_put(w, transfer(pst%y, b)); call ckpt_put(w, transfer(pst%yp, b))
      call ckpt_put(w, transfer(pst%vy, b)); call ckpt_put(w, transfer(pst%fy, b))
      call ckpt_put(w, transfer(pst%has_previous, b)); call ckpt_put(w, transfer(pst%nudge_step, b))
      call ckpt_put(w, transfer(pst%calm_since, b))
    end if
  end subroutine checkpoint_save

  subroutine checkpoint_restore(u, s, nl, pst, st)
    integer, intent(in) :: u
    type(state_t), intent(inout) :: s      !< allocated for the scene's n
    type(state_t), intent(inout) :: pst    !< free piston, allocated when the scene has one
    type(nlist_t), intent(inout) :: nl     !< set up for the scene's strategy
    type(status_t), intent(inout) :: st
    integer :: ios, n, k, ncs, nnb
    integer, allocatable :: rng(:)
    logical :: has_list, has_piston
    read(u, iostat=ios) n
    if (ios == 0 .and. n /= s%n) then
      call set_error(st, exit_io, 'checkpoint: particle count differs from the scene')
      return
    end if
    if (ios == 0) read(u, iostat=ios) s%step, s%t, s%piston_h, s%piston_force, s%phase, &
         s%has_previous, s%tail_ready, s%tail_step, k
    if (ios == 0 .and. (k < 1 .or. k > 1000)) ios = 1
    if (ios == 0) then
      allocate(rng(k))
      read(u, iostat=ios) rng
      if (ios == 0) call random_seed(put=rng)
    end if
    if (ios == 0) read(u, iostat=ios) s%x, s%y, s%vx, s%vy, s%xp, s%yp, s%fx, s%fy, s%fmag, &
         s%s3, s%fx_far, s%fy_far, s%s3_far, s%dfx_far, s%dfy_far, s%ds3_far, s%id, s%species, s%mass, s%mu, s%wsin, s%nfac
    if (ios == 0) read(u, iostat=ios) nl%valid, nl%builds, nl%pairs, nl%evaluated, has_list
    if (ios == 0 .and. has_list) then
      read(u, iostat=ios) ncs, nnb
      if (ios == 0 .and. allocated(nl%cell_start)) then
        if (size(nl%cell_start) /= ncs) ios = 1
      end if
      if (ios == 0 .and. (nnb < 0 .or. .not. allocated(nl%cell_start))) ios = 1
      if (ios == 0) then
        if (allocated(nl%nbr)) deallocate(nl%nbr)
        allocate(nl%nbr(nnb))
        read(u, iostat=ios) nl%cell_start, nl%cell_part, nl%start, nl%nbr, nl%xref, nl%yref
        if (ios == 0 .and. nl%valid) call nlist_owners(nl, s%n)   ! own follows from start
      end if
    end if
    if (ios == 0) read(u, iostat=ios) has_piston
    if (ios == 0 .and. has_piston .neqv. allocated(pst%y)) ios = 1
    if (ios == 0 .and. has_piston) read(u, iostat=ios) pst%y, pst%yp, pst%vy, pst%fy, &
         pst%has_previous, pst%nudge_step, pst%calm_since
    if (ios /= 0) call set_error(st, exit_io, 'checkpoint: payload does not match the scene')
  end subroutine checkpoint_restore

end module checkpoint
