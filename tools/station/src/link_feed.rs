//! What the robot's link sends, into the console's status board and camera view: one Zenoh
//! subscriber per key under `harvest/v1/<robot>/`, each decoding the JSON the robot sends (each
//! payload's own JSON, `harvest_remote::state_decoding`) back into the stack's payload and
//! handing it to the board as the robot's console does with its channels. Every stamp moves the
//! estimate of the robot's clock ([`harvest_console::stack_clock`]), so ages on the page are on
//! the robot's time. The camera is subscribed only while at least one page watches (the robot
//! sends it only while a subscriber matches).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use harvest_console::camera_view::EncodedFrame;
use harvest_console::shared::Shared;
use harvest_console::status_board::StatusBoard;
use harvest_ipc::Payload;
use harvest_ipc::payloads::rgbd_frame::RGB_WIDTH_PX;
use harvest_ipc::payloads::{
    AppleDetections, ArmState, HarvestEvent, OperatorModeState, ProcessHealth, VacuumState,
};
use harvest_remote::camera_image::CameraAttachment;
use harvest_remote::channel_policy::{Outbound, policy};
use harvest_remote::state_decoding::payload_from_json;
use harvest_remote_process::station_ctl::Station;
use serde::de::DeserializeOwned;
use zenoh::Wait;
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Sample, SampleKind};

use crate::error::StationError;
use crate::relayed_sessions::RelayedSessions;

/// What the subscribers update, read by the status loop.
pub struct FeedState {
    pub board: Mutex<StatusBoard>,
    /// The robot's liveliness token is present.
    pub robot_seen: AtomicBool,
    /// Samples that did not decode (a robot of another version), all keys.
    pub undecodable: AtomicU64,
    /// Camera images shown.
    pub images: AtomicU64,
}

/// What one decoded message does to the board.
type PayloadHandler<T> = Box<dyn Fn(T, &mut StatusBoard, &Shared) + Send + Sync>;

/// Subscribes to the key of `what`: each sample decoded as a `T`, its stamp given to the clock
/// estimate, then handed to `handle` with the board.
fn subscribe_payload<T: Payload + DeserializeOwned + 'static>(
    station: &Station,
    state: &Arc<FeedState>,
    shared: &Arc<Shared>,
    what: Outbound,
    handle: PayloadHandler<T>,
) -> Result<Subscriber<()>, StationError> {
    let (state, shared) = (state.clone(), shared.clone());
    Ok(station
        .session()
        .declare_subscriber(station.keys().key(key_suffix(what)))
        .callback(move |sample| {
            if let Some(message) = decode::<T>(&sample, &state) {
                shared.clock.observe(message.header().publish_ns);
                let mut board = state.board.lock().unwrap_or_else(|p| p.into_inner());
                handle(message, &mut board, &shared);
            }
        })
        .wait()?)
}

/// The subscribers; dropping this ends them.
pub struct LinkFeed {
    pub state: Arc<FeedState>,
    station: Arc<Station>,
    shared: Arc<Shared>,
    _subscribers: Vec<Subscriber<()>>,
    camera: Option<Subscriber<()>>,
}

fn key_suffix(what: Outbound) -> &'static str {
    policy(what).key_suffix
}

fn decode<T: DeserializeOwned>(sample: &Sample, state: &FeedState) -> Option<T> {
    match payload_from_json(&sample.payload().to_bytes()) {
        Ok(value) => Some(value),
        Err(error) => {
            if state.undecodable.fetch_add(1, Ordering::Relaxed) == 0 {
                tracing::warn!(key = %sample.key_expr(), %error, "a sample from the robot does not decode");
            }
            None
        }
    }
}

