!> Event calendar 'buckets' of the event-driven engine: a bucketed priority queue (calendar
!> queue; Brown 1988, the "bounded priority queue" of Marin et al. and DynamO) holding at most
!> one entry per particle (its earliest predicted event), O(1) per operation.
!>
!> An epoch covers the times [t0, t_hi) with nb buckets of width w; an entry of time t sits in
!> bucket k = int((t - t0)/w) (never below the current bucket `cur`, whatever round-off or a
!> time in the past gives), or in the overflow list when t >= t_hi. Buckets are unsorted
!> doubly linked lists. The top is the smallest (time, particle id) of the first non-empty
!> bucket: k is a non-decreasing function of t, so every entry of a later bucket or of the
!> overflow is later. Ties are broken by the particle id as in edmd_heap, so both calendars
!> pop the same sequence (a function of the keys only, not of the history of the queue: a
!> calendar rebuilt on restore pops in the same order). When the buckets are exhausted the
!> next epoch starts at the earliest overflow time, with w from the spread of the entries
!> (nb = 16 n, w = mean lead time / (2 n): about half an entry per bucket at the front; horizon
!> nb w = 8 mean lead times), so the queue follows a changing event rate (an aggregating gas).
!> The bucket count and width change the cost only (2-32 n buckets: within +-5 %, bench/RESULTS.md
!> s. 18), never the order.
module edmd_buckets
  use kinds, only: dp, i8
  implicit none
  private

  public :: bq_t, bq_entry_t, bq_init, bq_set, bq_remove, bq_top

  real(dp), parameter :: never = huge(1.0_dp)
  integer, parameter :: horizon = 8           !< epoch length in mean lead times

  !> One particle's entry, 64 bytes: the queue's fields and a payload the queue does not read
  !> (the engine's prediction of that particle), so that a pop or an update and the prediction
  !> share one cache line. The caller holds the array (one entry per particle) and passes it
  !> whole (assumed size: contiguous, no stride arithmetic in the accesses; s. 32.1).
  type :: bq_entry_t
    real(dp) :: key = never                   !< event time
    integer :: next = 0, prev = 0             !< bucket list links (0: none)
    integer :: bucket = -1                    !< -1 absent, 0..nb-1 a bucket, nb the overflow
    ! payload (edmd_core): the event and the best pair candidate of the last cell scans
    integer :: kind = 0, partner = 0          !< event type, partner (wall, direction, disk)
    integer :: pj = 0                         !< candidate partner (0: none)
    real(dp) :: pt = never                    !< candidate's collision time
    integer(i8) :: count = 0                  !< partner's collision counter at the prediction
    integer(i8) :: pcount = 0                 !< candidate's collision counter at its scan
    real(dp) :: m = 0                         !< the particle's mass [M] (edmd_core's copy: a pair
                                              !< or wall hit reads it from the lines it holds)
  end type bq_entry_t

  type :: bq_t
    integer :: n = 0                          !< entries
    integer :: nb = 1                         !< buckets of an epoch
    integer :: cur = 0                        !< first possibly non-empty bucket
    integer :: hint = 0                       !< likely next top after the last bq_top (or 0):
                                              !< for prefetching only, never for the order
    logical :: hints = .false.                !< keep the hint (else hint = 0)
    real(dp) :: t0 = 0, inv_w = 1             !< epoch start [time], 1 / bucket width
    real(dp) :: t_hi = -never                 !< epoch end: later entries overflow
    integer, allocatable :: head(:)           !< head(0:nb): first entry of each list
  end type bq_t

