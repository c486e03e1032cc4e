!> Piston schedule (thesis Algorithm 2.1) as a pure function of time, so that
!> a run is reproducible from (scene, step) alone.
!>
!> Phases: 1 relaxation with exponential descent h_start -> h0,
!>         2 constant-speed compression h0 -> hf, 3 hold at hf,
!>         4 expansion hf -> h0, 5 final relaxation at h0.
!> Piston 'fixed' stays at h_start (phase 0); 'none' has no piston (phase 0).
!> Piston 'free' (thesis §5.3): held at h_start while the bed relaxes (phase 1),
!> then released from rest. nudge = 0 (the thesis' Figs. 5.10, 5.12): the fall
!> itself is the record (phase 6 for t_record). nudge > 0: the fall lasts until
!> the engine finds the bed settled (piston speed below settle_speed and bed
!> kinetic energy per particle below settle_ekin, both for settle_hold), at most
!> t_settle; then the piston is lifted by `nudge` and released again (phase 7)
!> for t_record. Its height is then state; the nudge step is engine state
!> (piston state nudge_step), so phase 7 is set by the engine, not here.
module protocol
  use kinds, only: dp, i8
  use scene, only: scene_t
  use model, only: model_t, piston_prescribed, piston_none, piston_free
  implicit none
  private

  public :: protocol_t, protocol_build, piston_at, phase_names

  character(len=*), parameter :: phase_names(0:7) = [character(len=8) :: &
       'steady', 'relax', 'compress', 'hold', 'expand', 'final', 'fall', 'free']

  type :: protocol_t
    integer :: mode = piston_prescribed
    real(dp) :: h_start = 0, h0 = 0, hf = 0, speed = 0, rate = 5
    real(dp) :: t_relax = 0, t_comp = 0, t_hold = 0, t_exp = 0, t_final = 0
    real(dp) :: t_settle = 0, t_record = 0, nudge = 0   !< free piston [T], [T], [D1]
    real(dp) :: settle_speed = 0, settle_ekin = 0, settle_hold = 0  !< [D1/T], [m1 g D1], [T]
    integer(i8) :: record_steps = 0  !< free piston: steps recorded after the nudge
    real(dp) :: t_total = 0          !< [T]
    integer(i8) :: n_steps = 0       !< steps to run
  end type protocol_t

contains

  !> hf from phi_final: phi = (pi/4) sum_i D_i^2 / (W hf), or from the
  !> mono-disperse reference height (thesis eq. 4.23 generalised to r species):
  !> hf = hf_reference sum_k f_k (D_k/D1)^2, with the nominal number fractions f_k.
  subroutine protocol_build(sc, m, area_particles, p)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: m
    real(dp), intent(in) :: area_particles   !< sum of particle areas [D1^2]
    type(protocol_t), intent(out) :: p
    p%mode = m%piston_mode
    p%h_start = sc%h_start
    if (p%h_start < 0) p%h_start = sc%height
    if (m%piston_mode == piston_prescribed) then
      p%h0 = sc%h0
      if (p%h0 < 0) p%h0 = p%h_start
      p%hf = sc%hf
      if (sc%phi_final > 0) p%hf = area_particles/(sc%width*sc%phi_final)
      if (sc%hf_reference > 0) p%hf = sc%hf_reference*area_factor(sc)
      p%speed = sc%piston_speed
      p%rate = sc%relax_rate
      p%t_relax = sc%t_relax
      p%t_comp = (p%h0 - p%hf)/p%speed
      p%t_hold = sc%t_hold
      p%t_exp = 0
      if (sc%expand) p%t_exp = p%t_comp
      p%t_final = sc%t_final
      p%t_total = p%t_relax + p%t_comp + p%t_hold + p%t_exp + p%t_final
    else if (m%piston_mode == piston_free) then
      p%h0 = p%h_start; p%hf = p%h_start
      p%t_relax = sc%t_relax
      p%t_settle = sc%t_settle
      p%t_record = sc%t_record
      p%nudge = sc%nudge
      p%settle_speed = sc%settle_speed
      p%settle_ekin = sc%settle_ekin
      p%settle_hold = sc%settle_hold
      p%record_steps = nint(p%t_record/sc%dt, i8)
      if (p%nudge > 0) then   ! upper bound: the engine shortens it once the bed has settled
        p%t_total = p%t_relax + p%t_settle + p%t_record
      else
        p%t_total = p%t_relax + p%t_record
      end if
    else
      p%h0 = p%h_start; p%hf = p%h_start
      p%t_total = sc%t_end
    end if
    p%n_steps = max(1_i8, nint(p%t_total/sc%dt, i8))
  end subroutine protocol_build

  !> sum_k f_k (D_k/D1)^2 with the nominal fractions (mix_ratio for 2 species).
  pure real(dp) function area_factor(sc) result(a)
    type(scene_t), intent(in) :: sc
    select case (sc%n_species)
    case (1)
      a = 1
    case (2)
      a = (1 - sc%mix_ratio) + sc%mix_ratio*sc%species_diameter(2)**2
    case default
      a = sum(sc%species_fraction(1:sc%n_species)*sc%species_diameter(1:sc%n_species)**2)
    end select
  end function area_factor

  !> Piston height [D1] and phase at time t [T] (free piston: 1 held, else 6;
  !> the engine turns 6 into 7 from the nudge step on).
  pure subroutine piston_at(p, t, h, phase)
    type(protocol_t), intent(in) :: p
    real(dp), intent(in) :: t
    real(dp), intent(out) :: h
    integer, intent(out) :: phase
    real(dp) :: s
    if (p%mode == piston_free) then
      h = p%h_start                  ! only meaningful while held (phase 1)
      phase = 1
      if (t >= p%t_relax) phase = 6
      return
    end if
    if (p%mode /= piston_prescribed) then
      h = p%h_start
      if (p%mode == piston_none) h = huge(1.0_dp)
      phase = 0
      return
    end if
    s = t
    if (s < p%t_relax) then
      phase = 1
      h = p%h_start - (p%h_start - p%h0)*(exp(p%rate*s/p%t_relax) - 1.0_dp) &
           /(exp(p%rate) - 1.0_dp)
      return
    end if
    s = s - p%t_relax
    if (s < p%t_comp) then
      phase = 2
      h = p%h0 - p%speed*s
      return
    end if
    s = s - p%t_comp
    if (s < p%t_hold) then
      phase = 3
      h = p%hf
      return
    end if
    s = s - p%t_hold
    if (s < p%t_exp) then
      phase = 4
      h = p%hf + p%speed*s
      return
    end if
    phase = 5
    h = p%h0
    if (p%t_exp <= 0) h = p%hf
  end subroutine piston_at

end module protocol
