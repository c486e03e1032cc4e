!> Prototype, not part of the engine: a 4 x 4 cluster-pair pass for the bed's dipole law (2D),
!> GROMACS-nbnxm style, measured against the engine's list kernels in bench/RESULTS.md 38.
!> Clusters: columns of width sqrt(4/rho) in x, sorted by y, 4 consecutive disks per cluster
!> (padding lanes far away); cluster pairs whose bounding boxes are within r_c + 1 (skin 1);
!> the pass: per i-cluster two 8-lane halves (i 1-2 and i 3-4 against the j cluster tiled twice),
!> the law exact (one division, one root per lane), the reactions on j in tiled 8-lane
!> accumulators folded after the pass. Positions: the grid's jittered square lattice (spacing
!> 1.6 D1, density 0.39 D1^-2). Checked against all pairs (N <= 5000).
!>
!>   gfortran -O3 -march=native -ffree-line-length-none bench/prototypes/cluster_pairs.f90 -o /tmp/cp
!>   /tmp/cp N R_CUT PASSES [JITTER]   # e.g. /tmp/cp 2000 3 300; /tmp/cp 100000 7 20
!> JITTER [D1]: each disk uniform in a square of that side around its lattice site (default
!> 1.6 = the whole lattice cell: disordered; 0.6 is the engine's start lattice, whose 2 x 2
!> blocks make unusually compact clusters).
module clu
  use iso_fortran_env, only: dp => real64, i8 => int64
  implicit none
  integer, parameter :: cm = 4
