!> Tabulated pair laws (&integration pair_eval = 'table'): a force factor f(u) of u = r^2 as
!> cubic Hermite pieces on segments of u, evaluated with no square root and no division.
!>
!> The segments are those of the bit pattern of the double u: segment k holds the u whose
!> bits shifted right by 52 - bits equal base + k (exponent and the top `bits` bits of the
!> mantissa), so its lower end u_k is u with the low mantissa bits cleared, and there are
!> 2^bits segments per octave of u, of relative width 2^-bits .. 2^-(bits+1). For the power
!> laws of the pair forces this keeps the relative error uniform over the whole range; the
!> index is one shift, the piece f = c1 + d (c2 + d (c3 + d c4)), d = u - u_k, four
!> gathered coefficients from one row of the table.
!>
!> Each piece matches f and df/du at both its ends (C1 across segments). This module builds
!> the pieces; the evaluation (table_one, table_pair), the error measured against the exact
!> law and the choice of `bits` live in pair_forces, next to the exact kernels and the pair
!> loops (so that the loops inline them and the measured routine is the one they use). u is
!> clamped into [lo2, hi2] (and the index into the table) so no value of u reads outside it.
!>
!> The same type describes every pair evaluation of a run (pair_eval_t, `eval`): exact (the
!> reference, the default), table, single (the law's arithmetic in single precision from the
!> double r^2, the sums in double) or rsqrt (r^-1 from a bit-level guess refined by three
!> Newton steps: multiplies and adds only). Each cheaper evaluation's error is measured at load
!> over the run's range of r against the exact law (max_err, rms_err) and printed in run.json.
module pair_table
  use kinds, only: dp, i8
  use scene_input, only: int_str, json_real
  implicit none
  private

  public :: pair_table_t, law_i, table_pieces, segment_bounds, max_bits, table_json
  public :: eval_exact, eval_table, eval_single, eval_rsqrt, eval_names, eval_code

  integer, parameter :: max_bits = 12   !< finest table: 4096 segments per octave of r^2
  !> pair evaluations (&integration / &steric pair_eval), in the order of eval_names
  integer, parameter :: eval_exact = 1, eval_table = 2, eval_single = 3, eval_rsqrt = 4
  character(len=*), parameter :: eval_names = 'exact|table|single|rsqrt'

  type :: pair_table_t
    integer :: eval = eval_exact !< the evaluation (eval_*); the fields below: not exact
    logical :: on = .false.      !< a table (eval = eval_table)
    integer :: bits = 0          !< 2^bits segments per octave of u = r^2
    integer :: shift = 52        !< 52 - bits
    integer(i8) :: base = 0      !< segment k: the bits of u shifted right by shift = base + k
    integer :: n = 0             !< segments
    integer :: nq = 1            !< quantities tabulated (1: force factor; 2: and r^-3)
    real(dp) :: lo2 = 0, hi2 = 0 !< range of u [length^2]; u is clamped into it
    !> (4 nq, n): row k holds quantity q's piece in c(4q-3 : 4q, k)
    real(dp), allocatable :: c(:, :)
    real(dp) :: max_err = 0      !< largest relative error measured over the range [1]
    real(dp) :: rms_err = 0      !< rms relative error over the samples (uniform in log u) [1]
    real(dp) :: requested = 0    !< the requested largest relative error [1]
  end type pair_table_t

  abstract interface
    !> The exact law at u [length^2]: values v(q), derivatives dv(q) = dv/du and the scale
    !> mag(q) its relative error is measured against (the sum of its terms' magnitudes).
    subroutine law_i(u, v, dv, mag)
      import :: dp
      real(dp), intent(in) :: u
      real(dp), intent(out) :: v(:), dv(:), mag(:)
    end subroutine law_i
  end interface

contains

  !> Lower and upper end of segment k of table t [length^2].
  pure subroutine segment_bounds(t, k, u0, u1)
    type(pair_table_t), intent(in) :: t
    integer, intent(in) :: k
    real(dp), intent(out) :: u0, u1
    u0 = transfer(ishft(t%base + k, t%shift), 1.0_dp)
    u1 = transfer(ishft(t%base + k + 1, t%shift), 1.0_dp)
  end subroutine segment_bounds

  !> The segments of u in [lo2, hi2] (0 < lo2 < hi2) at 2^bits per octave and the Hermite
  !> piece of each quantity of `law` on each (values and derivatives at both ends).
  subroutine table_pieces(law, nq, lo2, hi2, bits, t)
    procedure(law_i) :: law
    integer, intent(in) :: nq, bits
    real(dp), intent(in) :: lo2, hi2
    type(pair_table_t), intent(out) :: t
    integer :: k, q
    real(dp) :: u0, u1, h, s
    real(dp) :: v0(nq), d0(nq), v1(nq), d1(nq), mg(nq)
    t%on = .true.
    t%eval = eval_table
    t%bits = bits
    t%shift = 52 - bits
    t%nq = nq
    t%lo2 = lo2
    t%hi2 = hi2
    t%base = ishft(transfer(lo2, 0_i8), -t%shift) - 1
    t%n = int(ishft(transfer(hi2, 0_i8), -t%shift) - t%base)
    allocate(t%c(4*nq, t%n))
    do k = 1, t%n
      call segment_bounds(t, k, u0, u1)
      h = u1 - u0
      call law(u0, v0, d0, mg)
      call law(u1, v1, d1, mg)
      do q = 1, nq
        s = (v1(q) - v0(q))/h
        t%c(4*q - 3, k) = v0(q)
        t%c(4*q - 2, k) = d0(q)
        t%c(4*q - 1, k) = (3*s - 2*d0(q) - d1(q))/h
        t%c(4*q, k) = (d0(q) + d1(q) - 2*s)/(h*h)
      end do
    end do
  end subroutine table_pieces

  !> The code (eval_*) of a pair_eval name (one of eval_names; 0 for another).
  pure integer function eval_code(name) result(code)
    character(len=*), intent(in) :: name
    select case (trim(name))
    case ('exact'); code = eval_exact
    case ('table'); code = eval_table
    case ('single'); code = eval_single
    case ('rsqrt'); code = eval_rsqrt
    case default; code = 0
    end select
  end function eval_code

  !> run.json members of the pair evaluation (each line '  "key": value,' and a newline):
  !> pair_eval, its largest and typical (rms) relative force error measured at load (0 for
  !> exact: the reference), for a table its requested error, size and range of r, for single
  !> and rsqrt the requested error and the range of r the error was measured over.
  function table_json(t) result(text)
    type(pair_table_t), intent(in) :: t
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = achar(10)
    character(len=*), parameter :: names(4) = [character(len=6) :: 'exact', 'table', 'single', &
         'rsqrt']
    if (t%eval == eval_exact) then
      text = '  "pair_eval": "exact",'//nl//'  "pair_max_rel_error": 0,'//nl// &
           '  "pair_typical_rel_error": 0,'//nl
      return
    end if
    text = '  "pair_eval": "'//trim(names(t%eval))//'",'//nl// &
         '  "pair_max_rel_error": '//json_real(t%max_err)//','//nl// &
         '  "pair_typical_rel_error": '//json_real(t%rms_err)//','//nl
    if (t%eval == eval_table) then
      text = text//'  "pair_table": {"requested_rel_error": '//json_real(t%requested)// &
           ', "segments_per_octave": '//int_str(int(2**t%bits, i8))//', "segments": '// &
           int_str(int(t%n, i8))// &
           ', "r_range": ['//json_real(sqrt(t%lo2))//', '//json_real(sqrt(t%hi2))//']},'//nl
    else
      text = text//'  "pair_error_measured": {"requested_rel_error": '//json_real(t%requested)// &
           ', "r_range": ['//json_real(sqrt(t%lo2))//', '//json_real(sqrt(t%hi2))//']},'//nl
    end if
  end function table_json

end module pair_table
