!> Checkpoints. A checkpoint file is a fixed header and a payload:
!>
!>   magic 'PYORCKPT' (8 bytes) | format version (int32) | header length (int32)
!>   | engine version (16 chars) | kind (32 chars) | scene hash (int64)
!>   | payload length [bytes] (int64) | payload CRC-64 (int64) | payload ...
!>
!> The header part is generic (any simulation kind): ckpt_begin opens a
!> temporary file (checked C stdio, see module output) with a placeholder
!> header, the caller appends its payload with ckpt_put (bytes, checksummed
!> as they go), ckpt_commit writes the real header, flushes, fsyncs and
!> renames the file into place (then fsyncs the directory), so the previous
!> checkpoint survives any failure. ckpt_open verifies every header field and the checksum before
!> the caller reads a byte of payload (Fortran stream reads); ckpt_close
!> checks that the payload was consumed exactly.
!>
!> The bed payload (checkpoint_write / checkpoint_read): the complete dynamic
!> state (particles, integrator history, frozen far field, neighbour list
!> with its reference positions, step, RNG state, output file sizes, wall time).
module checkpoint
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_long
  use, intrinsic :: iso_fortran_env, only: int8, int32
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io, exit_ok
  use state, only: state_t
  use neighbours, only: nlist_t
  use output, only: rename_into_place, engine_version, file_exists, remove_file, cfile_t, &
       cf_open, cf_write, cf_seek, cf_close, sync_dir
  implicit none
  private

  public :: checkpoint_write, checkpoint_read, truncate_file
  public :: ckpt_writer_t, ckpt_begin, ckpt_put, ckpt_commit, ckpt_open, ckpt_close, &
       file_crc64, crc64, ckpt_kind_len

  !> A checkpoint being written: its temporary file and the running checksum.
  type :: ckpt_writer_t
    type(cfile_t) :: f
    character(len=:), allocatable :: path   !< final name (the file is path.tmp until commit)
    integer(i8) :: crc = 0
    integer(i8) :: nbytes = 0
    type(status_t) :: st
  end type ckpt_writer_t

  character(len=8), parameter :: magic = 'PYORCKPT'
  integer(int32), parameter :: format_version = 4
  integer, parameter :: ckpt_kind_len = 32
  integer(int32), parameter :: header_len = 8 + 4 + 4 + 16 + ckpt_kind_len + 8 + 8 + 8
  integer, parameter :: chunk = 1048576   !< bytes per read when checksumming

  interface
    integer(c_int) function c_truncate(path, length) bind(C, name='truncate')
      import :: c_int, c_char, c_long
      character(kind=c_char), intent(in) :: path(*)
      integer(c_long), value :: length
    end function c_truncate
  end interface

  integer(i8), save :: crc_table(0:255)
  logical, save :: crc_ready = .false.

