//! The status the page shows, built from the channels: the operator's mode, each arm (phase,
//! apple, harvested count, its tube in the robot frame from its joints and the kinematic
//! model), the vacuum (valves, pressures, attachment), the newest detections (with which arm
//! can reach each apple and which apple is an arm's target), the fruit statistics from
//! `harvest/events` (`harvest_log`), the processes' heartbeats (the supervisor's table:
//! state, restarts seen as a new pid, message rate) and an event log. Serialized once per
//! update into the JSON that `/api/status` serves.

use harvest_ipc::WireCode;
use std::collections::{BTreeMap, VecDeque};

use harvest_arm::node::{ArmNodeConfig, pick_reachable};
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase, ArmState, ArmTarget, DepthSourceCode, DeviceErrorCode, HarvestEvent,
    OperatorAck, OperatorCommandCode, OperatorModeCode, OperatorModeState, OperatorRefusalCode,
    ProcessHealth, VacuumState,
};
use harvest_log::HarvestLog;
use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::kinematics::{forward, yaw_pivot};
use harvest_robot_model::params::{ArmId, ArmParams};
use serde_json::{Value, json};

/// Lines kept in the event log.
const EVENT_LOG_LINES: usize = 80;
/// Distance within which a detection is an arm's target, m.
const TARGET_MATCH_M: f64 = 0.03;

#[derive(Debug, Clone)]
struct ProcessRow {
    latest: ProcessHealth,
    pids_seen: Vec<u32>,
    rate_hz: f64,
    rate_from: (u64, u64),
    heard_ns: u64,
}

/// Everything the status panel shows; see the module documentation.
#[derive(Debug, Clone)]
pub struct StatusBoard {
    origin_ns: u64,
    mode: Option<OperatorModeState>,
    arms: [Option<ArmState>; 2],
    targets: [Option<ArmTarget>; 2],
    vacuum: Option<VacuumState>,
    detections: Option<AppleDetections>,
    reachable: Vec<[bool; 2]>,
    harvest_log: HarvestLog,
    processes: BTreeMap<String, ProcessRow>,
    events: VecDeque<String>,
    arm_config: ArmNodeConfig,
}

/// The kind of a heartbeat's last device error (`timeout`, `disconnected`, ...), `None` without
/// one; an unknown code shows as `code N`.
fn device_error_name(code: WireCode<DeviceErrorCode>) -> Option<String> {
    match code.get() {
        Ok(DeviceErrorCode::None) => None,
        Ok(kind) => Some(kind.name().to_owned()),
        Err(unknown) => Some(format!("code {}", unknown.code)),
    }
}

fn phase_name(code: WireCode<ArmPhase>) -> String {
    code.get().map_or_else(
        |unknown| format!("code {}", unknown.code),
        |p| format!("{p:?}").to_lowercase(),
    )
}

fn finite(values: &[f64]) -> Value {
    if values.iter().all(|v| v.is_finite()) {
        json!(values)
    } else {
        Value::Null
    }
}

