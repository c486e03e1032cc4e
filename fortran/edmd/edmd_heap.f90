!> The event calendar of the event-driven engine: an indexed binary min-heap
!> holding at most one entry per particle (its earliest predicted event).
!> Insert, update (decrease or increase key), remove and peek are O(log N) /
!> O(1); the heap never holds more than N entries, so stale events cost no
!> memory (they are detected at the top by the collision counters of the
!> partners and re-predicted, module edmd_core).
!> Ties are broken by the particle id (smaller first), so the order of events
!> is a function of the keys only and not of the history of the heap: the
!> calendar rebuilt on restore pops in the same order as the original.
module edmd_heap
  use kinds, only: dp
  implicit none
  private

  public :: heap_t, heap_init, heap_set, heap_remove, heap_top

  type :: heap_t
    integer :: n = 0                       !< entries in the heap
    integer, allocatable :: item(:)        !< item(k): particle at heap slot k
    integer, allocatable :: slot(:)        !< slot(i): heap slot of particle i (0: absent)
    real(dp), allocatable :: key(:)        !< key(i): event time of particle i
    real(dp), allocatable :: hkey(:)       !< hkey(k) = key(item(k)): keys in heap order, so the
                                           !< sifts read contiguous memory (measured: bench)
  end type heap_t

contains

  subroutine heap_init(h, n)
    type(heap_t), intent(out) :: h
    integer, intent(in) :: n
    allocate(h%item(n), h%slot(n), h%key(n), h%hkey(n))
    h%n = 0
    h%slot = 0
    h%key = huge(1.0_dp)
    h%hkey = huge(1.0_dp)
  end subroutine heap_init

  !> (ka, a) before (kb, b): earlier time, ties by the smaller particle id.
  pure logical function before(ka, a, kb, b)
    real(dp), intent(in) :: ka, kb
    integer, intent(in) :: a, b
    before = ka < kb .or. (ka == kb .and. a < b)
  end function before

  !> Insert particle i with key t, or move it to key t.
  subroutine heap_set(h, i, t)
    type(heap_t), intent(inout) :: h
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    integer :: k
    h%key(i) = t
    k = h%slot(i)
    if (k == 0) then
      h%n = h%n + 1
      k = h%n
      h%item(k) = i
      h%slot(i) = k
    end if
    h%hkey(k) = t
    call sift_up(h, k)
    call sift_down(h, h%slot(i))
  end subroutine heap_set

  subroutine heap_remove(h, i)
    type(heap_t), intent(inout) :: h
    integer, intent(in) :: i
    integer :: k, last
    k = h%slot(i)
    if (k == 0) return
    last = h%item(h%n)
    h%item(k) = last
    h%hkey(k) = h%hkey(h%n)
    h%slot(last) = k
    h%n = h%n - 1
    h%slot(i) = 0
    h%key(i) = huge(1.0_dp)
    if (k <= h%n) then
      call sift_up(h, k)
      call sift_down(h, h%slot(last))
    end if
  end subroutine heap_remove

  !> Particle with the earliest event (0 if the heap is empty).
  pure integer function heap_top(h)
    type(heap_t), intent(in) :: h
    heap_top = 0
    if (h%n > 0) heap_top = h%item(1)
  end function heap_top

  subroutine sift_up(h, k0)
    type(heap_t), intent(inout) :: h
    integer, intent(in) :: k0
    integer :: k, p, a
    real(dp) :: ka
    k = k0
    a = h%item(k)
    ka = h%hkey(k)
    do while (k > 1)
      p = k/2
      if (.not. before(ka, a, h%hkey(p), h%item(p))) exit
      h%item(k) = h%item(p)
      h%hkey(k) = h%hkey(p)
      h%slot(h%item(k)) = k
      k = p
    end do
    h%item(k) = a
    h%hkey(k) = ka
    h%slot(a) = k
  end subroutine sift_up

  subroutine sift_down(h, k0)
    type(heap_t), intent(inout) :: h
    integer, intent(in) :: k0
    integer :: k, c, a
    real(dp) :: ka
    k = k0
    a = h%item(k)
    ka = h%hkey(k)
    do
      c = 2*k
      if (c > h%n) exit
      if (c < h%n) then
        if (before(h%hkey(c + 1), h%item(c + 1), h%hkey(c), h%item(c))) c = c + 1
      end if
      if (.not. before(h%hkey(c), h%item(c), ka, a)) exit
      h%item(k) = h%item(c)
      h%hkey(k) = h%hkey(c)
      h%slot(h%item(k)) = k
      k = c
    end do
    h%item(k) = a
    h%hkey(k) = ka
    h%slot(a) = k
  end subroutine sift_down

end module edmd_heap