contains
  ! build clusters: columns of width w, sorted by y, groups of cm; perm(cm, ncl) (0 = pad)
  subroutine build_clusters(n, x, y, w, ncl, perm, ccol)
    integer, intent(in) :: n
    real(dp), intent(in) :: x(n), y(n), w
    integer, intent(out) :: ncl
    integer, allocatable, intent(out) :: perm(:,:), ccol(:)
    integer :: ncol, i, c, k, p, q
    integer, allocatable :: col(:), cnt(:), st(:), idx(:)
    real(dp) :: x0
    x0 = minval(x)
    allocate(col(n))
    col = int((x - x0)/w) + 1
    ncol = maxval(col)
    allocate(cnt(ncol), st(ncol+1), idx(n))
    cnt = 0
    do i = 1, n; cnt(col(i)) = cnt(col(i)) + 1; end do
    st(1) = 1
    do c = 1, ncol; st(c+1) = st(c) + cnt(c); end do
    cnt = 0
    do i = 1, n
      idx(st(col(i)) + cnt(col(i))) = i; cnt(col(i)) = cnt(col(i)) + 1
    end do
    ! sort each column by y (insertion sort; columns short-ish)
    do c = 1, ncol
      do p = st(c)+1, st(c+1)-1
        q = p; k = idx(p)
        do while (q > st(c))
          if (y(idx(q-1)) <= y(k)) exit
          idx(q) = idx(q-1); q = q - 1
        end do
        idx(q) = k
      end do
    end do
    ncl = 0
    do c = 1, ncol; ncl = ncl + (st(c+1)-st(c)+cm-1)/cm; end do
    allocate(perm(cm, ncl), ccol(ncl))
    perm = 0; ncl = 0
    do c = 1, ncol
      do p = st(c), st(c+1)-1, cm
        ncl = ncl + 1; ccol(ncl) = c
        do k = 0, min(cm, st(c+1)-p) - 1
          perm(k+1, ncl) = idx(p+k)
        end do
      end do
    end do
  end subroutine

  subroutine build_pairs(ncl, xc, yc, rl, w, ccol, cstart, clist, npairs)
    integer, intent(in) :: ncl, ccol(ncl)
    real(dp), intent(in) :: xc(cm,ncl), yc(cm,ncl), rl, w   !< list radius, column width [D1]
    integer, allocatable, intent(out) :: cstart(:), clist(:)
    integer, intent(out) :: npairs
    real(dp) :: lo(2,ncl), hi(2,ncl), dx, dy
    integer :: a, b, cap
    integer, allocatable :: t(:)
    do a = 1, ncl
      lo(1,a) = minval(xc(:,a), mask=xc(:,a) < 1e7_dp); hi(1,a) = maxval(xc(:,a), mask=xc(:,a) < 1e7_dp)
      lo(2,a) = minval(yc(:,a), mask=xc(:,a) < 1e7_dp); hi(2,a) = maxval(yc(:,a), mask=xc(:,a) < 1e7_dp)
    end do
    cap = ncl*64
    allocate(cstart(ncl+1), clist(cap))
    npairs = 0
    do a = 1, ncl
      cstart(a) = npairs + 1
      do b = a, ncl   ! naive scan (prototype): columns ordered, break when column too far
        dx = max(0.0_dp, lo(1,b) - hi(1,a), lo(1,a) - hi(1,b))
        if (dx >= rl) then
          if (ccol(b) > ccol(a) + ceiling(rl/w) + 1) exit   ! every later column is beyond r_l
          cycle
        end if
        dy = max(0.0_dp, lo(2,b) - hi(2,a), lo(2,a) - hi(2,b))
        if (dx*dx + dy*dy < rl*rl) then
          npairs = npairs + 1
          if (npairs > cap) then
            allocate(t(2*cap)); t(1:cap) = clist; call move_alloc(t, clist); cap = 2*cap
          end if
          clist(npairs) = b
        end if
      end do
    end do
    cstart(ncl+1) = npairs + 1
  end subroutine

  ! 4 x 4 cluster pairs as two 8-lane halves: lane l = jj + 4 (ii' - 1), ii' = 1, 2 in the
  ! half (i = ii' or ii' + 2); j tiled twice per cluster (xt(8, ncl)); reactions on j in tiled
  ! 8-lane accumulators (ft), folded after the pass
  subroutine kernel(ncl, xc, yc, mc, xt, yt, mt, cstart, clist, rc2, shift4, fxc, fyc, ftx, fty)
    integer, intent(in) :: ncl, cstart(ncl+1), clist(*)
    real(dp), intent(in) :: xc(cm,ncl), yc(cm,ncl), mc(cm,ncl), rc2, shift4
    real(dp), intent(in) :: xt(8,ncl), yt(8,ncl), mt(8,ncl)
    real(dp), intent(inout) :: fxc(cm,ncl), fyc(cm,ncl), ftx(8,ncl), fty(8,ncl)
    integer :: a, b, p, l
    real(dp), dimension(8) :: gx, gy, xa1, ya1, ma1, xa2, ya2, ma2, fx1, fy1, fx2, fy2, up1, up2
    real(dp) :: dx1, dy1, r21, k1, dx2, dy2, r22, k2, q1, q2, s1, s2, c1, c2
    do l = 1, 8
      up1(l) = merge(1.0_dp, 0.0_dp, mod(l-1, 4) + 1 > (l-1)/4 + 1)
      up2(l) = merge(1.0_dp, 0.0_dp, mod(l-1, 4) + 1 > (l-1)/4 + 3)
    end do
    ftx = 0; fty = 0
    do a = 1, ncl
      do l = 1, 8
        xa1(l) = xc((l-1)/4 + 1, a); ya1(l) = yc((l-1)/4 + 1, a); ma1(l) = mc((l-1)/4 + 1, a)
        xa2(l) = xc((l-1)/4 + 3, a); ya2(l) = yc((l-1)/4 + 3, a); ma2(l) = mc((l-1)/4 + 3, a)
      end do
      fx1 = 0; fy1 = 0; fx2 = 0; fy2 = 0
      p = cstart(a)
      if (p < cstart(a+1)) then   ! the self pair (listed first)
        b = a
        do l = 1, 8
          dx1 = xa1(l) - xt(l,b); dy1 = ya1(l) - yt(l,b)
          dx2 = xa2(l) - xt(l,b); dy2 = ya2(l) - yt(l,b)
          r21 = merge(dx1*dx1 + dy1*dy1, 1.0_dp, up1(l) > 0)
          r22 = merge(dx2*dx2 + dy2*dy2, 1.0_dp, up2(l) > 0)
          k1 = merge(up1(l), 0.0_dp, r21 < rc2); k2 = merge(up2(l), 0.0_dp, r22 < rc2)
          q1 = 1/r21; s1 = sqrt(q1); q2 = 1/r22; s2 = sqrt(q2)
          c1 = k1*ma1(l)*mt(l,b)*(q1*q1*s1 - shift4*s1)
          c2 = k2*ma2(l)*mt(l,b)*(q2*q2*s2 - shift4*s2)
          fx1(l) = fx1(l) + c1*dx1; fy1(l) = fy1(l) + c1*dy1
          fx2(l) = fx2(l) + c2*dx2; fy2(l) = fy2(l) + c2*dy2
          gx(l) = c1*dx1 + c2*dx2; gy(l) = c1*dy1 + c2*dy2
        end do
        ftx(:,b) = ftx(:,b) - gx; fty(:,b) = fty(:,b) - gy
        p = p + 1
      end if
      call irow(cstart(a+1) - p, clist(p), ncl, xa1, ya1, ma1, xa2, ya2, ma2, xt, yt, mt, rc2, shift4, fx1, fy1, fx2, fy2, ftx, fty)
      fxc(1,a) = fxc(1,a) + sum(fx1(1:4)); fxc(2,a) = fxc(2,a) + sum(fx1(5:8))
      fxc(3,a) = fxc(3,a) + sum(fx2(1:4)); fxc(4,a) = fxc(4,a) + sum(fx2(5:8))
      fyc(1,a) = fyc(1,a) + sum(fy1(1:4)); fyc(2,a) = fyc(2,a) + sum(fy1(5:8))
      fyc(3,a) = fyc(3,a) + sum(fy2(1:4)); fyc(4,a) = fyc(4,a) + sum(fy2(5:8))
    end do
    do a = 1, ncl
      fxc(:,a) = fxc(:,a) + ftx(1:4,a) + ftx(5:8,a)
      fyc(:,a) = fyc(:,a) + fty(1:4,a) + fty(5:8,a)
    end do
  end subroutine
  subroutine irow(nb, blist, ncl, xa1, ya1, ma1, xa2, ya2, ma2, xt, yt, mt, rc2, shift4, fx1, fy1, fx2, fy2, ftx, fty)
    integer, intent(in) :: nb, blist(*), ncl
    real(dp), intent(in) :: xa1(8), ya1(8), ma1(8), xa2(8), ya2(8), ma2(8), xt(8,ncl), yt(8,ncl), mt(8,ncl), rc2, shift4
    real(dp), intent(inout) :: fx1(8), fy1(8), fx2(8), fy2(8), ftx(8,ncl), fty(8,ncl)
    real(dp) :: dx1, dy1, r21, k1, dx2, dy2, r22, k2, q1, q2, s1, s2, c1, c2
    integer :: l, p, b
    do p = 1, nb
        b = blist(p)
        do l = 1, 8
          dx1 = xa1(l) - xt(l,b); dy1 = ya1(l) - yt(l,b)
          dx2 = xa2(l) - xt(l,b); dy2 = ya2(l) - yt(l,b)
          r21 = dx1*dx1 + dy1*dy1; r22 = dx2*dx2 + dy2*dy2
          k1 = merge(1.0_dp, 0.0_dp, r21 < rc2); k2 = merge(1.0_dp, 0.0_dp, r22 < rc2)
          q1 = 1/r21; s1 = sqrt(q1); q2 = 1/r22; s2 = sqrt(q2)
          c1 = k1*ma1(l)*mt(l,b)*(q1*q1*s1 - shift4*s1)
          c2 = k2*ma2(l)*mt(l,b)*(q2*q2*s2 - shift4*s2)
          fx1(l) = fx1(l) + c1*dx1; fy1(l) = fy1(l) + c1*dy1
          fx2(l) = fx2(l) + c2*dx2; fy2(l) = fy2(l) + c2*dy2
          ftx(l,b) = ftx(l,b) - (c1*dx1 + c2*dx2); fty(l,b) = fty(l,b) - (c1*dy1 + c2*dy2)
        end do
    end do
  end subroutine
end module

program proto
  use clu
  implicit none
  integer :: n, m, i, ncl, npairs, k, nrep, a, ii, j
  real(dp), allocatable :: x(:), y(:), fx(:), fy(:), xc(:,:), yc(:,:), mc(:,:), fxc(:,:), fyc(:,:), rx(:), ry(:), xt(:,:), yt(:,:), mt(:,:), ftx(:,:), fty(:,:)
  integer, allocatable :: perm(:,:), ccol(:), cstart(:), clist(:)
  real(dp) :: jit, rc, rl, w, u(2), t0, t1, dx, dy, r2, f, err, fmax
  character(len=32) :: arg
  call get_command_argument(1, arg); read(arg,*) n
  call get_command_argument(2, arg); read(arg,*) rc
  call get_command_argument(3, arg); read(arg,*) nrep
  jit = 1.6_dp   ! uniform within each lattice cell (disordered); 0.6: the engine's start lattice
  if (command_argument_count() > 3) then
    call get_command_argument(4, arg); read(arg,*) jit
  end if
  rl = rc + 1
  call random_seed(size=k)
  call random_seed(put=[(12345 + 7*i, i = 1, k)])
  m = ceiling(sqrt(real(n)))
  allocate(x(n), y(n), fx(n), fy(n))
  do i = 1, n
    call random_number(u)
    x(i) = 1 + 1.6_dp*mod(i-1, m) + jit*(u(1)-0.5_dp)
    y(i) = 1 + 1.6_dp*((i-1)/m) + jit*(u(2)-0.5_dp)
  end do
  w = sqrt(cm*2.56_dp)
  call cpu_time(t0)
  call build_clusters(n, x, y, w, ncl, perm, ccol)
  allocate(xc(cm,ncl), yc(cm,ncl), mc(cm,ncl), fxc(cm,ncl), fyc(cm,ncl))
  do a = 1, ncl
    do ii = 1, cm
      if (perm(ii,a) > 0) then
        xc(ii,a) = x(perm(ii,a)); yc(ii,a) = y(perm(ii,a)); mc(ii,a) = 1
      else
        xc(ii,a) = 1e8_dp + 4*rl*(cm*a+ii); yc(ii,a) = 1e8_dp; mc(ii,a) = 0
      end if
    end do
  end do
  call build_pairs(ncl, xc, yc, rl, w, ccol, cstart, clist, npairs)
  allocate(xt(8,ncl), yt(8,ncl), mt(8,ncl), ftx(8,ncl), fty(8,ncl))
  do a = 1, ncl
    xt(1:4,a) = xc(:,a); xt(5:8,a) = xc(:,a); yt(1:4,a) = yc(:,a); yt(5:8,a) = yc(:,a)
    mt(1:4,a) = mc(:,a); mt(5:8,a) = mc(:,a)
  end do
  call cpu_time(t1)
  print '(a,i0,a,f8.3,a,i0,a,f6.2,a,f8.2,a)', 'N ', n, ' rc ', rc, ' clusters ', ncl, ' cl-pairs/cluster ', &
       real(npairs)/ncl, ' build ', (t1-t0)/n*1e9, ' ns/particle'
  call cpu_time(t0)
  do k = 1, nrep
    fxc = 0; fyc = 0
    call kernel(ncl, xc, yc, mc, xt, yt, mt, cstart, clist, rc*rc, rc**(-4), fxc, fyc, ftx, fty)
  end do
  call cpu_time(t1)
  print '(a,f8.2,a,f6.2)', 'kernel ', (t1-t0)/nrep/n*1e9, ' ns/particle/pass; lanes/particle ', real(npairs)*cm*cm/n
  if (n <= 5000) then
    allocate(rx(n), ry(n)); rx = 0; ry = 0
    do i = 1, n
      do j = i+1, n
        dx = x(i)-x(j); dy = y(i)-y(j); r2 = dx*dx+dy*dy
        if (r2 < rc*rc) then
          f = r2**(-2.5_dp) - rc**(-4)/sqrt(r2)
          rx(i) = rx(i)+f*dx; ry(i) = ry(i)+f*dy; rx(j) = rx(j)-f*dx; ry(j) = ry(j)-f*dy
        end if
      end do
    end do
    err = 0; fmax = maxval(abs(rx))
    do a = 1, ncl
      do ii = 1, cm
        if (perm(ii,a) > 0) err = max(err, abs(fxc(ii,a)-rx(perm(ii,a))), abs(fyc(ii,a)-ry(perm(ii,a))))
      end do
    end do
    print *, 'max abs err / max |f| ', err/fmax, ' / rms |f| ', err/sqrt(sum(rx**2 + ry**2)/n)
  end if
end program
