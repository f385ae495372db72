//! The live stack's failed attempts in the categories of [dual-arm Table 3], as far as the
//! stack can tell them apart without ground truth.
//!
//! The stack sees a failed attempt only through the vacuum: no seal within the attach window
//! (`no_attachment`), or a seal lost before the drop-off (`apple_lost`). A cup that never sealed
//! may have met a bad surface (sealing) or missed an apple that perception placed wrong
//! (localization, occlusion, cluster, false detection); a lost seal may be a stem that held
//! (detachment) or a branch that knocked the apple off (interference). `harvest eval row` splits
//! them with the simulator's ground truth; here each category names what it may hold.

use harvest_ipc::payloads::HarvestCause;

/// Table 3 category of a failed attempt's cause, as the live stack can name it.
pub fn table3_category(cause: HarvestCause) -> &'static str {
    match cause {
        HarvestCause::NoAttachment => "sealing or perception (no seal)",
        HarvestCause::AppleLost => "detachment or interference (seal lost)",
        HarvestCause::EmergencyStop => "emergency stop",
        _ => "other",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vacuum_failures_name_the_table_3_categories_they_may_hold() {
        assert_eq!(
            table3_category(HarvestCause::NoAttachment),
            "sealing or perception (no seal)"
        );
        assert_eq!(
            table3_category(HarvestCause::AppleLost),
            "detachment or interference (seal lost)"
        );
        assert_eq!(table3_category(HarvestCause::ApproachTimeout), "other");
    }
}
