//! The picking cycle's phase ([`CyclePhase`]) and the phase an arm reports in `ArmState::phase`
//! (`harvest_ipc::payloads::ArmPhase`), both ways, in one place.
//!
//! The reported phases are the cycle's plus `Stopped`, which is the arm node's state under the
//! emergency stop, not a phase of the cycle; the cycle's `Attach` is reported as `AttachDetach`.
//! The vacuum coordination's view of the same arm is a third type,
//! `harvest_robot_model::CoordinationPhase`.

use harvest_ipc::payloads::ArmPhase as ReportedPhase;

use crate::picking_cycle::CyclePhase;

/// The phase an arm whose picking cycle is in `phase` reports in `ArmState::phase`.
pub const fn reported_phase(phase: CyclePhase) -> ReportedPhase {
    match phase {
        CyclePhase::Idle => ReportedPhase::Idle,
        CyclePhase::Approach => ReportedPhase::Approach,
        CyclePhase::Attach => ReportedPhase::AttachDetach,
        CyclePhase::Retract => ReportedPhase::Retract,
        CyclePhase::Release => ReportedPhase::Release,
    }
}

/// The cycle phase of an arm that reports `reported` (`None`: an unknown code), as the
/// clearance check sees the other arm: idle, stopped (braked where it is) or unknown count as
/// idle, where only its current pose counts.
pub const fn cycle_phase_of_reported(reported: Option<ReportedPhase>) -> CyclePhase {
    match reported {
        Some(ReportedPhase::Approach) => CyclePhase::Approach,
        Some(ReportedPhase::AttachDetach) => CyclePhase::Attach,
        Some(ReportedPhase::Retract) => CyclePhase::Retract,
        Some(ReportedPhase::Release) => CyclePhase::Release,
        Some(ReportedPhase::Idle | ReportedPhase::Stopped) | None => CyclePhase::Idle,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_cycle_phase_survives_the_round_trip_through_its_report() {
        for phase in [
            CyclePhase::Idle,
            CyclePhase::Approach,
            CyclePhase::Attach,
            CyclePhase::Retract,
            CyclePhase::Release,
        ] {
            assert_eq!(cycle_phase_of_reported(Some(reported_phase(phase))), phase);
        }
        assert_eq!(
            cycle_phase_of_reported(Some(ReportedPhase::Stopped)),
            CyclePhase::Idle
        );
        assert_eq!(cycle_phase_of_reported(None), CyclePhase::Idle);
    }
}
