//! What leaves the robot, at what pace and with what priority: one table, [`OUTBOUND`]. A
//! channel not in it never leaves; raw camera frames (`camera/rgbd`) and arm commands
//! (`armN/command`, `armN/manual`, `armN/target`, the hardware layer) are deliberately absent.
//! Every publisher drops on congestion: a slow link never blocks the bridge, and the bridge
//! never blocks a publisher onboard (it reads the stack's channels like any subscriber, whose
//! overflow is safe).

/// The link's priorities, highest first (the process maps them to Zenoh's).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum LinkPriority {
    /// The emergency stop.
    RealTime,
    /// Mode, health, the fleet summary, command answers.
    InteractiveHigh,
    /// Arm and vacuum states.
    Data,
    /// Detections and harvest events.
    DataLow,
    /// The camera image.
    Background,
}

/// How often a channel's messages go out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    /// The newest value at most `max_hz` times a second.
    Latest { max_hz: f64 },
    /// On change, and unchanged every `beat_ms`.
    OnChange { beat_ms: u64 },
    /// Every message.
    Every,
    /// The newest frame at most `max_hz` times a second, only while a subscriber matches.
    WhileWatched { max_hz: f64 },
}

/// What a message on the link carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Outbound {
    /// `armN/state`, N = 1 or 2.
    ArmState(u8),
    /// `vacuum/state`.
    VacuumState,
    /// `operator/mode`.
    Mode,
    /// `safety/emergency_stop`.
    EmergencyStop,
    /// `system/health`, one message per process heartbeat that changed.
    Health,
    /// `perception/apples`.
    Detections,
    /// `harvest/events`.
    HarvestEvents,
    /// `camera/rgbd`, downscaled and JPEG-encoded.
    Camera,
    /// The fleet line built from mode, health and events.
    Summary,
}

/// One channel on the link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChannelPolicy {
    pub what: Outbound,
    /// Suffix under `harvest/v1/<robot>/`.
    pub key_suffix: &'static str,
    pub pace: Pace,
    pub priority: LinkPriority,
    /// Sent at once, never batched with others.
    pub express: bool,
}

/// Beat of the on-change channels, ms.
pub const SLOW_BEAT_MS: u64 = 1000;

/// The table (module docs).
pub const OUTBOUND: [ChannelPolicy; 9] = [
    ChannelPolicy {
        what: Outbound::EmergencyStop,
        key_suffix: "state/estop",
        pace: Pace::OnChange {
            beat_ms: SLOW_BEAT_MS,
        },
        priority: LinkPriority::RealTime,
        express: true,
    },
    ChannelPolicy {
        what: Outbound::Mode,
        key_suffix: "state/mode",
        pace: Pace::OnChange {
            beat_ms: SLOW_BEAT_MS,
        },
        priority: LinkPriority::InteractiveHigh,
        express: true,
    },
    ChannelPolicy {
        what: Outbound::Health,
        key_suffix: "state/health",
        pace: Pace::OnChange {
            beat_ms: SLOW_BEAT_MS,
        },
        priority: LinkPriority::InteractiveHigh,
        express: false,
    },
    ChannelPolicy {
        what: Outbound::Summary,
        key_suffix: "summary",
        pace: Pace::OnChange {
            beat_ms: SLOW_BEAT_MS,
        },
        priority: LinkPriority::InteractiveHigh,
        express: false,
    },
    ChannelPolicy {
        what: Outbound::ArmState(1),
        key_suffix: "state/arm1",
        pace: Pace::Latest { max_hz: 20.0 },
        priority: LinkPriority::Data,
        express: false,
    },
    ChannelPolicy {
        what: Outbound::ArmState(2),
        key_suffix: "state/arm2",
        pace: Pace::Latest { max_hz: 20.0 },
        priority: LinkPriority::Data,
        express: false,
    },
    ChannelPolicy {
        what: Outbound::VacuumState,
        key_suffix: "state/vacuum",
        pace: Pace::Latest { max_hz: 20.0 },
        priority: LinkPriority::Data,
        express: false,
    },
    ChannelPolicy {
        what: Outbound::Detections,
        key_suffix: "detections",
        pace: Pace::Latest { max_hz: 10.0 },
        priority: LinkPriority::DataLow,
        express: false,
    },
    ChannelPolicy {
        what: Outbound::HarvestEvents,
        key_suffix: "events",
        pace: Pace::Every,
        priority: LinkPriority::DataLow,
        express: false,
    },
];

/// The camera's entry (its own thread; see [`crate::camera_image`]).
pub const CAMERA: ChannelPolicy = ChannelPolicy {
    what: Outbound::Camera,
    key_suffix: "camera/jpeg",
    pace: Pace::WhileWatched { max_hz: 2.0 },
    priority: LinkPriority::Background,
    express: false,
};

/// The policy of `what`.
pub fn policy(what: Outbound) -> ChannelPolicy {
    OUTBOUND
        .iter()
        .copied()
        .find(|policy| policy.what == what)
        .unwrap_or(CAMERA)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_estop_is_first_and_nothing_outruns_its_limit() {
        let estop = policy(Outbound::EmergencyStop);
        assert_eq!(estop.priority, LinkPriority::RealTime);
        assert!(estop.express);
        assert!(
            OUTBOUND
                .iter()
                .filter(|p| p.what != Outbound::EmergencyStop)
                .all(|p| p.priority > LinkPriority::RealTime)
        );
        for p in OUTBOUND.iter().chain([&CAMERA]) {
            match p.pace {
                Pace::Latest { max_hz } => assert!(max_hz <= 20.0, "{:?}", p.what),
                Pace::WhileWatched { max_hz } => assert!(max_hz <= 2.0),
                _ => {}
            }
        }
        assert_eq!(
            policy(Outbound::Detections).pace,
            Pace::Latest { max_hz: 10.0 }
        );
        // Suffixes are distinct and none is a queryable's.
        let mut suffixes: Vec<_> = OUTBOUND
            .iter()
            .chain([&CAMERA])
            .map(|p| p.key_suffix)
            .collect();
        suffixes.sort_unstable();
        suffixes.dedup();
        assert_eq!(suffixes.len(), OUTBOUND.len() + 1);
        assert!(!suffixes.contains(&crate::keys::COMMAND));
        assert!(!suffixes.contains(&crate::keys::ESTOP));
    }
}
