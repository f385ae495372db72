//! `harvest/events` -> `/apples/harvest`: the vacuum supervisor's apples (its ids, as on
//! `armN/target`) as spheres in the robot frame, coloured by where each is in the harvest:
//! assigned (blue), attached (orange), harvested (green), failed (red), out of reach (grey).
//!
//! Perception's ids (`/apples/detected`) are another id space; the two views overlap in the 3D
//! scene where they describe the same apple.

use crate::color::{self, Rgba};
use crate::frames;
use crate::geometry::{IDENTITY, pose, vector};
use crate::stamps::TimeBase;
use foxglove::messages::{Duration, KeyValuePair, SceneEntity, SceneUpdate, SpherePrimitive};
use harvest_ipc::payloads::{HarvestCause, HarvestEvent, HarvestEventKind};
use std::collections::BTreeMap;

/// Sphere diameter when no radius is known, m (a typical apple).
pub const DEFAULT_DIAMETER_M: f64 = 0.08;
/// How long a harvested or failed apple stays shown, s.
pub const FINISHED_LIFETIME_S: f64 = 10.0;
/// Apples remembered at most (the oldest are forgotten first).
const MAX_APPLES: usize = 512;

/// Where an apple is in the harvest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AppleState {
    Assigned,
    Attached,
    Harvested,
    Failed,
    OutOfReach,
}

impl AppleState {
    pub fn name(self) -> &'static str {
        match self {
            Self::Assigned => "assigned",
            Self::Attached => "attached",
            Self::Harvested => "harvested",
            Self::Failed => "failed",
            Self::OutOfReach => "out_of_reach",
        }
    }

    pub fn color(self) -> Rgba {
        match self {
            Self::Assigned => color::BLUE,
            Self::Attached => color::ORANGE,
            Self::Harvested => color::GREEN,
            Self::Failed => color::RED,
            Self::OutOfReach => color::GREY,
        }
    }

    /// The new state an event puts its apple in, if it changes it.
    pub fn after(event: &HarvestEvent) -> Option<Self> {
        match event.kind.get().ok()? {
            HarvestEventKind::Assigned => Some(Self::Assigned),
            HarvestEventKind::Attached => Some(Self::Attached),
            HarvestEventKind::AttemptEnded | HarvestEventKind::AttemptFinished => {
                Some(if event.harvested != 0 {
                    Self::Harvested
                } else {
                    Self::Failed
                })
            }
            // Refused for good because the arm cannot reach it (retried refusals leave it).
            HarvestEventKind::TargetRejected
                if event.harvested == 0 && event.cause == HarvestCause::OutsideWorkspace =>
            {
                Some(Self::OutOfReach)
            }
            _ => None,
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Known {
    state: AppleState,
    position_in_robot_m: Option<[f64; 3]>,
    arm_id: u8,
    order: u64,
}

/// The apples the events told about.
#[derive(Debug, Default)]
pub struct HarvestApples {
    apples: BTreeMap<u32, Known>,
    next_order: u64,
}

impl HarvestApples {
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes in one event; returns the scene update it causes (none when the event changes no
    /// apple's state or the apple's position was never told).
    pub fn update(&mut self, event: &HarvestEvent, time: &TimeBase) -> Option<SceneUpdate> {
        if event.apple_id == 0 {
            return None;
        }
        let state = AppleState::after(event)?;
        let position = event
            .position_in_robot_m
            .iter()
            .all(|v| v.is_finite())
            .then_some(event.position_in_robot_m);
        let order = self.next_order;
        self.next_order += 1;
        let known = self.apples.entry(event.apple_id).or_insert(Known {
            state,
            position_in_robot_m: None,
            arm_id: event.arm_id,
            order,
        });
        known.state = state;
        known.order = order;
        if event.arm_id != 0 {
            known.arm_id = event.arm_id;
        }
        if position.is_some() {
            known.position_in_robot_m = position;
        }
        let known = *known;
        if self.apples.len() > MAX_APPLES
            && let Some(oldest) = self
                .apples
                .iter()
                .min_by_key(|(_, apple)| apple.order)
                .map(|(id, _)| *id)
        {
            self.apples.remove(&oldest);
        }
        let position = known.position_in_robot_m?;
        let finished = matches!(state, AppleState::Harvested | AppleState::Failed);
        let entity = SceneEntity {
            timestamp: Some(time.timestamp(event.header.capture_ns)),
            frame_id: frames::ROBOT.to_owned(),
            id: format!("apple/{}", event.apple_id),
            lifetime: finished.then(|| Duration::saturating_from_secs_f64(FINISHED_LIFETIME_S)),
            frame_locked: false,
            metadata: vec![
                KeyValuePair {
                    key: "state".to_owned(),
                    value: state.name().to_owned(),
                },
                KeyValuePair {
                    key: "arm".to_owned(),
                    value: known.arm_id.to_string(),
                },
            ],
            spheres: vec![SpherePrimitive {
                pose: Some(pose(position, IDENTITY)),
                size: Some(vector([DEFAULT_DIAMETER_M; 3])),
                color: Some(state.color().with_alpha(0.85).into()),
            }],
            ..SceneEntity::default()
        };
        Some(SceneUpdate {
            deletions: Vec::new(),
            entities: vec![entity],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payloads::HarvestEventSource;

    fn event(kind: HarvestEventKind, apple_id: u32, position: [f64; 3]) -> HarvestEvent {
        let mut event = HarvestEvent::new(1, HarvestEventSource::Vacuum, kind, 1, apple_id);
        event.position_in_robot_m = position;
        event
    }

    #[test]
    fn an_apple_goes_from_assigned_to_harvested() {
        let mut apples = HarvestApples::new();
        let time = TimeBase::MONOTONIC;
        let assigned = apples
            .update(
                &event(HarvestEventKind::Assigned, 5, [1.3, 0.1, 0.5]),
                &time,
            )
            .expect("update");
        assert_eq!(assigned.entities[0].id, "apple/5");
        assert_eq!(
            assigned.entities[0].spheres[0].color,
            Some(color::BLUE.with_alpha(0.85).into())
        );
        // Attached without a position: the assigned position is kept.
        let attached = apples
            .update(&event(HarvestEventKind::Attached, 5, [f64::NAN; 3]), &time)
            .expect("update");
        let position = attached.entities[0].spheres[0]
            .pose
            .and_then(|pose| pose.position)
            .expect("position");
        assert_eq!(position.x, 1.3);
        let mut ended = event(HarvestEventKind::AttemptEnded, 5, [f64::NAN; 3]);
        ended.harvested = 1;
        let harvested = apples.update(&ended, &time).expect("update");
        assert_eq!(harvested.entities[0].metadata[0].value, "harvested");
        assert!(harvested.entities[0].lifetime.is_some());
        // Events that change nothing, and apples never placed, give no update.
        assert!(
            apples
                .update(&event(HarvestEventKind::Replanned, 5, [0.0; 3]), &time)
                .is_none()
        );
        assert!(
            apples
                .update(&event(HarvestEventKind::Attached, 6, [f64::NAN; 3]), &time)
                .is_none()
        );
    }
}
