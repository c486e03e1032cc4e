!> The upkeep of a neighbour list (neighbours' nlist_t) before each force pass: the rebuild
!> when due (nlist_refresh, the particles re-sorted by cell), and the pruned list (GROMACS'
!> dynamic pruning: the listed pairs within r_c + a margin, taken again when a particle moved
!> half the margin) with its margin fixed or chosen at every build (nlist_margin). The forces
!> over the pruned list are the same bits as over the whole list at any margin (see nlist_t).
module nlist_upkeep
  use kinds, only: dp, i8
  use parallel, only: par_min_loop
  use state, only: state_t, state_permute
  use scene_input, only: int_str, json_real
  use neighbours, only: nlist_t, nlist_bin, nlist_build, max_shift2, nb_verlet, nb_cells
  implicit none
  private

  public :: nlist_refresh, nlist_pruned, nlist_prune_holds, nlist_set_prune, nlist_prune_json
  public :: nlist_force_start, nlist_force_done

  !> The automatic margin of the pruned list (nlist_set_prune, a scene's prune_skin < 0): the
  !> candidates as fractions of the skin, the first period's margin (narrow: its many prunes
  !> measure the motion), and what a prune costs per listed pair (plus one per particle)
  !> against what a force pass costs per pruned pair until both have been timed (prune_rows
  !> ~2 ns a listed pair, rows_kept 3-5 ns a pruned pair, bench/RESULTS.md 42.3; the ratio
  !> differs by kernel: the standard cycle's friction and far field make its pairs dearer,
  !> section 43)
  integer, parameter :: n_margins = 5
  real(dp), parameter :: margin_fractions(n_margins) = [0.05_dp, 0.1_dp, 0.15_dp, 0.25_dp, 0.4_dp]
  real(dp), parameter :: margin_start = 0.1_dp, prune_cost = 0.5_dp

contains

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
    integer(i8) :: t0, t1
    want = .false.
    if (present(prune)) want = prune
    want = want .and. nl%prune > 0 .and. nl%strategy == nb_verlet .and. nl%check
    if (want) then
      nl%period_steps = nl%period_steps + 1
      nl%margin_sum = nl%margin_sum + nl%prune
      nl%margin_passes = nl%margin_passes + 1
    end if
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
    if (want .and. .not. keep) then
      if (nl%prune_auto) call system_clock(t0)
      call nlist_prune(nl, s%n, s%x, s%y, sqrt(db2))
      if (nl%prune_auto) then
        call system_clock(t1)
        nl%prune_ticks = nl%prune_ticks + (t1 - t0)
        nl%prune_work = nl%prune_work + (nl%start(s%n + 1) - 1) + s%n
      end if
    end if
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
    nl%prune_ticks = 0
    nl%prune_work = 0
    nl%force_ticks = 0
    nl%force_pairs = 0
    nl%margin_sum = 0
    nl%margin_passes = 0
  end subroutine nlist_set_prune

  !> The automatic margin, chosen at a build from the list just built at x, y and the build
  !> period that ended: the one of the candidates p (margin_fractions of the skin) with the
  !> least work per period, S P(p) + c (pairs + n) M(p): P(p) the listed pairs within r_c + p
  !> now (what the force passes take), M(p) the prunes of a period (a prune comes when a
  !> particle moved p/2, a build when it moved skin/2), c the measured cost of a prune per
  !> listed pair and particle over that of a force pass per pruned pair (the run's totals so
  !> far; prune_cost until both were timed). The period that ended had S force passes and
  !> m + 1 prunes at margin p0, so M(p0) = m + 1 and M(skin) = 1; between them and beyond,
  !> M(p) = (m + 1) (p0/p)^a with a = ln(m + 1)/ln(skin/p0) clipped to [1, 2] (ballistic 1 ..
  !> diffusive 2), and at least 1. c is timed, so the choices may differ between runs (as
  !> GROMACS' tuning of its PME grid does); the forces are the same bits at any margin.
  subroutine nlist_margin(nl, n, x, y, period)
    type(nlist_t), intent(inout) :: nl
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n)
    logical, intent(in) :: period   !< a build period ended (false: the first build, a restart)
    integer(i8) :: cnt(n_margins)
    real(dp) :: p(n_margins), r2c(n_margins), work(n_margins), r2, m1, a, s_len, ratio
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
    ratio = cost_ratio(nl)   ! a prune's cost per unit of work / a force pass's per pruned pair
    if (ratio <= 0) ratio = prune_cost
    work = s_len*real(cnt, dp) + ratio*real(nl%pairs + n, dp)*max(1.0_dp, m1*(nl%prune/p)**a)
    c = minloc(work, 1)
    if (p(c) /= nl%prune) nl%margin_changes = nl%margin_changes + 1
    nl%prune = p(c)
  end subroutine nlist_margin

  !> Around a force pass over the pruned list (automatic margin only, else nothing): its clock
  !> ticks and pruned pairs, for nlist_margin's cost ratio.
  subroutine nlist_force_start(nl)
    type(nlist_t), intent(inout) :: nl
    if (nl%prune_auto) call system_clock(nl%force_t0)
  end subroutine nlist_force_start

  subroutine nlist_force_done(nl)
    type(nlist_t), intent(inout) :: nl
    integer(i8) :: t1
    if (.not. nl%prune_auto) return
    call system_clock(t1)
    nl%force_ticks = nl%force_ticks + (t1 - nl%force_t0)
    nl%force_pairs = nl%force_pairs + nl%ppairs
  end subroutine nlist_force_done

  !> run.json's "pruned_list" member (a line, ending in a comma): the margin in use at the end
  !> and its mean over the force passes that took the pruned list [length], whether it was
  !> chosen automatically, the measured cost ratio c of nlist_margin
  !> (0: not timed), how often the choice changed, the prunes, the pairs in the pruned list at
  !> the end.
  function nlist_prune_json(nl) result(text)
    type(nlist_t), intent(in) :: nl
    character(len=:), allocatable :: text
    real(dp) :: ratio
    ratio = cost_ratio(nl)
    text = '  "pruned_list": {"margin": '//json_real(nl%prune)//', "margin_mean": '// &
         json_real(nl%margin_sum/real(max(1_i8, nl%margin_passes), dp))//', "automatic": '// &
         trim(merge('true ', 'false', nl%prune_auto))//', "cost_ratio": '//json_real(ratio)// &
         ', "margin_changes": '// &
         int_str(nl%margin_changes)//', "prunes": '//int_str(nl%prunes)//', "pairs": '// &
         int_str(nl%ppairs)//'},'//achar(10)
  end function nlist_prune_json

  !> The run's measured cost of a prune per listed pair and particle over that of a force pass
  !> per pruned pair (clock ticks of both so far), 0 until both were timed.
  pure real(dp) function cost_ratio(nl) result(ratio)
    type(nlist_t), intent(in) :: nl
    ratio = 0
    if (nl%prune_ticks > 0 .and. nl%prune_work > 0 .and. nl%force_ticks > 0 .and. &
        nl%force_pairs > 0) ratio = (real(nl%prune_ticks, dp)/real(nl%prune_work, dp))/ &
        (real(nl%force_ticks, dp)/real(nl%force_pairs, dp))
  end function cost_ratio

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

end module nlist_upkeep
