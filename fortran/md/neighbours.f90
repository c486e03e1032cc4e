!> Neighbour strategies feeding the one pair kernel:
!>   all_pairs  O(N^2) reference, no cut-off;
!>   cells      pairs within r_c found from a cell grid at every step (no skin);
!>   verlet     half Verlet list of radius r_c + skin built from cells, rebuilt
!>              when the largest displacement since the last build exceeds skin/2
!>              (never at a fixed interval), particles re-sorted by cell at rebuilds;
!>   thesis     the thesis' variant (ch. 5.1): every listed pair within r_v = r_c + skin
!>              is used (no cut-off test), same rebuild rule.
!> Walls are never truncated. The rebuild when due and the pruned list are module nlist_upkeep.
module neighbours
  use kinds, only: dp, i8
  use parallel, only: par_min_loop
  implicit none
  private

  public :: nlist_t, nlist_setup, nlist_due, nlist_bin, nlist_build, nlist_owners, max_shift2
  public :: nb_all_pairs, nb_cells, nb_verlet, nb_thesis

  integer, parameter :: nb_all_pairs = 0, nb_cells = 1, nb_verlet = 2, nb_thesis = 3
  !> Largest run of unlisted j kept inside one range (each costs a masked evaluation; a new
  !> range costs a loop start and a partial block)
  integer, parameter :: range_gap = 8
  !> Cells per list radius along each side: cells of side >= rlist/cell_split, the stencil
  !> +-cell_split cells (2: 25 cells of area rlist^2/4, 6.25 rlist^2 of candidates per
  !> particle against 9 with cells of side rlist; the particles sorted by these cells make the
  !> ranges of a row tighter)
  integer, parameter :: cell_split = 2
  !> what nlist_build's scan_row does with a row
  integer, parameter :: row_count = 1, row_fill = 2, row_append = 3, row_candidates = 4

  type :: nlist_t
    integer :: strategy = nb_all_pairs
    real(dp) :: rc = 0          !< cut-off radius [D1]
    real(dp) :: skin = 0        !< list skin [D1]
    real(dp) :: rlist = 0       !< list radius r_c + skin [D1]
    logical :: check = .true.   !< skip listed pairs beyond r_c
    integer :: ncx = 1, ncy = 1 !< cell grid
    real(dp) :: csx = 1, csy = 1  !< cell sizes (>= rlist/cell_split) [D1]
    integer, allocatable :: cell_start(:)  !< (ncx*ncy + 1) CSR offsets into cell_part
    integer, allocatable :: cell_part(:)   !< (n) particles ordered by cell
    integer, allocatable :: start(:)       !< (n + 1) CSR offsets into nbr
    integer, allocatable :: nbr(:)         !< neighbours j > i of each i
    logical :: with_owner = .false.        !< also fill own (flat pair loops)
    integer, allocatable :: own(:)         !< i of each listed pair (with_owner only)
    !> the largest listed j of each row i (i when empty; with_owner only): whether a row's
    !> reactions are all below a thread block's end, the same for the list and its pruned one
    integer, allocatable :: rowmax(:)
    !> also fill the ranges (verlet only): the listed j of row i, cut where two consecutive
    !> ones are more than range_gap apart, as contiguous ranges rlo(r)..rhi(r),
    !> r = rstart(i)..rstart(i+1)-1 (rows_ranges). A range also holds unlisted j; for the
    !> Verlet rule they are beyond r_c until the next rebuild (a pair within r_c now was within
    !> r_c + skin at the build, so listed), and the kernel's r_c test masks them out.
    logical :: with_ranges = .false.
    !> ... built only for a list of at least ranges_from pairs per row (the caller sets the
    !> kernel's threshold: shorter rows never go by ranges, so their ranges would cost ~2 % of
    !> the step for nothing, bench/RESULTS.md 42); otherwise rstart, rlo, rhi are deallocated
    !> (passed as optional arguments, they are then absent)
    real(dp) :: ranges_from = 0
    integer, allocatable :: rstart(:), rlo(:), rhi(:)
    real(dp), allocatable :: xref(:), yref(:)  !< positions at the last build (n)
    !> The pruned list (GROMACS' dynamic pruning, for a verlet list with check): the listed
    !> pairs within r_c + prune of the list, in the list's order, taken again from the list
    !> whenever a particle moved more than prune/2 since (a pair left out was at r >= r_c +
    !> prune then, so is at r >= r_c until then: a kernel that drops or zeroes pairs beyond r_c
    !> sums the same terms in the same order as over the whole list). prune = 0: none.
    real(dp) :: prune = 0
    logical :: pruned = .false.            !< pstart, pnbr, pown hold the pruned list
    integer, allocatable :: pstart(:)      !< (n + 1) CSR offsets into pnbr
    integer, allocatable :: pnbr(:), pown(:)   !< its neighbours j > i, and their rows i
    integer, allocatable :: ptmp(:, :)     !< the threaded prune's blocks (kept: no page faults)
    real(dp), allocatable :: xpr(:), ypr(:)    !< positions at the last prune (n)
    real(dp) :: dprune = 0                 !< largest displacement since the build at that prune
    integer(i8) :: prunes = 0              !< number of prunes
    integer(i8) :: ppairs = 0              !< pairs in the current pruned list
    !> The margin chosen at every build (nlist_margin) when automatic: the force passes and the
    !> prunes (not counting the one after the build) of the current build period, the changes
    logical :: prune_auto = .false.
    integer(i8) :: period_steps = 0, period_prunes = 0, margin_changes = 0
    !> ... and the measured costs it weighs (automatic only): clock ticks spent in prunes and
    !> their work (listed pairs + particles), in the timed force passes over the pruned list
    !> and their pruned pairs (nlist_upkeep nlist_force_start / nlist_force_done)
    integer(i8) :: prune_ticks = 0, prune_work = 0, force_ticks = 0, force_pairs = 0
    integer(i8) :: force_t0 = 0
    real(dp) :: margin_sum = 0             !< the margin summed over the passes that wanted it
    integer(i8) :: margin_passes = 0       !< ... and their number
    logical :: valid = .false.             !< a list exists for the current ordering
    integer(i8) :: builds = 0              !< number of list builds
    integer(i8) :: pairs = 0               !< pairs in the current list
    integer(i8) :: evaluated = 0           !< pair evaluations so far (list lengths summed over steps)
  end type nlist_t

contains

  subroutine nlist_setup(nl, strategy, rc, skin, width, height, n)
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: strategy, n
    real(dp), intent(in) :: rc, skin, width, height
    nl%strategy = strategy
    nl%rc = rc
    nl%skin = skin
    if (strategy == nb_cells) nl%skin = 0
    nl%rlist = rc + nl%skin
    nl%check = strategy /= nb_thesis
    nl%ncx = max(1, min(4096, int(cell_split*width/nl%rlist)))
    nl%ncy = max(1, min(4096, int(cell_split*height/nl%rlist)))
    nl%csx = width/nl%ncx
    nl%csy = height/nl%ncy
    if (allocated(nl%cell_start)) deallocate(nl%cell_start, nl%cell_part, nl%start, nl%xref, nl%yref)
    allocate(nl%cell_start(nl%ncx*nl%ncy + 1), nl%cell_part(n), nl%start(n + 1), &
         nl%xref(n), nl%yref(n))
    if (allocated(nl%nbr)) deallocate(nl%nbr)
    allocate(nl%nbr(max(16, 8*n)), source=0)   ! zeroed: checkpoints save it whole (reproducible)
    nl%valid = .false.
    nl%builds = 0
    nl%prune = 0          ! (the caller sets the scene's margin: nlist_set_prune)
    nl%prune_auto = .false.
    nl%pruned = .false.
    nl%prunes = 0
  end subroutine nlist_setup

  !> Whether the list must be rebuilt before computing forces at x, y.
  logical function nlist_due(nl, n, x, y) result(due)
    type(nlist_t), intent(in) :: nl
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    real(dp) :: lim2, d2max
    integer :: i
    if (.not. nl%valid .or. nl%strategy == nb_cells) then
      due = .true.
      return
    end if
    lim2 = (0.5_dp*nl%skin)**2
    d2max = max_shift2(n, x, y, nl%xref, nl%yref)
    due = d2max > lim2
  end function nlist_due

  !> Largest squared displacement max_i |r_i - r_ref,i|^2 [D1^2].
  function max_shift2(n, x, y, xr, yr) result(d2max)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), xr(n), yr(n)
    real(dp) :: d2max
    integer :: i
    d2max = 0
    if (n < par_min_loop) then     ! no OpenMP region at all (an inactive one costs ~0.3 us)
      do i = 1, n
        d2max = max(d2max, (x(i) - xr(i))**2 + (y(i) - yr(i))**2)
      end do
    else
      !$omp parallel do schedule(static) reduction(max: d2max)
      do i = 1, n
        d2max = max(d2max, (x(i) - xr(i))**2 + (y(i) - yr(i))**2)
      end do
      !$omp end parallel do
    end if
  end function max_shift2


  !> own(k) = the row i of listed pair k (with_owner lists only), and the ranges (with_ranges,
  !> verlet only, rows of ranges_from pairs or more): both follow from start and nbr, also after a restore.
  subroutine nlist_owners(nl, n)
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: n
    integer :: i
    nl%pruned = .false.   ! (a new list, or one restored: pruned again before its next use)
    ! (without them rstart, rlo, rhi are deallocated: passed as optional arguments, they are
    ! then absent, Fortran 2008)
    if (nl%with_ranges .and. nl%strategy == nb_verlet .and. &
        real(nl%start(n + 1) - 1, dp) >= nl%ranges_from*real(n, dp)) then
      call nlist_ranges(nl, n)
    else if (allocated(nl%rstart)) then
      deallocate(nl%rstart)
      if (allocated(nl%rlo)) deallocate(nl%rlo, nl%rhi)
    end if
    if (.not. nl%with_owner) return
    if (allocated(nl%own)) then
      if (size(nl%own) /= size(nl%nbr)) deallocate(nl%own)
    end if
    if (.not. allocated(nl%own)) allocate(nl%own(size(nl%nbr)))
    if (allocated(nl%rowmax)) then
      if (size(nl%rowmax) /= n) deallocate(nl%rowmax)
    end if
    if (.not. allocated(nl%rowmax)) allocate(nl%rowmax(n))
    do i = 1, n
      nl%own(nl%start(i):nl%start(i + 1) - 1) = i
      nl%rowmax(i) = max(i, maxval(nl%nbr(nl%start(i):nl%start(i + 1) - 1), &
           mask=nl%start(i) < nl%start(i + 1)))
    end do
  end subroutine nlist_owners

  !> The ranges of each row (see nlist_t): a row's listed j in increasing order (as nlist_build
  !> writes them for particles sorted by cell) are cut where the gap exceeds range_gap; a row
  !> out of order (never written so) is one range from its smallest to its largest j.
  subroutine nlist_ranges(nl, n)
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: n
    integer :: i, k, nr, pass
    logical :: sorted
    if (allocated(nl%rstart)) then
      if (size(nl%rstart) /= n + 1) deallocate(nl%rstart)
    end if
    if (.not. allocated(nl%rstart)) allocate(nl%rstart(n + 1))
    do pass = 1, 2          ! count, then fill
      nr = 0
      do i = 1, n
        if (pass == 1) nl%rstart(i) = nr + 1
        if (nl%start(i + 1) == nl%start(i)) cycle
        sorted = .true.
        do k = nl%start(i) + 1, nl%start(i + 1) - 1
          sorted = sorted .and. nl%nbr(k) > nl%nbr(k - 1)
        end do
        if (.not. sorted) then
          nr = nr + 1
          if (pass == 2) then
            nl%rlo(nr) = minval(nl%nbr(nl%start(i):nl%start(i + 1) - 1))
            nl%rhi(nr) = maxval(nl%nbr(nl%start(i):nl%start(i + 1) - 1))
          end if
          cycle
        end if
        nr = nr + 1
        if (pass == 2) nl%rlo(nr) = nl%nbr(nl%start(i))
        do k = nl%start(i) + 1, nl%start(i + 1) - 1
          if (nl%nbr(k) - nl%nbr(k - 1) > range_gap + 1) then
            if (pass == 2) nl%rhi(nr) = nl%nbr(k - 1)
            nr = nr + 1
            if (pass == 2) nl%rlo(nr) = nl%nbr(k)
          end if
        end do
        if (pass == 2) nl%rhi(nr) = nl%nbr(nl%start(i + 1) - 1)
      end do
      if (pass == 1) then
        nl%rstart(n + 1) = nr + 1
        if (allocated(nl%rlo)) then
          if (size(nl%rlo) < nr) deallocate(nl%rlo, nl%rhi)
        end if
        if (.not. allocated(nl%rlo)) allocate(nl%rlo(max(16, nr + nr/4)), nl%rhi(max(16, nr + nr/4)))
      end if
    end do
  end subroutine nlist_ranges

  pure integer function cell_index(nl, xi, yi) result(c)
    type(nlist_t), intent(in) :: nl
    real(dp), intent(in) :: xi, yi
    integer :: ix, iy
    ix = min(nl%ncx - 1, max(0, int(xi/nl%csx)))
    iy = min(nl%ncy - 1, max(0, int(yi/nl%csy)))
    c = 1 + ix + nl%ncx*iy
  end function cell_index

  !> Counting sort of the particles by cell: cell_part lists them cell by cell.
  subroutine nlist_bin(nl, n, x, y)
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    integer :: i, c, nc
    integer, allocatable :: fill(:)
    nc = nl%ncx*nl%ncy
    nl%cell_start = 0
    do i = 1, n
      c = cell_index(nl, x(i), y(i))
      nl%cell_start(c + 1) = nl%cell_start(c + 1) + 1
    end do
    nl%cell_start(1) = 1
    do c = 1, nc
      nl%cell_start(c + 1) = nl%cell_start(c + 1) + nl%cell_start(c)
    end do
    allocate(fill(nc))
    fill = nl%cell_start(1:nc)
    do i = 1, n
      c = cell_index(nl, x(i), y(i))
      nl%cell_part(fill(c)) = i
      fill(c) = fill(c) + 1
    end do
  end subroutine nlist_bin

  !> Build the half list (pairs i < j within rlist) from the cell grid.
  !> Assumes nlist_bin was called for the current positions. Two passes over
  !> the particles (count, then fill at the prefix-summed offsets), both
  !> parallel from par_min_loop particles; the list is the same for any thread count.
  !> Serially, one pass instead: each row written where the previous one ended, while its
  !> candidates (the stencil's particles) fit in nbr; a row that might not fit falls back to
  !> the two passes. The rows written by then are those of the two passes at the same
  !> places, and every other slot holds its old value: nbr is the same array either way
  !> (each row scanned into a buffer first, then its kept neighbours copied).
  subroutine nlist_build(nl, n, x, y)
    !$ use omp_lib, only: omp_get_max_threads
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    integer :: i, total, dummy, cand
    integer, allocatable :: cnt(:)
    integer, allocatable :: row(:)   !< serial: one row's candidates, the kept ones first
    logical :: serial
    serial = n < par_min_loop
    !$ serial = serial .or. omp_get_max_threads() == 1
    if (serial) then
      nl%start(1) = 1
      allocate(row(64))
      do i = 1, n
        call scan_row(i, row_candidates, cand, 0, 0)
        if (nl%start(i) + cand - 1 > size(nl%nbr)) exit
        if (cand > size(row)) then
          deallocate(row)
          allocate(row(2*cand))
        end if
        call scan_row(i, row_append, cand, 0, 0)
        nl%nbr(nl%start(i):nl%start(i) + cand - 1) = row(1:cand)
        nl%start(i + 1) = nl%start(i) + cand
      end do
      if (i > n) then
        call built(nl%start(n + 1) - 1)
        return
      end if
    end if
    allocate(cnt(n))
    !$omp parallel do if (n >= par_min_loop) schedule(static) private(i, dummy)
    do i = 1, n
      call scan_row(i, row_count, cnt(i), dummy, 0)
    end do
    !$omp end parallel do
    nl%start(1) = 1
    do i = 1, n
      nl%start(i + 1) = nl%start(i) + cnt(i)
    end do
    total = nl%start(n + 1) - 1
    if (total > size(nl%nbr)) then
      deallocate(nl%nbr)
      allocate(nl%nbr(total + total/4 + 16), source=0)
    end if

    !$omp parallel do if (n >= par_min_loop) schedule(static) private(i, dummy)
    do i = 1, n
      if (cnt(i) > 0) call scan_row(i, row_fill, dummy, nl%start(i), cnt(i))
    end do
    !$omp end parallel do
    call built(total)
  contains
    subroutine built(total)
      integer, intent(in) :: total
      nl%pairs = total
      call nlist_owners(nl, n)
      nl%xref = x
      nl%yref = y
      nl%valid = .true.
      nl%builds = nl%builds + 1
    end subroutine built
    !> Neighbours j > i of particle i within rlist, by mode: count them (row_count), write
    !> them to nbr from position at (row_fill: the row's count from the counting pass is
    !> expected), to row(1:count) (row_append: serial; row holds the candidates), or count
    !> the candidates, the stencil's particles (row_candidates). No branch on the distance (a
    !> candidate is in the list about half the time, so a branch mispredicts): the count adds
    !> the tests' 0 or 1. row_fill writes every candidate to the row's next free slot (the
    !> slot's old value back when the candidate is out - GCC 12 compiles that merge into a
    !> branch and a conditional store - never past the row's last slot, which may be another
    !> thread's); row_append stores every candidate to row's next free slot unconditionally
    !> (no branch: the next candidate overwrites one that is out), and nlist_build copies
    !> the kept ones to nbr, so that nbr past the list keeps its old values.
    subroutine scan_row(i, mode, count, at, expected)
      integer, intent(in) :: i, mode
      integer, intent(out) :: count
      integer, intent(in) :: at, expected
      integer :: c, ix, iy, jx, jy, k, j, slot, k_hi
      real(dp) :: rl2, dx, dy
      logical :: half, keep
      rl2 = nl%rlist**2
      count = 0
      c = cell_index(nl, x(i), y(i)) - 1
      ix = mod(c, nl%ncx)
      iy = c/nl%ncx
      ! particles sorted by cell (all but 'cells'): every j > i is in a cell of index >= i's,
      ! i.e. in i's cell row from i's cell on, or in the rows above
      half = nl%strategy /= nb_cells
      ! the stencil's cells of one cell row are consecutive in cell_part: one loop over them
      ! (the same j in the same order as cell by cell; a cell holds ~1 particle at the
      ! production densities, so a loop per cell cost more than its distances)
      do jy = merge(iy, max(0, iy - cell_split), half), min(nl%ncy - 1, iy + cell_split)
        jx = merge(ix, max(0, ix - cell_split), half .and. jy == iy)
        c = 1 + jx + nl%ncx*jy
        k_hi = nl%cell_start(c + 1 + min(nl%ncx - 1, ix + cell_split) - jx) - 1
        select case (mode)
        case (row_candidates)
          count = count + k_hi - nl%cell_start(c) + 1
        case (row_count)
          do k = nl%cell_start(c), k_hi
            j = nl%cell_part(k)
            dx = x(i) - x(j)
            dy = y(i) - y(j)
            count = count + merge(1, 0, dx*dx + dy*dy < rl2 .and. j > i)
          end do
        case (row_append)
          call append_near(i, nl%cell_start(c), k_hi, nl%cell_part, x, y, x(i), y(i), rl2, &
               row, count)
        case default
          do k = nl%cell_start(c), k_hi
            j = nl%cell_part(k)
            dx = x(i) - x(j)
            dy = y(i) - y(j)
            keep = dx*dx + dy*dy < rl2 .and. j > i
            slot = at + min(count, expected - 1)
            nl%nbr(slot) = merge(j, nl%nbr(slot), keep)
            count = count + merge(1, 0, keep)
          end do
        end select
      end do
    end subroutine scan_row
  end subroutine nlist_build

  !> nlist_build's serial scan (row_append) of the candidates j = cell_part(k_lo..k_hi) of
  !> particle i at (xi, yi): each stored at row(1 + count), count advanced when j > i and
  !> j lies within rlist (r^2 < rl2). A routine of its own, not inside scan_row: there GCC 12
  !> reloads the bases of x, y and row at every candidate (a store to row might alias them).
  pure subroutine append_near(i, k_lo, k_hi, cell_part, x, y, xi, yi, rl2, row, count)
    integer, intent(in) :: i, k_lo, k_hi, cell_part(*)
    real(dp), intent(in) :: x(*), y(*), xi, yi, rl2
    integer, intent(inout) :: row(*), count
    integer :: k, j
    real(dp) :: dx, dy
    do k = k_lo, k_hi
      j = cell_part(k)
      dx = xi - x(j)
      dy = yi - y(j)
      row(1 + count) = j
      count = count + merge(1, 0, dx*dx + dy*dy < rl2)*merge(1, 0, j > i)
    end do
  end subroutine append_near

end module neighbours
