//! The key layout of the link, all under `harvest/v1/<robot>/`:
//!
//! | key | what |
//! |---|---|
//! | `state/arm1`, `state/arm2`, `state/vacuum` | states, 20 Hz latest-only (JSON) |
//! | `state/mode`, `state/estop`, `state/health` | on change plus a slow beat (JSON) |
//! | `detections` | the newest detections, <= 10 Hz (JSON) |
//! | `events` | every harvest event (JSON) |
//! | `camera/jpeg` | downscaled JPEG, <= 2 Hz, only while a subscriber matches |
//! | `summary` | the fleet line: mode, e-stop, harvested, success, alarms, console (JSON) |
//! | `alive` | the robot's liveliness token |
//! | `command` | queryable: an operator command, answered with the executive's answer |
//! | `estop` | queryable: the emergency stop's own lane (no token needed) |
//!
//! The version segment lets a later layout live beside this one.

use crate::robot_name::RobotName;

/// The prefix of every key.
pub const ROOT: &str = "harvest/v1";

/// Every robot's liveliness token (a station's liveliness subscriber).
pub const ALL_ALIVE: &str = "harvest/v1/*/alive";
/// Every robot's fleet summary.
pub const ALL_SUMMARIES: &str = "harvest/v1/*/summary";

/// Suffix of the command queryable.
pub const COMMAND: &str = "command";
/// Suffix of the emergency stop's queryable.
pub const ESTOP: &str = "estop";
/// Suffix of the liveliness token.
pub const ALIVE: &str = "alive";
/// Suffix of the fleet summary.
pub const SUMMARY: &str = "summary";

/// The keys of one robot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RobotKeys {
    robot: RobotName,
    prefix: String,
}

impl RobotKeys {
    pub fn new(robot: RobotName) -> Self {
        let prefix = format!("{ROOT}/{robot}");
        Self { robot, prefix }
    }

    pub fn robot(&self) -> &RobotName {
        &self.robot
    }

    /// `harvest/v1/<robot>/<suffix>`.
    pub fn key(&self, suffix: &str) -> String {
        format!("{}/{suffix}", self.prefix)
    }

    /// Every key of this robot (`harvest/v1/<robot>/**`).
    pub fn all(&self) -> String {
        format!("{}/**", self.prefix)
    }

    pub fn command(&self) -> String {
        self.key(COMMAND)
    }

    pub fn estop(&self) -> String {
        self.key(ESTOP)
    }

    pub fn alive(&self) -> String {
        self.key(ALIVE)
    }

    pub fn summary(&self) -> String {
        self.key(SUMMARY)
    }

    /// What follows `harvest/v1/<robot>/` in `key`, if `key` is one of this robot's.
    pub fn suffix_of<'k>(&self, key: &'k str) -> Option<&'k str> {
        key.strip_prefix(self.prefix.as_str())?.strip_prefix('/')
    }
}

/// The robot and the suffix of a concrete key `harvest/v1/<robot>/<suffix>`.
pub fn split_key(key: &str) -> Option<(RobotName, &str)> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let (robot, suffix) = rest.split_once('/')?;
    Some((RobotName::parse(robot).ok()?, suffix))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_round_trip() {
        let keys = RobotKeys::new(RobotName::parse("r1").expect("name"));
        assert_eq!(keys.command(), "harvest/v1/r1/command");
        assert_eq!(keys.alive(), "harvest/v1/r1/alive");
        assert_eq!(
            keys.suffix_of("harvest/v1/r1/state/arm1"),
            Some("state/arm1")
        );
        assert_eq!(keys.suffix_of("harvest/v1/r12/state/arm1"), None);
        let (robot, suffix) = split_key("harvest/v1/r1/summary").expect("split");
        assert_eq!((robot.as_str(), suffix), ("r1", "summary"));
        assert!(split_key("harvest/v2/r1/summary").is_none());
        assert!(split_key("harvest/v1/R1/summary").is_none());
    }
}
