!> Working precision and physical constants shared by every engine module.
module kinds
  use, intrinsic :: iso_fortran_env, only: real64, int64
  implicit none
  private

  public :: dp, i8, pi, mu0

  integer, parameter :: dp = real64   !< working real kind (IEEE double)
  integer, parameter :: i8 = int64    !< 64-bit integer kind (step counters)
  real(dp), parameter :: pi = 3.141592653589793238462643383279502884_dp
  real(dp), parameter :: mu0 = 4.0e-7_dp*pi  !< vacuum permeability [H/m]
end module kinds