contains

  ! ---- CRC-64 (ECMA-182, reflected, as in xz) -------------------------------

  subroutine crc_init()
    integer(i8) :: poly, c
    integer :: i, k
    poly = ior(shiftl(int(z'C96C5795', i8), 32), int(z'D7870F42', i8))
    do i = 0, 255
      c = int(i, i8)
      do k = 1, 8
        if (iand(c, 1_i8) /= 0) then
          c = ieor(shiftr(c, 1), poly)
        else
          c = shiftr(c, 1)
        end if
      end do
      crc_table(i) = c
    end do
    crc_ready = .true.
  end subroutine crc_init

  !> Continue a CRC-64 over bytes b (start with crc = 0).
  subroutine crc64(crc, b)
    integer(i8), intent(inout) :: crc
    integer(int8), intent(in) :: b(:)
    integer :: i
    integer(i8) :: c
    if (.not. crc_ready) call crc_init()
    c = not(crc)
    do i = 1, size(b)
      c = ieor(crc_table(int(iand(ieor(c, int(b(i), i8)), 255_i8))), shiftr(c, 8))
    end do
    crc = not(c)
  end subroutine crc64

  !> CRC-64 of the bytes of unit u (stream, opened for reading) from byte
  !> position first for nbytes bytes.
  subroutine unit_crc64(u, first, nbytes, crc, ios)
    integer, intent(in) :: u
    integer(i8), intent(in) :: first, nbytes
    integer(i8), intent(out) :: crc
    integer, intent(out) :: ios
    integer(int8), allocatable :: buf(:)
    integer(i8) :: done, m
    crc = 0
    ios = 0
    allocate(buf(chunk))
    done = 0
    do while (done < nbytes)
      m = min(int(chunk, i8), nbytes - done)
      read(u, pos=first + done, iostat=ios) buf(1:m)
      if (ios /= 0) return
      call crc64(crc, buf(1:m))
      done = done + m
    end do
  end subroutine unit_crc64

  !> CRC-64 of a whole file (e.g. the resolved scene a checkpoint is bound to).
  subroutine file_crc64(path, crc, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(out) :: crc
    type(status_t), intent(inout) :: st
    integer :: u, ios
    integer(i8) :: n
    character(len=256) :: iom
    crc = 0
    iom = ''
    open(newunit=u, file=trim(path), access='stream', form='unformatted', status='old', &
         action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot open: '//trim(iom))
      return
    end if
    inquire(unit=u, size=n)
    call unit_crc64(u, 1_i8, n, crc, ios)
    close(u)
    if (ios /= 0) call set_error(st, exit_io, trim(path)//': cannot read')
  end subroutine file_crc64

  ! ---- generic container -------------------------------------------------------

  !> Open path.tmp for a new checkpoint; the caller then appends its
  !> payload with ckpt_put and calls ckpt_commit.
  subroutine ckpt_begin(w, path)
    type(ckpt_writer_t), intent(out) :: w
    character(len=*), intent(in) :: path
    integer(int8) :: zeros(header_len)
    w%path = trim(path)
    call cf_open(w%f, w%path//'.tmp', 'w', w%st)
    zeros = 0
    call cf_write(w%f, zeros, w%st)
  end subroutine ckpt_begin

  !> Append payload bytes (use transfer(x, [0_int8]) for any variable).
  subroutine ckpt_put(w, b)
    type(ckpt_writer_t), intent(inout) :: w
    integer(int8), intent(in) :: b(:)
    if (w%st%code /= exit_ok) return
    call cf_write(w%f, b, w%st)
    call crc64(w%crc, b)
    w%nbytes = w%nbytes + size(b)
  end subroutine ckpt_put

  !> Write the header, flush, fsync, close, rename into place. On any
  !> failure the temporary file is removed, the previous checkpoint is kept
  !> and the OS error is returned in st.
  subroutine ckpt_commit(w, kind, scene_hash, st)
    type(ckpt_writer_t), intent(inout) :: w
    character(len=*), intent(in) :: kind
    integer(i8), intent(in) :: scene_hash
    type(status_t), intent(inout) :: st
    character(len=16) :: ver
    character(len=ckpt_kind_len) :: kd
    type(status_t) :: junk
    ver = engine_version
    kd = kind
    call cf_seek(w%f, 0_i8, w%st)
    if (w%st%code == exit_ok) call cf_write(w%f, [transfer(magic, [0_int8]), &
         transfer(format_version, [0_int8]), transfer(header_len, [0_int8]), &
         transfer(ver, [0_int8]), transfer(kd, [0_int8]), transfer(scene_hash, [0_int8]), &
         transfer(w%nbytes, [0_int8]), transfer(w%crc, [0_int8])], w%st)
    call cf_close(w%f, w%st, sync=.true.)
    if (w%st%code == exit_ok) call rename_into_place(w%path//'.tmp', w%path, w%st)
    if (w%st%code == exit_ok) call sync_dir(w%path)
    if (w%st%code /= exit_ok) then
      call remove_file(w%path//'.tmp', junk)
      call set_error(st, w%st%code, trim(w%st%msg)//' (the previous checkpoint, if any, '// &
           'is kept)')
    end if
  end subroutine ckpt_commit

  !> Open a checkpoint and verify it before any payload is read: magic,
  !> format version, engine version, kind, scene hash, payload length and
  !> checksum. On success u is positioned at the first payload byte.
  subroutine ckpt_open(path, kind, scene_hash, u, st)
    character(len=*), intent(in) :: path, kind
    integer(i8), intent(in) :: scene_hash
    integer, intent(out) :: u
    type(status_t), intent(inout) :: st
    integer :: ios
    character(len=256) :: iom
    character(len=8) :: mg
    integer(int32) :: ver, hlen
    character(len=16) :: ever
    character(len=ckpt_kind_len) :: kd
    integer(i8) :: hash, nbytes, crc, crc_now, total
    character(len=40) :: b1, b2
    iom = ''
    u = -1
    if (.not. file_exists(path)) then
      call set_error(st, exit_io, trim(path)//': no checkpoint')
      return
    end if
    open(newunit=u, file=trim(path), access='stream', form='unformatted', status='old', &
         action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot open checkpoint: '//trim(iom))
      u = -1
      return
    end if
    inquire(unit=u, size=total)
    if (total < header_len) then
      call refuse('too short to be a checkpoint')
      return
    end if
    read(u, pos=1, iostat=ios) mg, ver, hlen, ever, kd, hash, nbytes, crc
    if (ios /= 0 .or. mg /= magic) then
      call refuse('not a checkpoint (bad magic)')
    else if (ver /= format_version .or. hlen /= header_len) then
      write(b1, '(i0)') ver
      write(b2, '(i0)') format_version
      call refuse('checkpoint format '//trim(b1)//', this engine reads format '//trim(b2))
    else if (ever /= engine_version) then
      call refuse('written by engine version '''//trim(printable(ever))//''', this is '''// &
           engine_version//'''')
    else if (kd /= kind) then
      call refuse('checkpoint of kind '''//trim(printable(kd))//''', the scene is '''// &
           trim(kind)//'''')
    else if (hash /= scene_hash) then
      call refuse('belongs to another scene (its scene hash differs from scene.nml: the '// &
           'scene was edited, or the checkpoint comes from another run)')
    else if (nbytes /= total - header_len) then
      write(b1, '(i0)') total - header_len
      write(b2, '(i0)') nbytes
      call refuse('truncated or extended: payload of '//trim(b1)//' bytes, the header '// &
           'records '//trim(b2))
    else
      call unit_crc64(u, int(header_len, i8) + 1, nbytes, crc_now, ios)
      if (ios /= 0 .or. crc_now /= crc) then
        call refuse('corrupted (payload checksum mismatch)')
      else
        read(u, pos=int(header_len, i8) + 1, iostat=ios)   ! position at the payload
        if (ios /= 0) call refuse('cannot read the payload')
      end if
    end if
  contains
    subroutine refuse(why)
      character(len=*), intent(in) :: why
      call set_error(st, exit_io, trim(path)//': refused: '//why)
      close(u, iostat=ios)
      u = -1
    end subroutine refuse
  end subroutine ckpt_open

  !> End a payload read: ios of the reads, and the payload must be consumed
  !> exactly (a checksummed payload of the wrong shape is refused too).
  subroutine ckpt_close(u, path, ios, st)
    integer, intent(inout) :: u
    character(len=*), intent(in) :: path
    integer, intent(in) :: ios
    type(status_t), intent(inout) :: st
    integer(i8) :: pos, total
    integer :: ios2
    if (u == -1) return
    if (ios == 0) then
      inquire(unit=u, pos=pos, size=total)
      if (pos /= total + 1) call set_error(st, exit_io, trim(path)//': refused: payload '// &
           'does not match the scene (unread bytes)')
    else
      call set_error(st, exit_io, trim(path)//': refused: payload does not match the scene')
    end if
    close(u, iostat=ios2)
    u = -1
  end subroutine ckpt_close

  pure function printable(s) result(r)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: r
    integer :: i, c
    r = s
    do i = 1, len(s)
      c = iachar(s(i:i))
      if (c < 32 .or. c > 126) r(i:i) = '?'
    end do
  end function printable

  ! ---- the bed payload --------------------------------------------------------

  subroutine checkpoint_write(path, kind, scene_hash, s, nl, sizes, wall, pst, st)
    character(len=*), intent(in) :: path, kind
    integer(i8), intent(in) :: scene_hash
    type(state_t), intent(in) :: s
    type(state_t), intent(in) :: pst      !< free piston (unallocated otherwise)
    type(nlist_t), intent(in) :: nl
    integer(i8), intent(in) :: sizes(4)   !< bytes of piston, particles, distance, energy files
    real(dp), intent(in) :: wall          !< wall time so far [s]
    type(status_t), intent(inout) :: st
    type(ckpt_writer_t) :: w
    integer :: k
    integer, allocatable :: rng(:)
    integer(int8), parameter :: b(0) = [integer(int8) ::]
    call random_seed(size=k)
    allocate(rng(k))
    call random_seed(get=rng)
    call ckpt_begin(w, path)
    call ckpt_put(w, [transfer(s%n, b), transfer(s%step, b), transfer(s%t, b), &
         transfer(s%piston_h, b), transfer(s%piston_force, b), transfer(s%phase, b), &
         transfer(s%has_previous, b), transfer(s%tail_ready, b), transfer(sizes, b), &
         transfer(wall, b), transfer(k, b)])
    call ckpt_put(w, transfer(rng, b))
    call ckpt_put(w, transfer(s%x, b)); call ckpt_put(w, transfer(s%y, b))
    call ckpt_put(w, transfer(s%vx, b)); call ckpt_put(w, transfer(s%vy, b))
    call ckpt_put(w, transfer(s%xp, b)); call ckpt_put(w, transfer(s%yp, b))
    call ckpt_put(w, transfer(s%fx, b)); call ckpt_put(w, transfer(s%fy, b))
    call ckpt_put(w, transfer(s%fmag, b)); call ckpt_put(w, transfer(s%s3, b))
    call ckpt_put(w, transfer(s%fx_far, b)); call ckpt_put(w, transfer(s%fy_far, b))
    call ckpt_put(w, transfer(s%s3_far, b)); call ckpt_put(w, transfer(s%id, b))
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
      call ckpt_put(w, transfer(pst%has_previous, b))
    end if
    call ckpt_commit(w, kind, scene_hash, st)
  end subroutine checkpoint_write

  subroutine checkpoint_read(path, kind, scene_hash, s, nl, sizes, wall, pst, st)
    character(len=*), intent(in) :: path, kind
    integer(i8), intent(in) :: scene_hash
    type(state_t), intent(inout) :: s      !< allocated for the scene's n
    type(state_t), intent(inout) :: pst    !< free piston, allocated when the scene has one
    type(nlist_t), intent(inout) :: nl     !< set up for the scene's strategy
    integer(i8), intent(out) :: sizes(4)
    real(dp), intent(out) :: wall
    type(status_t), intent(inout) :: st
    integer :: u, ios, n, k, ncs, nnb
    integer, allocatable :: rng(:)
    logical :: has_list, has_piston
    sizes = 0
    wall = 0
    call ckpt_open(path, kind, scene_hash, u, st)
    if (u == -1) return
    read(u, iostat=ios) n
    if (ios == 0 .and. n /= s%n) then
      call set_error(st, exit_io, trim(path)//': refused: checkpoint particle count differs '// &
           'from the scene')
      close(u); return
    end if
    if (ios == 0) read(u, iostat=ios) s%step, s%t, s%piston_h, s%piston_force, s%phase, &
         s%has_previous, s%tail_ready, sizes, wall, k
    if (ios == 0) then
      call random_seed(size=ncs)
      if (k /= ncs) ios = 1
    end if
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
      if (ios == 0 .and. (nnb < 0 .or. .not. allocated(nl%start))) ios = 1
      if (ios == 0) then
        if (allocated(nl%nbr)) deallocate(nl%nbr)
        allocate(nl%nbr(nnb))
        read(u, iostat=ios) nl%cell_start, nl%cell_part, nl%start, nl%nbr, nl%xref, nl%yref
      end if
    end if
    if (ios == 0) read(u, iostat=ios) has_piston
    if (ios == 0 .and. (has_piston .neqv. allocated(pst%y))) ios = 1
    if (ios == 0 .and. has_piston) read(u, iostat=ios) pst%y, pst%yp, pst%vy, pst%fy, &
         pst%has_previous
    call ckpt_close(u, path, ios, st)
  end subroutine checkpoint_read

  !> Cut a file back to `length` bytes (drops rows written after a
  !> checkpoint). A file shorter than the checkpoint recorded is refused:
  !> it is never padded.
  subroutine truncate_file(path, length, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: length
    type(status_t), intent(inout) :: st
    integer(i8) :: now
    character(len=64) :: b
    if (.not. file_exists(path)) then
      if (length > 0) call set_error(st, exit_io, trim(path)//': missing output file to resume')
      return
    end if
    inquire(file=trim(path), size=now)
    if (now < length) then
      write(b, '(i0,a,i0)') now, ' bytes, the checkpoint recorded ', length
      call set_error(st, exit_io, trim(path)//': refused: shorter than at the checkpoint ('// &
           trim(b)//'); the run directory is damaged')
      return
    end if
    if (c_truncate(trim(path)//c_null_char, int(length, c_long)) /= 0) &
         call set_error(st, exit_io, trim(path)//': cannot truncate to the checkpoint')
  end subroutine truncate_file

end module checkpoint
