!> The registry of methods: which type runs which scene kind. Adding a kind
!> = one line here (and its folder, scene groups and pyorch subpackage).
module methods
  use errors, only: status_t, set_error, exit_bad_input
  use method, only: method_t
  use scene_input, only: kind_len, read_kind
  use bed_method, only: bed_t
  use oscillator, only: oscillator_t
  use edmd_dla, only: dla_t
  use dsmc_rods, only: rods_t
  use lj_box, only: lj_box_t
  implicit none
  private

  public :: method_for_scene, method_for_kind, kind_names

  character(len=*), parameter :: kind_names = "'magnet_bed' | 'oscillator' | 'dla' | 'rods' | 'lj_box'"

contains

  !> Allocate the method that runs the scene at `path` (from its &scene kind).
  subroutine method_for_scene(path, m, kind, st)
    character(len=*), intent(in) :: path
    class(method_t), allocatable, intent(out) :: m
    character(len=kind_len), intent(out) :: kind
    type(status_t), intent(inout) :: st
    call read_kind(path, kind_names, kind, st)
    if (st%code /= 0) return
    call method_for_kind(kind, m, st, path)
  end subroutine method_for_scene

  !> Allocate the method of scene kind `kind` (refused naming the kinds when unknown).
  subroutine method_for_kind(kind, m, st, path)
    character(len=*), intent(in) :: kind
    class(method_t), allocatable, intent(out) :: m
    type(status_t), intent(inout) :: st
    character(len=*), intent(in), optional :: path
    character(len=:), allocatable :: where
    where = 'kind'
    if (present(path)) where = trim(path)//': &scene kind'
    select case (trim(kind))
    case ('magnet_bed')
      allocate(bed_t :: m)
    case ('oscillator')
      allocate(oscillator_t :: m)
    case ('dla')
      allocate(dla_t :: m)
    case ('rods')
      allocate(rods_t :: m)
    case ('lj_box')
      allocate(lj_box_t :: m)
    case default
      call set_error(st, exit_bad_input, where//" = '"//trim(kind)// &
           "': allowed "//kind_names)
    end select
  end subroutine method_for_kind

end module methods
