//! One robot's line on the fleet page, built on the robot from its channels: the mode, the
//! e-stop, apples harvested and the success rate so far (from `harvest/events` through
//! `harvest_log`, as the supervisor and the console count them), the alarms (the e-stop, a
//! process failed or degraded, a device error), and the address of its console.

use std::collections::BTreeMap;

use harvest_ipc::payloads::{
    DeviceErrorCode, EmergencyStop, HarvestEvent, OperatorModeCode, OperatorModeState,
    ProcessHealth, ProcessRunState,
};
use harvest_log::HarvestLog;
use serde::{Deserialize, Serialize};

/// The line (JSON on `harvest/v1/<robot>/summary`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FleetSummary {
    pub robot: String,
    /// `idle`, `harvesting`, `paused`, `manual`, `estopped`; `unknown` before the executive is
    /// heard.
    pub mode: String,
    pub estop_engaged: bool,
    pub apples_harvested: u32,
    pub apples_attempted: u32,
    /// Harvested / attempted apples, none before the first attempt.
    pub success_rate: Option<f64>,
    /// What needs a person, in a few words each.
    pub alarms: Vec<String>,
    /// The robot's console, as configured on the robot (none: not served beyond the robot).
    pub console_url: Option<String>,
}

/// Collects what the line needs.
#[derive(Debug, Clone)]
pub struct SummaryBuilder {
    robot: String,
    console_url: Option<String>,
    mode: Option<OperatorModeState>,
    estop: Option<(bool, String)>,
    processes: BTreeMap<String, (u8, u8)>,
    log: HarvestLog,
}

impl SummaryBuilder {
    pub fn new(robot: &str, console_url: Option<String>, origin_ns: u64) -> Self {
        Self {
            robot: robot.to_owned(),
            console_url,
            mode: None,
            estop: None,
            processes: BTreeMap::new(),
            log: HarvestLog::new(origin_ns),
        }
    }

    pub fn on_mode(&mut self, mode: &OperatorModeState) {
        self.mode = Some(*mode);
    }

    pub fn on_estop(&mut self, stop: &EmergencyStop) {
        self.estop = Some((stop.engaged != 0, stop.reason.as_str().to_owned()));
    }

    pub fn on_health(&mut self, health: &ProcessHealth) {
        self.processes.insert(
            health.process_name.as_str().to_owned(),
            (health.run_state.raw(), health.last_device_error.raw()),
        );
    }

    pub fn on_event(&mut self, event: &HarvestEvent) {
        let _ = self.log.on_event(event);
    }

    /// The line now.
    pub fn summary(&self) -> FleetSummary {
        let stats = self.log.summary();
        let estop_engaged = self
            .estop
            .as_ref()
            .map(|(on, _)| *on)
            .unwrap_or_else(|| self.mode.is_some_and(|m| m.emergency_stop_engaged != 0));
        let mut alarms = Vec::new();
        if estop_engaged {
            let reason = self
                .estop
                .as_ref()
                .map_or("", |(_, reason)| reason.as_str());
            alarms.push(
                format!("e-stop engaged: {reason}")
                    .trim_end_matches([' ', ':'])
                    .to_owned(),
            );
        }
        for (name, (state, device_error)) in &self.processes {
            match harvest_ipc::WireCode::<ProcessRunState>::from_raw(*state).get() {
                Ok(ProcessRunState::Failed) => alarms.push(format!("{name} failed")),
                Ok(ProcessRunState::Degraded) => alarms.push(format!("{name} degraded")),
                _ => {}
            }
            match harvest_ipc::WireCode::<DeviceErrorCode>::from_raw(*device_error).get() {
                Ok(DeviceErrorCode::None) => {}
                Ok(kind) => alarms.push(format!("{name}: device {}", kind.name())),
                Err(unknown) => alarms.push(format!("{name}: device error code {}", unknown.code)),
            }
        }
        FleetSummary {
            robot: self.robot.clone(),
            mode: self
                .mode
                .and_then(|m| m.mode_code())
                .map_or("unknown", OperatorModeCode::name)
                .to_owned(),
            estop_engaged,
            apples_harvested: stats.apples_harvested,
            apples_attempted: stats.apples_attempted,
            success_rate: (stats.apples_attempted > 0)
                .then(|| f64::from(stats.apples_harvested) / f64::from(stats.apples_attempted)),
            alarms,
            console_url: self.console_url.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::FixedString;

    #[test]
    fn the_line_names_the_alarms() {
        let mut builder = SummaryBuilder::new("r1", Some("http://10.0.0.5:8080".to_owned()), 0);
        let empty = builder.summary();
        assert_eq!(empty.mode, "unknown");
        assert_eq!(empty.success_rate, None);
        assert!(empty.alarms.is_empty());
        let mut mode = OperatorModeState {
            mode: OperatorModeCode::Harvesting as u8,
            ..OperatorModeState::default()
        };
        builder.on_mode(&mode);
        let stop = EmergencyStop {
            engaged: 1,
            reason: FixedString::new("operator"),
            ..EmergencyStop::default()
        };
        builder.on_estop(&stop);
        let mut health = ProcessHealth {
            process_name: FixedString::new("lidar"),
            ..ProcessHealth::default()
        };
        health.run_state.set(ProcessRunState::Failed);
        builder.on_health(&health);
        mode.emergency_stop_engaged = 1;
        builder.on_mode(&mode);
        let line = builder.summary();
        assert_eq!(line.mode, "harvesting");
        assert!(line.estop_engaged);
        assert_eq!(line.alarms, ["e-stop engaged: operator", "lidar failed"]);
        let back: FleetSummary =
            serde_json::from_str(&serde_json::to_string(&line).expect("json")).expect("back");
        assert_eq!(back, line);
    }
}