contains

  subroutine bq_init(q, n)
    type(bq_t), intent(out) :: q
    integer, intent(in) :: n
    q%nb = max(16, 2*horizon*n)
    allocate(q%head(0:q%nb))
    q%head = 0
    q%n = 0
    q%cur = q%nb                              ! no epoch yet: every entry overflows
    q%t_hi = -never
  end subroutine bq_init

  !> List (bucket or overflow) of time t in the current epoch.
  pure integer function list_of(q, t) result(k)
    type(bq_t), intent(in) :: q
    real(dp), intent(in) :: t
    real(dp) :: x
    if (.not. (t < q%t_hi)) then
      k = q%nb
      return
    end if
    x = (t - q%t0)*q%inv_w
    if (x < real(q%cur, dp)) then
      k = q%cur
    else
      k = min(int(x), q%nb - 1)
    end if
  end function list_of

  subroutine link(q, e, i, k)
    type(bq_t), intent(inout) :: q
    type(bq_entry_t), intent(inout) :: e(*)
    integer, intent(in) :: i, k
    integer :: h
    h = q%head(k)
    e(i)%bucket = k
    e(i)%prev = 0
    e(i)%next = h
    if (h /= 0) e(h)%prev = i
    q%head(k) = i
  end subroutine link

  subroutine unlink(q, e, i)
    type(bq_t), intent(inout) :: q
    type(bq_entry_t), intent(inout) :: e(*)
    integer, intent(in) :: i
    integer :: p, nx
    p = e(i)%prev
    nx = e(i)%next
    if (p /= 0) then
      e(p)%next = nx
    else
      q%head(e(i)%bucket) = nx
    end if
    if (nx /= 0) e(nx)%prev = p
    e(i)%bucket = -1
  end subroutine unlink

  !> Insert particle i with key t, or move it to key t.
  subroutine bq_set(q, e, i, t)
    type(bq_t), intent(inout) :: q
    type(bq_entry_t), intent(inout) :: e(*)
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    integer :: k
    k = list_of(q, t)
    if (e(i)%bucket >= 0) then
      if (e(i)%bucket == k) then            ! same list: only the key changes
        e(i)%key = t
        return
      end if
      call unlink(q, e, i)
    else
      q%n = q%n + 1
    end if
    e(i)%key = t
    call link(q, e, i, k)
  end subroutine bq_set

  subroutine bq_remove(q, e, i)
    type(bq_t), intent(inout) :: q
    type(bq_entry_t), intent(inout) :: e(*)
    integer, intent(in) :: i
    if (e(i)%bucket < 0) return
    call unlink(q, e, i)
    e(i)%key = never
    q%n = q%n - 1
  end subroutine bq_remove

  !> Smallest (key, id) of list k (0 if empty).
  pure integer function list_min(q, e, k) result(best)
    type(bq_t), intent(in) :: q
    type(bq_entry_t), intent(in) :: e(*)
    integer, intent(in) :: k
    integer :: i
    real(dp) :: kb
    best = q%head(k)
    if (best == 0) return
    kb = e(best)%key
    i = e(best)%next
    do while (i /= 0)
      if (e(i)%key < kb .or. (e(i)%key == kb .and. i < best)) then
        best = i
        kb = e(i)%key
      end if
      i = e(i)%next
    end do
  end function list_min

  !> Likely next top after top (the first entry of bucket cur): the earliest other entry of
  !> that bucket, else the first entry of one of the next 8 buckets (0: none). A guess for
  !> prefetching (a later insertion may come first), never used for the order.
  pure integer function next_hint(q, e, top) result(h)
    type(bq_t), intent(in) :: q
    type(bq_entry_t), intent(in) :: e(*)
    integer, intent(in) :: top
    integer :: i, k
    h = 0
    i = q%head(q%cur)
    do while (i /= 0)
      if (i /= top) then
        if (h == 0) then
          h = i
        else if (e(i)%key < e(h)%key) then
          h = i
        end if
      end if
      i = e(i)%next
    end do
    do k = q%cur + 1, min(q%cur + 8, q%nb - 1)
      if (h /= 0) return
      h = q%head(k)
    end do
  end function next_hint

  !> Particle with the earliest event (0 if the queue is empty).
  integer function bq_top(q, e) result(top)
    type(bq_t), intent(inout) :: q
    type(bq_entry_t), intent(inout) :: e(*)
    top = 0
    q%hint = 0
    if (q%n == 0) return
    do
      do while (q%cur < q%nb)
        if (q%head(q%cur) /= 0) then
          top = list_min(q, e, q%cur)
          if (q%hints) q%hint = next_hint(q, e, top)
          return
        end if
        q%cur = q%cur + 1
      end do
      if (.not. new_epoch(q, e)) then            ! only entries without an event (key = never)
        top = list_min(q, e, q%nb)
        return
      end if
    end do
  end function bq_top

  !> The buckets are empty: start the epoch at the earliest overflow time and move the
  !> overflow into it. .false. (nothing moved) if no entry has a finite time.
  logical function new_epoch(q, e) result(moved)
    type(bq_t), intent(inout) :: q
    type(bq_entry_t), intent(inout) :: e(*)
    integer :: i, nx, nf
    real(dp) :: tmin, lead, w
    tmin = never
    nf = 0
    i = q%head(q%nb)
    do while (i /= 0)
      if (e(i)%key < never) then
        tmin = min(tmin, e(i)%key)
        nf = nf + 1
      end if
      i = e(i)%next
    end do
    moved = nf > 0
    if (.not. moved) return
    lead = 0
    i = q%head(q%nb)
    do while (i /= 0)
      if (e(i)%key < never) lead = lead + (e(i)%key - tmin)
      i = e(i)%next
    end do
    w = real(horizon, dp)*(lead/real(nf, dp))/real(q%nb, dp)
    w = max(w, 1.0e-12_dp*max(1.0_dp, abs(tmin)))
    q%t0 = tmin
    q%inv_w = 1.0_dp/w
    q%t_hi = tmin + real(q%nb, dp)*w
    q%cur = 0
    i = q%head(q%nb)
    q%head(q%nb) = 0
    do while (i /= 0)
      nx = e(i)%next
      call link(q, e, i, list_of(q, e(i)%key))
      i = nx
    end do
  end function new_epoch

end module edmd_buckets
