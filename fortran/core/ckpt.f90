!> Checkpoint container, the same for every method:
!>
!>   magic 'PYORCKPT' | format version (int32) | engine version (16 chars) | kind (32 chars)
!>   | scene hash (int64, CRC-64 of the run's resolved scene.nml) | wall time [s] (real64)
!>   | step/units done (int64) | number of output files (int32) | their names (32 chars each)
!>   | their sizes [bytes] (int64 each) | method payload ... | CRC-64 of all preceding bytes
!>
!> Written to path.tmp, checksummed, then renamed into place, so the previous
!> checkpoint survives any failure. Reading verifies the checksum, magic,
!> version, engine version, kind and scene hash before the method reads a
!> byte of payload, and that the payload was consumed exactly.
module ckpt
  use, intrinsic :: iso_fortran_env, only: int8, int32
  use kinds, only: dp, i8
  use errors, only: status_t, set_error, exit_io, msg_len
  use method, only: method_t, fname_len, max_out_files
  use files, only: rename_into_place, remove_file
  implicit none
  private

  public :: ckpt_write, ckpt_read, file_crc64, crc64, engine_version

  character(len=8), parameter :: magic = 'PYORCKPT'
  integer(int32), parameter :: format_version = 5
  character(len=16), parameter :: engine_version = '0.2.0'
  integer, parameter :: chunk = 1048576       !< bytes per read when checksumming

  integer(i8), save :: crc_table(0:255)
  logical, save :: crc_ready = .false.

contains

  subroutine crc_init()
    integer(i8) :: poly, c
    integer :: i, k
    ! ECMA-182 polynomial, reflected (as in xz): 0xC96C5795D7870F42
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

  !> CRC-64 of bytes first .. first+nbytes-1 of an open stream unit.
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

  !> CRC-64 of a whole file (the resolved scene a checkpoint is bound to).
  subroutine file_crc64(path, crc, st)
    character(len=*), intent(in) :: path
    integer(i8), intent(out) :: crc
    type(status_t), intent(inout) :: st
    integer :: u, ios
    integer(i8) :: n
    character(len=msg_len) :: iom
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

  !> Write a checkpoint of method m at `path` (via path.tmp and rename).
  subroutine ckpt_write(path, kind, scene_hash, wall, done, names, sizes, m, st)
    character(len=*), intent(in) :: path, kind
    integer(i8), intent(in) :: scene_hash, done
    real(dp), intent(in) :: wall
    character(len=fname_len), intent(in) :: names(:)
    integer(i8), intent(in) :: sizes(:)
    class(method_t), intent(in) :: m
    type(status_t), intent(inout) :: st
    character(len=:), allocatable :: tmp
    character(len=32) :: kind32
    integer :: u, ios
    integer(i8) :: n, crc
    character(len=msg_len) :: iom
    tmp = trim(path)//'.tmp'
    kind32 = kind
    iom = ''
    open(newunit=u, file=tmp, access='stream', form='unformatted', status='replace', &
         action='readwrite', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, tmp//': cannot write checkpoint: '//trim(iom))
      return
    end if
    write(u, iostat=ios, iomsg=iom) magic, format_version, engine_version, kind32, scene_hash, &
         wall, done, int(size(names), int32), names, sizes
    if (ios == 0) then
      call m%save_state(u, st)
      if (st%code /= 0) ios = -1
    end if
    if (ios == 0) flush(u, iostat=ios, iomsg=iom)
    if (ios == 0) then
      inquire(unit=u, size=n)
      call unit_crc64(u, 1_i8, n, crc, ios)
      if (ios == 0) write(u, pos=n + 1, iostat=ios, iomsg=iom) crc
    end if
    if (ios == 0) flush(u, iostat=ios, iomsg=iom)
    if (ios == 0) then
      close(u, iostat=ios, iomsg=iom)
    else
      close(u)
    end if
    if (ios /= 0 .or. st%code /= 0) then
      call set_error(st, exit_io, tmp//': checkpoint write failed: '//trim(iom)// &
           ' (the previous checkpoint is kept)')
      call remove_file(tmp, st)
      return
    end if
    call rename_into_place(tmp, trim(path), st)
  end subroutine ckpt_write

  !> Verify and read a checkpoint into method m (already loaded from the run's scene).
  !> names/sizes: the output files and their sizes at the checkpoint.
  subroutine ckpt_read(path, kind, scene_hash, wall, done, names, sizes, nfiles, m, st)
    character(len=*), intent(in) :: path, kind
    integer(i8), intent(in) :: scene_hash
    real(dp), intent(out) :: wall
    integer(i8), intent(out) :: done
    character(len=fname_len), intent(out) :: names(max_out_files)
    integer(i8), intent(out) :: sizes(max_out_files)
    integer, intent(out) :: nfiles
    class(method_t), intent(inout) :: m
    type(status_t), intent(inout) :: st
    character(len=8) :: mg
    integer(int32) :: ver, nf
    character(len=16) :: ev
    character(len=32) :: k32
    integer(i8) :: h, n, crc, stored, pos
    integer :: u, ios
    character(len=msg_len) :: iom
    nfiles = 0
    names = ''
    sizes = 0
    wall = 0
    done = 0
    iom = ''
    open(newunit=u, file=trim(path), access='stream', form='unformatted', status='old', &
         action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      call set_error(st, exit_io, trim(path)//': cannot open checkpoint: '//trim(iom))
      return
    end if
    inquire(unit=u, size=n)
    if (n < 8 + 4 + 16 + 32 + 8 + 8 + 8 + 4 + 8) then
      call fail('too short to be a checkpoint'); return
    end if
    call unit_crc64(u, 1_i8, n - 8, crc, ios)
    if (ios == 0) read(u, pos=n - 7, iostat=ios) stored
    if (ios /= 0 .or. crc /= stored) then
      call fail('checksum mismatch (corrupted or truncated)'); return
    end if
    read(u, pos=1, iostat=ios) mg, ver, ev, k32
    if (ios /= 0 .or. mg /= magic) then
      call fail('not a checkpoint of this engine'); return
    end if
    if (ver /= format_version .or. ev /= engine_version) then
      call fail('written by engine '//trim(ev)//' (this is '//trim(engine_version)// &
           '): not resumable with this version'); return
    end if
    if (k32 /= kind) then
      call fail("of kind '"//trim(k32)//"', the run is '"//trim(kind)//"'"); return
    end if
    read(u, iostat=ios) h, wall, done, nf
    if (ios /= 0) then
      call fail('header unreadable'); return
    end if
    if (h /= scene_hash) then
      call fail('belongs to another scene (scene.nml changed since the checkpoint, or the '// &
           'checkpoint comes from another run)'); return
    end if
    if (nf < 0 .or. nf > max_out_files) then
      call fail('bad file count'); return
    end if
    nfiles = nf
    read(u, iostat=ios) names(1:nfiles), sizes(1:nfiles)
    if (ios /= 0) then
      call fail('header unreadable'); return
    end if
    call m%restore_state(u, st)
    if (st%code /= 0) then
      close(u); return
    end if
    inquire(unit=u, pos=pos)
    if (pos /= n - 7) then
      call fail('payload size does not match the scene'); return
    end if
    close(u)
  contains
    subroutine fail(why)
      character(len=*), intent(in) :: why
      close(u)
      call set_error(st, exit_io, trim(path)//': checkpoint refused: '//why)
    end subroutine fail
  end subroutine ckpt_read

end module ckpt
