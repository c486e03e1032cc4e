!> Neighbour strategies feeding the one pair kernel:
!>   all_pairs  O(N^2) reference, no cut-off;
!>   cells      pairs within r_c found from a cell grid at every step (no skin);
!>   verlet     half Verlet list of radius r_c + skin built from cells, rebuilt
!>              when the largest displacement since the last build exceeds skin/2
!>              (never at a fixed interval), particles re-sorted by cell at rebuilds;
!>   thesis     the thesis' variant (ch. 5.1): every listed pair within r_v = r_c + skin
!>              is used (no cut-off test), same rebuild rule.
!> Walls are never truncated.
module neighbours
  use kinds, only: dp, i8
  use parallel, only: par_min_loop
  use state, only: state_t, state_permute
  use scene_input, only: int_str, json_real
  implicit none
  private

  public :: nlist_t, nlist_setup, nlist_due, nlist_bin, nlist_build, nlist_refresh, nlist_owners
  public :: nlist_pruned, nlist_prune_holds, nlist_set_prune, nlist_prune_json
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
  !> The automatic margin of the pruned list (nlist_set_prune, a scene's prune_skin < 0): the
  !> candidates as fractions of the skin, the first period's margin (narrow: its many prunes
  !> measure the motion), and what a prune costs per listed pair (plus one per particle)
  !> against what a force pass costs per pruned pair (prune_rows ~2 ns a listed pair, rows_kept
  !> 3-5 ns a pruned pair, bench/RESULTS.md 42.3; with 0.5 the model's work per margin follows
  !> the measured step at N 2e3, r_c 3 and 4: section 43)
  integer, parameter :: n_margins = 5
  real(dp), parameter :: margin_fractions(n_margins) = [0.05_dp, 0.1_dp, 0.15_dp, 0.25_dp, 0.4_dp]
  real(dp), parameter :: margin_start = 0.1_dp, prune_cost = 0.5_dp

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

  !> Before a force pass: rebuild the list when due, re-sorting the particles
  !> by cell first (memory locality; not for 'cells', whose grid is rebuilt every step).
  !> With prune (a pruned list wanted for this pass, nl%prune > 0, verlet with check): the
  !> pruned list taken again when a particle moved more than nl%prune/2 since the last prune.
  !> The rebuild rule is the same (a displacement since the build above skin/2): while the
  !> pruned list holds, only the displacements since the prune are taken, and the list is
  !> kept when they bound those since the build below skin/2 (|r - r_build| <= |r - r_prune|
  !> + the largest displacement since the build at the prune); otherwise as without prune.
  subroutine nlist_refresh(nl, s, prune)
    type(nlist_t), intent(inout) :: nl
    type(state_t), intent(inout) :: s
    logical, intent(in), optional :: prune
    integer :: k
    logical :: want, keep, period
    real(dp) :: db2, dp2
    want = .false.
    if (present(prune)) want = prune
    want = want .and. nl%prune > 0 .and. nl%strategy == nb_verlet .and. nl%check
    if (want) nl%period_steps = nl%period_steps + 1
    keep = .false.   ! the pruned list holds
    if (want) then
      keep = nlist_prune_holds(nl, s%n, s%x, s%y, dp2)
      ! and the list: |r - r_build| <= |r - r_prune| + the largest one at the prune
      ! (margin: square roots of rounded squares; a near tie goes to the exact test)
      if (keep .and. sqrt(dp2) + nl%dprune <= 0.5_dp*nl%skin*(1 - 1.0e-12_dp)) return
    end if
    period = nl%valid   ! a build now ends a build period (not: the first, or after a reorder)
    if (.not. nl%valid .or. nl%strategy == nb_cells) then
      db2 = huge(1.0_dp)
    else
      db2 = max_shift2(s%n, s%x, s%y, nl%xref, nl%yref)
    end if
    if (db2 > (0.5_dp*nl%skin)**2) then
      call rebuild()
      db2 = 0
      keep = .false.
      if (want .and. nl%prune_auto) call nlist_margin(nl, s%n, s%x, s%y, period)
    else if (want .and. .not. keep) then
      nl%period_prunes = nl%period_prunes + 1
    end if
    if (want .and. .not. keep) call nlist_prune(nl, s%n, s%x, s%y, sqrt(db2))
  contains
    subroutine rebuild()
    call nlist_bin(nl, s%n, s%x, s%y)
    if (nl%strategy /= nb_cells) then
      call state_permute(s, nl%cell_part)
      ! now sorted by cell: binning again would give the same cell_start, and cell_part 1..n
      nl%cell_part = [(k, k = 1, s%n)]
    end if
    call nlist_build(nl, s%n, s%x, s%y)
    end subroutine rebuild
  end subroutine nlist_refresh

  !> Whether the pruned list holds at x, y: every particle within prune/2 (less a margin for
  !> the rounded squares) of its place at the last prune, and no build since (the list
  !> itself: nlist_due). dp2: the largest squared displacement since the prune [D1^2].
  logical function nlist_prune_holds(nl, n, x, y, dp2) result(holds)
    type(nlist_t), intent(in) :: nl
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    real(dp), intent(out), optional :: dp2
    real(dp) :: d2
    holds = .false.
    d2 = huge(1.0_dp)
    if (nl%pruned .and. nl%valid .and. nl%prune > 0) then
      d2 = max_shift2(n, x, y, nl%xpr, nl%ypr)
      holds = d2 <= (0.5_dp*nl%prune*(1 - 1.0e-9_dp))**2
    end if
    if (present(dp2)) dp2 = d2
  end function nlist_prune_holds

  !> The pruned list's margin from a scene's prune_skin [length]: 0 none, > 0 that margin, < 0
  !> automatic (nlist_margin: margin_start*skin until the first build period has been seen).
  subroutine nlist_set_prune(nl, prune_skin)
    type(nlist_t), intent(inout) :: nl
    real(dp), intent(in) :: prune_skin
    nl%prune_auto = prune_skin < 0
    nl%prune = prune_skin
    if (nl%prune_auto) nl%prune = margin_start*nl%skin
    nl%period_steps = 0
    nl%period_prunes = 0
    nl%margin_changes = 0
  end subroutine nlist_set_prune

  !> The automatic margin, chosen at a build from the list just built at x, y and the build
  !> period that ended: the one of the candidates p (margin_fractions of the skin) with the
  !> least work per period, S P(p) + prune_cost (pairs + n) M(p): P(p) the listed pairs within
  !> r_c + p now (what the force passes take), M(p) the prunes of a period (a prune comes when
  !> a particle moved p/2, a build when it moved skin/2). The period that ended had S force
  !> passes and m + 1 prunes at margin p0, so M(p0) = m + 1 and M(skin) = 1; between them and
  !> beyond, M(p) = (m + 1) (p0/p)^a with a = ln(m + 1)/ln(skin/p0) clipped to [1, 2]
  !> (ballistic 1 .. diffusive 2), and at least 1. Integer counts and step numbers only: the
  !> same choice for any thread count; the forces are the same bits at any margin anyway.
  subroutine nlist_margin(nl, n, x, y, period)
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    logical, intent(in) :: period   !< a build period ended (false: the first build, a restart)
    integer(i8) :: cnt(n_margins)
    real(dp) :: p(n_margins), r2c(n_margins), work(n_margins), r2, m1, a, s_len
    integer :: i, k, j, c
    s_len = real(nl%period_steps, dp)
    m1 = real(nl%period_prunes + 1, dp)
    nl%period_steps = 0
    nl%period_prunes = 0
    if (.not. period .or. s_len <= 0) return   ! no period seen: the margin stays
    p = margin_fractions*nl%skin
    r2c = (nl%rc + p)**2
    cnt = 0
    !$omp parallel do schedule(static) reduction(+: cnt) private(k, j, r2, c) &
    !$omp& if (n >= par_min_loop)
    do i = 1, n
      do k = nl%start(i), nl%start(i + 1) - 1
        j = nl%nbr(k)
        r2 = (x(i) - x(j))**2 + (y(i) - y(j))**2
        do c = 1, n_margins
          cnt(c) = cnt(c) + merge(1_i8, 0_i8, r2 < r2c(c))
        end do
      end do
    end do
    !$omp end parallel do
    a = 1
    if (m1 > 1) a = min(2.0_dp, max(1.0_dp, log(m1)/log(nl%skin/nl%prune)))
    work = s_len*real(cnt, dp) + prune_cost*real(nl%pairs + n, dp)*max(1.0_dp, m1*(nl%prune/p)**a)
    c = minloc(work, 1)
    if (p(c) /= nl%prune) nl%margin_changes = nl%margin_changes + 1
    nl%prune = p(c)
  end subroutine nlist_margin

  !> run.json's "pruned_list" member (a line, ending in a comma): the margin in use at the end
  !> [length], whether it was chosen automatically, how often the choice changed, the prunes,
  !> the pairs in the pruned list at the end.
  function nlist_prune_json(nl) result(text)
    type(nlist_t), intent(in) :: nl
    character(len=:), allocatable :: text
    text = '  "pruned_list": {"margin": '//json_real(nl%prune)//', "automatic": '// &
         trim(merge('true ', 'false', nl%prune_auto))//', "margin_changes": '// &
         int_str(nl%margin_changes)//', "prunes": '//int_str(nl%prunes)//', "pairs": '// &
         int_str(nl%ppairs)//'},'//achar(10)
  end function nlist_prune_json

  !> Whether a force pass may use the pruned list now (see nlist_t).
  pure logical function nlist_pruned(nl) result(yes)
    type(nlist_t), intent(in) :: nl
    yes = nl%pruned .and. nl%valid
  end function nlist_pruned

  !> The pruned list from the list at positions x, y (see nlist_t); d_build: the largest
  !> displacement since the build now [D1]. Rows in order, each row's pairs in the list's
  !> order; no branch on the distance (every pair stored at the next free slot, which
  !> advances when it is kept). On the threads from par_min_loop particles: blocks of rows
  !> into their own part of the list's length, then moved together.
  subroutine nlist_prune(nl, n, x, y, d_build)
    !$ use omp_lib, only: omp_get_max_threads, omp_get_thread_num
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), d_build
    integer :: nt, t, lo, hi, kept(0:64), at(0:64), i, k, total
    if (allocated(nl%pstart)) then
      if (size(nl%pstart) /= n + 1) deallocate(nl%pstart, nl%xpr, nl%ypr)
    end if
    if (.not. allocated(nl%pstart)) allocate(nl%pstart(n + 1), nl%xpr(n), nl%ypr(n))
    total = nl%start(n + 1) - 1
    if (allocated(nl%pnbr)) then
      if (size(nl%pnbr) < total + 1) deallocate(nl%pnbr, nl%pown)
    end if
    if (.not. allocated(nl%pnbr)) allocate(nl%pnbr(size(nl%nbr) + 1), nl%pown(size(nl%nbr) + 1))
    nt = 1
    !$ if (n >= par_min_loop) nt = min(64, omp_get_max_threads())
    if (nt == 1) then
      call prune_rows(1, n, 1, nl%pnbr, nl%pown, kept(1))
    else
      if (allocated(nl%ptmp)) then
        if (size(nl%ptmp, 1) < total + 1) deallocate(nl%ptmp)
      end if
      if (.not. allocated(nl%ptmp)) allocate(nl%ptmp(size(nl%nbr) + 1, 2))
      !$omp parallel num_threads(nt) default(shared) private(t, lo, hi, i, k)
      t = 1
      !$ t = omp_get_thread_num() + 1
      lo = int(int(n, i8)*(t - 1)/nt) + 1
      hi = int(int(n, i8)*t/nt)
      call prune_rows(lo, hi, nl%start(lo), nl%ptmp(:, 1), nl%ptmp(:, 2), kept(t))
      !$omp barrier
      !$omp single
      at(0) = 0
      do k = 1, nt
        at(k) = at(k - 1) + kept(k)
      end do
      !$omp end single
      ! block t's rows: its pstart(lo:hi) counted from start(lo); moved to follow block t - 1
      do i = lo, hi
        nl%pstart(i) = nl%pstart(i) - nl%start(lo) + at(t - 1) + 1
      end do
      do k = 1, kept(t)
        nl%pnbr(at(t - 1) + k) = nl%ptmp(nl%start(lo) + k - 1, 1)
        nl%pown(at(t - 1) + k) = nl%ptmp(nl%start(lo) + k - 1, 2)
      end do
      !$omp end parallel
    end if
    nl%pstart(n + 1) = sum(kept(1:nt)) + 1
    nl%ppairs = nl%pstart(n + 1) - 1
    nl%xpr = x
    nl%ypr = y
    nl%dprune = d_build
    nl%pruned = .true.
    nl%prunes = nl%prunes + 1
  contains
    !> Rows lo..hi into out, from position first on: pstart(i), kept the pairs written.
    subroutine prune_rows(lo, hi, first, out, outo, kept)
      integer, intent(in) :: lo, hi, first
      integer, intent(inout) :: out(:), outo(:)
      integer, intent(out) :: kept
      integer :: i, k, j, slot
      real(dp) :: rp2, xi, yi, dx, dy
      rp2 = (nl%rc + nl%prune)**2
      slot = first
      do i = lo, hi
        nl%pstart(i) = slot
        xi = x(i); yi = y(i)
        do k = nl%start(i), nl%start(i + 1) - 1
          j = nl%nbr(k)
          dx = xi - x(j)
          dy = yi - y(j)
          out(slot) = j
          outo(slot) = i
          slot = slot + merge(1, 0, dx*dx + dy*dy < rp2)
        end do
      end do
      kept = slot - first
    end subroutine prune_rows
  end subroutine nlist_prune

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