impl LinkFeed {
    /// Subscribes to the robot's keys (the camera once a page watches: [`Self::watch_camera`]).
    pub fn start(
        station: Arc<Station>,
        shared: Arc<Shared>,
        relayed: Arc<RelayedSessions>,
    ) -> Result<Self, StationError> {
        let state = Arc::new(FeedState {
            board: Mutex::new(StatusBoard::new(shared.clock.now_ns())),
            robot_seen: AtomicBool::new(false),
            undecodable: AtomicU64::new(0),
            images: AtomicU64::new(0),
        });
        let mut subscribers = vec![subscribe_payload(
            &station,
            &state,
            &shared,
            Outbound::Mode,
            Box::new(move |mut mode: OperatorModeState, board, shared| {
                mode.controlling_session = relayed.page_session(mode.controlling_session);
                shared
                    .controlling_session
                    .store(mode.controlling_session, Ordering::Release);
                board.on_mode(&mode);
            }),
        )?];
        for (index, arm) in [1u8, 2].into_iter().enumerate() {
            subscribers.push(subscribe_payload(
                &station,
                &state,
                &shared,
                Outbound::ArmState(arm),
                Box::new(move |arm_state: ArmState, board, _| {
                    board.on_arm_state(index, &arm_state)
                }),
            )?);
        }
        subscribers.push(subscribe_payload(
            &station,
            &state,
            &shared,
            Outbound::VacuumState,
            Box::new(|vacuum: VacuumState, board, _| board.on_vacuum(&vacuum)),
        )?);
        subscribers.push(subscribe_payload(
            &station,
            &state,
            &shared,
            Outbound::Detections,
            Box::new(|set: AppleDetections, board, _| board.on_detections(&set)),
        )?);
        subscribers.push(subscribe_payload(
            &station,
            &state,
            &shared,
            Outbound::HarvestEvents,
            Box::new(|event: HarvestEvent, board, _| board.on_harvest_event(&event)),
        )?);
        subscribers.push(subscribe_payload(
            &station,
            &state,
            &shared,
            Outbound::Health,
            Box::new(|beat: ProcessHealth, board, shared| {
                board.on_health(&beat, shared.clock.now_ns())
            }),
        )?);
        let seen = state.clone();
        let alive = station
            .session()
            .liveliness()
            .declare_subscriber(station.keys().alive())
            .history(true)
            .callback(move |sample| {
                seen.robot_seen
                    .store(sample.kind() == SampleKind::Put, Ordering::Release);
            })
            .wait()?;
        subscribers.push(alive);
        Ok(Self {
            state,
            station,
            shared,
            _subscribers: subscribers,
            camera: None,
        })
    }

    /// Subscribes to the camera while `watched`, and lets go of it otherwise.
    pub fn watch_camera(&mut self, watched: bool) -> Result<(), StationError> {
        if !watched {
            self.camera = None;
            return Ok(());
        }
        if self.camera.is_some() {
            return Ok(());
        }
        let (state, shared) = (self.state.clone(), self.shared.clone());
        let subscriber = self
            .station
            .session()
            .declare_subscriber(self.station.keys().key(key_suffix(Outbound::Camera)))
            .callback(move |sample| show_image(&sample, &state, &shared))
            .wait()?;
        self.camera = Some(subscriber);
        Ok(())
    }
}

/// One JPEG from the robot, as the page's camera view.
fn show_image(sample: &Sample, state: &FeedState, shared: &Shared) {
    let Some(attachment) = sample
        .attachment()
        .and_then(|bytes| serde_json::from_slice::<CameraAttachment>(&bytes.to_bytes()).ok())
    else {
        state.undecodable.fetch_add(1, Ordering::Relaxed);
        return;
    };
    let view_seq = state.images.fetch_add(1, Ordering::Relaxed) + 1;
    let scale = (RGB_WIDTH_PX as u32 / attachment.width_px.max(1)).max(1);
    shared.view.publish(EncodedFrame::new(
        &sample.payload().to_bytes(),
        view_seq,
        attachment.frame_seq,
        attachment.capture_ns,
        shared.clock.now_ns(),
        (attachment.width_px, attachment.height_px),
        scale,
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_remote::state_encoding::json_bytes;

    fn round_trip<T: harvest_ipc::Payload + DeserializeOwned + PartialEq + std::fmt::Debug>(
        value: T,
    ) {
        let bytes = json_bytes(&value);
        let back: T = payload_from_json(&bytes).unwrap_or_else(|error| {
            panic!(
                "{}: {error}: {}",
                T::TYPE_NAME,
                String::from_utf8_lossy(&bytes)
            )
        });
        assert_eq!(back, value);
    }

    #[test]
    fn what_the_robot_sends_decodes_into_the_stack_payloads() {
        round_trip(OperatorModeState {
            last_change_reason: harvest_ipc::FixedString::new("started by test"),
            ..OperatorModeState::default()
        });
        round_trip(ArmState::default());
        round_trip(VacuumState::default());
        round_trip(ProcessHealth::default());
        round_trip(HarvestEvent::default());
        round_trip(AppleDetections::default());
    }
}
