//! What the executive process must do after a decision.

/// One thing to carry out, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Publish `safety/emergency_stop` engaged with this reason.
    EngageEmergencyStop {
        /// Why, in words.
        reason: String,
    },
    /// Publish `safety/emergency_stop` released.
    ReleaseEmergencyStop,
    /// Send arm `arm` (1 or 2) to `goal` (`armN/manual`, move to).
    ArmMoveTo {
        /// Arm number.
        arm: u8,
        /// `[D m, theta rad, phi rad, twist rad]`, inside the limits.
        goal: [f64; 4],
        /// Share of the rate limits.
        speed_fraction: f64,
        /// The operator request behind it.
        request_id: u64,
    },
    /// Stop arm `arm`'s manual motion (`armN/manual`, stop).
    ArmStop {
        /// Arm number.
        arm: u8,
    },
    /// Move the platform stages to `[in_out, up_down]`, m.
    PlatformMoveTo {
        /// Targets, m.
        target_m: [f64; 2],
    },
    /// Stop the platform stages where they are.
    PlatformStop,
    /// End the harvest at the row's current stop and advance (the row's stop cycle,
    /// `harvest_field::StopCycle::next_stop`, may still refuse: the ack then says why).
    NextStop,
}
