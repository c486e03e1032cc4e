!> What this process may still allocate (MemAvailable, the cgroup limit, ulimit -v and -d,
!> each minus what is already in use; the smallest), and the refusal of a scene whose memory
!> estimate exceeds it: before anything is allocated, naming the estimate and the limit.
module memory
  use, intrinsic :: iso_c_binding, only: c_int, c_long
  use kinds, only: dp
  use errors, only: status_t, set_error, exit_bad_input
  implicit none
  private

  public :: memory_available, check_memory_need

  integer(c_int), parameter :: rlimit_data = 2, rlimit_as = 9   !< Linux resource numbers

  type, bind(C) :: rlimit_t
    integer(c_long) :: cur, max   !< rlim_t; RLIM_INFINITY reads as -1
  end type rlimit_t

  interface
    integer(c_int) function c_getrlimit(resource, rl) bind(C, name='getrlimit')
      import :: c_int, rlimit_t
      integer(c_int), value :: resource
      type(rlimit_t), intent(out) :: rl
    end function c_getrlimit
  end interface

contains

  !> Refused (exit_bad_input) when `need` bytes exceed what is available: `what` names the key
  !> and value ('FILE: &group key = value'), `fix` what to change.
  subroutine check_memory_need(need, what, fix, st)
    real(dp), intent(in) :: need
    character(len=*), intent(in) :: what, fix
    type(status_t), intent(inout) :: st
    real(dp) :: avail
    character(len=:), allocatable :: which
    character(len=80) :: b
    call memory_available(avail, which)
    if (avail > 0 .and. need > avail) then
      write(b, '(f0.1,a,f0.1,a)') need/2.0_dp**20, ' MiB of memory, ', avail/2.0_dp**20, ' MiB'
      call set_error(st, exit_bad_input, what//': the run needs about '//trim(b)// &
           ' are available ('//which//'): '//fix)
    end if
  end subroutine check_memory_need

  subroutine memory_available(avail, which)
    real(dp), intent(out) :: avail     !< bytes; <= 0: unknown
    character(len=:), allocatable, intent(out) :: which
    type(rlimit_t) :: rl
    real(dp) :: v, vm_size, vm_data
    avail = -1
    which = 'unknown'
    vm_size = proc_kb('/proc/self/status', 'VmSize:')*1024
    vm_data = proc_kb('/proc/self/status', 'VmData:')*1024
    v = proc_kb('/proc/meminfo', 'MemAvailable:')*1024
    if (v > 0) call take(v, 'MemAvailable')
    v = file_number('/sys/fs/cgroup/memory.max')
    if (v > 0) call take(v - max(0.0_dp, file_number('/sys/fs/cgroup/memory.current')), &
         'cgroup memory.max')
    if (c_getrlimit(rlimit_as, rl) == 0) then
      if (rl%cur > 0) call take(real(rl%cur, dp) - max(0.0_dp, vm_size), 'ulimit -v')
    end if
    if (c_getrlimit(rlimit_data, rl) == 0) then
      if (rl%cur > 0) call take(real(rl%cur, dp) - max(0.0_dp, vm_data), 'ulimit -d')
    end if
  contains
    subroutine take(x, name)
      real(dp), intent(in) :: x
      character(len=*), intent(in) :: name
      if (avail < 0 .or. x < avail) then
        avail = max(x, 1.0_dp)
        which = name
      end if
    end subroutine take
  end subroutine memory_available

  !> The number after `key` in a /proc file such as /proc/meminfo (kB); -1 if absent.
  real(dp) function proc_kb(path, key) result(v)
    character(len=*), intent(in) :: path, key
    integer :: u, ios
    character(len=256) :: ln
    v = -1
    open(newunit=u, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) return
    do
      read(u, '(a)', iostat=ios) ln
      if (ios /= 0) exit
      if (index(ln, key) == 1) then
        read(ln(len(key) + 1:), *, iostat=ios) v
        if (ios /= 0) v = -1
        exit
      end if
    end do
    close(u)
  end function proc_kb

  !> A file holding one number (e.g. cgroup memory.max); -1 if absent or 'max'.
  real(dp) function file_number(path) result(v)
    character(len=*), intent(in) :: path
    integer :: u, ios
    v = -1
    open(newunit=u, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) return
    read(u, *, iostat=ios) v
    if (ios /= 0) v = -1
    close(u)
  end function file_number

end module memory