fn distance_m(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

impl StatusBoard {
    /// An empty board; times in the event log are relative to `origin_ns`.
    pub fn new(origin_ns: u64) -> Self {
        Self {
            origin_ns,
            mode: None,
            arms: [None; 2],
            targets: [None; 2],
            vacuum: None,
            detections: None,
            reachable: Vec::new(),
            harvest_log: HarvestLog::new(origin_ns),
            processes: BTreeMap::new(),
            events: VecDeque::with_capacity(EVENT_LOG_LINES),
            arm_config: ArmNodeConfig::default(),
        }
    }

    fn log(&mut self, line: String) {
        if self.events.len() == EVENT_LOG_LINES {
            self.events.pop_front();
        }
        self.events.push_back(line);
    }

    pub fn on_mode(&mut self, mode: &OperatorModeState) {
        let changed = self
            .mode
            .is_none_or(|old| old.last_change_ns != mode.last_change_ns);
        if changed {
            let t = mode.last_change_ns.saturating_sub(self.origin_ns) as f64 * 1e-9;
            let name = mode.mode_code().map_or("?", OperatorModeCode::name);
            self.log(format!(
                "{t:7.1} s  mode {name}: {}",
                mode.last_change_reason
            ));
        }
        self.mode = Some(*mode);
    }

    pub fn on_arm_state(&mut self, index: usize, state: &ArmState) {
        self.arms[index] = Some(*state);
    }

    pub fn on_arm_target(&mut self, index: usize, target: &ArmTarget) {
        self.targets[index] = Some(*target);
    }

    pub fn on_vacuum(&mut self, state: &VacuumState) {
        self.vacuum = Some(*state);
    }

    pub fn on_detections(&mut self, set: &AppleDetections) {
        self.reachable = set
            .apples
            .as_slice()
            .iter()
            .map(|apple| {
                [ArmId::Arm1, ArmId::Arm2].map(|arm| {
                    pick_reachable(
                        arm,
                        apple.position_in_robot_m,
                        apple.radius_m,
                        &self.arm_config,
                    )
                })
            })
            .collect();
        self.detections = Some(*set);
    }

    pub fn on_harvest_event(&mut self, event: &HarvestEvent) {
        if let Some(line) = self.harvest_log.on_event(event) {
            self.log(line);
        }
    }

    pub fn on_ack(&mut self, ack: &OperatorAck, now_ns: u64) {
        if ack.code == OperatorCommandCode::Heartbeat as u16 && ack.accepted != 0 {
            return;
        }
        let name = OperatorCommandCode::from_code(ack.code)
            .map_or_else(|| format!("code {}", ack.code), |c| c.name().to_owned());
        let t = now_ns.saturating_sub(self.origin_ns) as f64 * 1e-9;
        let verdict = if ack.accepted != 0 {
            "accepted"
        } else {
            "REFUSED"
        };
        self.log(format!("{t:7.1} s  {name} {verdict}: {}", ack.reason));
    }

    pub fn on_health(&mut self, beat: &ProcessHealth, now_ns: u64) {
        let name = beat.process_name.as_str().to_owned();
        let row = self.processes.entry(name).or_insert_with(|| ProcessRow {
            latest: *beat,
            pids_seen: Vec::new(),
            rate_hz: 0.0,
            rate_from: (now_ns, beat.main_channel_count),
            heard_ns: now_ns,
        });
        if !row.pids_seen.contains(&beat.pid) {
            row.pids_seen.push(beat.pid);
            row.rate_from = (now_ns, beat.main_channel_count);
        }
        let elapsed_ns = now_ns.saturating_sub(row.rate_from.0);
        if elapsed_ns >= 1_000_000_000 {
            row.rate_hz = beat.main_channel_count.saturating_sub(row.rate_from.1) as f64
                / (elapsed_ns as f64 * 1e-9);
            row.rate_from = (now_ns, beat.main_channel_count);
        }
        row.latest = *beat;
        row.heard_ns = now_ns;
    }

    fn mode_json(&self, now_ns: u64) -> Value {
        let Some(m) = self.mode else {
            return Value::Null;
        };
        json!({
            "name": m.mode_code().map(OperatorModeCode::name),
            "estop": m.emergency_stop_engaged != 0,
            "arms_enabled": [m.arms_enabled[0] != 0, m.arms_enabled[1] != 0],
            "controller": m.controller.as_str(),
            "controlling_session": m.controlling_session.to_string(),
            "last_change": m.last_change_reason.as_str(),
            "age_ms": now_ns.saturating_sub(m.header.capture_ns) / 1_000_000,
            "platform": {
                "present": m.platform_present != 0,
                "position_m": finite(&m.platform_position_m),
                "moving": m.platform_in_motion != 0,
            },
        })
    }

    fn arm_json(&self, index: usize, now_ns: u64) -> Value {
        let Some(state) = self.arms[index] else {
            return Value::Null;
        };
        let params = ArmParams::for_arm([ArmId::Arm1, ArmId::Arm2][index]);
        let q = JointPosition::from_array(state.joint_position);
        let (pivot, tip) = if q.is_finite() {
            (
                finite(&yaw_pivot(&params.links, &q)),
                finite(&forward(&params.links, &q)),
            )
        } else {
            (Value::Null, Value::Null)
        };
        let target = self.targets[index].filter(|t| t.apple_id != 0);
        json!({
            "number": index + 1,
            "phase": phase_name(state.phase),
            "apple_id": state.apple_id,
            "harvested": state.harvested_count,
            "holding": state.holding != 0,
            "target_apple_id": target.map(|t| t.apple_id),
            "target_m": target.map(|t| finite(&t.position_in_robot_m)),
            "joints": finite(&state.joint_position),
            "base_m": [params.links.x0_m, params.links.y0_m, params.links.z0_m],
            "pivot_m": pivot,
            "tip_m": tip,
            "age_ms": now_ns.saturating_sub(state.header.capture_ns) / 1_000_000,
        })
    }

    fn detections_json(&self) -> Value {
        let Some(set) = &self.detections else {
            return Value::Null;
        };
        let targets: Vec<(usize, [f64; 3])> = self
            .targets
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                t.filter(|t| t.apple_id != 0)
                    .map(|t| (i + 1, t.position_in_robot_m))
            })
            .collect();
        let apples: Vec<Value> = set
            .apples
            .as_slice()
            .iter()
            .enumerate()
            .map(|(k, apple)| {
                let target_of = targets
                    .iter()
                    .find(|(_, p)| distance_m(p, &apple.position_in_robot_m) < TARGET_MATCH_M)
                    .map(|(arm, _)| *arm);
                json!({
                    "id": apple.apple_id,
                    "box_px": apple.box_px,
                    "confidence": apple.confidence,
                    "depth_source": match apple.depth_source.get() {
                        Ok(DepthSourceCode::Tof) => "ToF",
                        Ok(DepthSourceCode::LidarFused) => "LiDAR",
                        Ok(DepthSourceCode::LaserLine) => "laser",
                        Err(_) => "?",
                    },
                    "method": apple.method.get().ok().map(|m| format!("{m:?}")),
                    "position_m": finite(&apple.position_in_robot_m),
                    "radius_m": apple.radius_m,
                    "reachable": self.reachable.get(k).copied().unwrap_or([false; 2]),
                    "target_of": target_of,
                })
            })
            .collect();
        json!({
            "frame_seq": set.source_frame_seq,
            "capture_ns": set.source_capture_ns,
            "processing_ms": set.processing_ns as f64 * 1e-6,
            "apples": apples,
        })
    }

    fn processes_json(&self, now_ns: u64) -> Vec<Value> {
        self.processes
            .iter()
            .map(|(name, row)| {
                let state = row
                    .latest
                    .run_state
                    .get()
                    .map_or_else(|_| "?".to_owned(), |s| format!("{s:?}").to_lowercase());
                json!({
                    "name": name,
                    "pid": row.latest.pid,
                    "state": state,
                    "messages": row.latest.main_channel_count,
                    "rate_hz": row.rate_hz,
                    "detail": row.latest.detail.as_str(),
                    "value": row.latest.detail_value,
                    "age_ms": now_ns.saturating_sub(row.heard_ns) / 1_000_000,
                    "restarts": row.pids_seen.len().saturating_sub(1),
                    "device_error": device_error_name(row.latest.last_device_error),
                })
            })
            .collect()
    }

    /// The JSON `/api/status` serves; `view` describes the newest camera view.
    pub fn to_json(&self, now_ns: u64, view: Value) -> Value {
        let recorder = self
            .processes_json(now_ns)
            .into_iter()
            .find(|row| row["name"] == "recorder");
        json!({
            "now_ns": now_ns,
            "mode": self.mode_json(now_ns),
            "arms": [self.arm_json(0, now_ns), self.arm_json(1, now_ns)],
            "vacuum": self.vacuum.map(|v| json!({
                "valve_open": v.valve_open,
                "in_transit": v.valve_in_transit,
                "pressure_mmh2o": v.pressure_mmh2o,
                "attachment": v.arm_attachment,
                "age_ms": now_ns.saturating_sub(v.header.capture_ns) / 1_000_000,
            })),
            "detections": self.detections_json(),
            "fruit": self.harvest_log.summary(),
            "processes": self.processes_json(now_ns),
            "recorder": recorder,
            "events": self.events,
            "view": view,
            "refusal_codes": OperatorRefusalCode::ALL.map(|c| format!("{c:?}")),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payloads::AppleDetection;
    use harvest_ipc::{FixedString, Header};

    #[test]
    fn the_board_shows_what_the_channels_carry() {
        let mut board = StatusBoard::new(0);
        let mode = OperatorModeState {
            header: Header {
                capture_ns: 1_000,
                ..Header::default()
            },
            mode: OperatorModeCode::Paused as u8,
            arms_enabled: [1, 0],
            last_change_ns: 5,
            last_change_reason: FixedString::new("paused by test"),
            ..OperatorModeState::default()
        };
        board.on_mode(&mode);
        let state = ArmState {
            arm_id: 1,
            phase: ArmPhase::Approach.into(),
            apple_id: 4,
            harvested_count: 3,
            joint_position: [0.0; 4],
            ..ArmState::default()
        };
        board.on_arm_state(0, &state);
        let target = ArmTarget {
            arm_id: 1,
            apple_id: 4,
            position_in_robot_m: [1.4, 0.1, 0.4],
            ..ArmTarget::default()
        };
        board.on_arm_target(0, &target);
        let mut set = AppleDetections::default();
        for (id, p) in [(10, [1.4, 0.1, 0.4]), (11, [9.0, 0.0, 0.0])] {
            let pushed = set.apples.push(AppleDetection {
                apple_id: id,
                position_in_robot_m: p,
                radius_m: 0.04,
                depth_source: DepthSourceCode::Tof.into(),
                confidence: 0.9,
                ..AppleDetection::default()
            });
            assert!(pushed.is_ok());
        }
        board.on_detections(&set);
        let value = board.to_json(2_000_000, Value::Null);
        assert_eq!(value["mode"]["name"], "paused");
        assert_eq!(value["mode"]["arms_enabled"], json!([true, false]));
        assert_eq!(value["arms"][0]["phase"], "approach");
        assert_eq!(value["arms"][0]["harvested"], 3);
        assert_eq!(value["arms"][1], Value::Null);
        let apples = value["detections"]["apples"].as_array().expect("apples");
        assert_eq!(apples[0]["target_of"], 1);
        assert_eq!(apples[0]["depth_source"], "ToF");
        assert_eq!(apples[1]["target_of"], Value::Null);
        assert_eq!(apples[1]["reachable"], json!([false, false]));
        let events = value["events"].as_array().expect("events");
        assert!(
            events[0]
                .as_str()
                .is_some_and(|e| e.contains("paused by test"))
        );
    }

    #[test]
    fn a_new_pid_counts_as_a_restart() {
        let mut board = StatusBoard::new(0);
        let mut beat = ProcessHealth {
            process_name: FixedString::new("arm1"),
            pid: 10,
            run_state: harvest_ipc::payloads::ProcessRunState::Running.into(),
            main_channel_count: 0,
            ..ProcessHealth::default()
        };
        board.on_health(&beat, 0);
        beat.main_channel_count = 200;
        board.on_health(&beat, 1_000_000_000);
        beat.pid = 11;
        board.on_health(&beat, 2_000_000_000);
        let rows = board.processes_json(2_000_000_000);
        assert_eq!(rows[0]["restarts"], 1);
        assert_eq!(rows[0]["rate_hz"], 200.0);
        assert_eq!(rows[0]["device_error"], Value::Null);
    }

    #[test]
    fn the_kind_of_the_last_device_error_is_shown() {
        let mut board = StatusBoard::new(0);
        let mut beat = ProcessHealth {
            process_name: FixedString::new("vacuum"),
            pid: 10,
            run_state: harvest_ipc::payloads::ProcessRunState::Degraded.into(),
            ..ProcessHealth::default()
        };
        beat.last_device_error.set(DeviceErrorCode::Timeout);
        board.on_health(&beat, 0);
        let rows = board.processes_json(0);
        assert_eq!(rows[0]["device_error"], "timeout");
    }
}
