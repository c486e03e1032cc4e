!> The one simulation instance behind the f2py door (kept out of the f2py
!> sources: f2py does not wrap derived types).
module api_state
  use engine, only: sim_t
  implicit none
  private
  public :: the_sim
  type(sim_t), save :: the_sim
end module api_state
