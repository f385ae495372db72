//! The camera on the link: while a station's subscriber matches the camera key (Zenoh's
//! matching listener), or with `--ros2-domain` a ROS 2 subscriber matches the camera topic, the
//! newest frame of `camera/rgbd`, read in place, downscaled and
//! JPEG-encoded at most `max_hz` times a second; while nobody watches, the thread sleeps on a
//! condition variable and encodes nothing. The frame's sequence and capture stamp ride in the
//! attachment (`harvest_remote::camera_image`). Raw frames never leave the robot.

use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::{Context, Domain, MonotonicClock, termination};
use harvest_remote::camera_image::{CameraEncoder, CameraImageSettings};
use harvest_remote::channel_policy::CAMERA;
use harvest_remote::{RateGate, RobotKeys};
use tracing::{debug, info, warn};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

use crate::error::RemoteError;
use crate::link_session::priority;
use crate::ros2_link::RosCamera;

/// Longest wait before the thread looks at the termination flag again.
const WAKE_BOUND: Duration = Duration::from_millis(500);

/// Whether a subscriber matches (the link's camera key, the ROS 2 topic), with a condition
/// variable for the thread to sleep on.
#[derive(Default)]
struct Watched {
    matching: Mutex<[bool; 2]>,
    changed: Condvar,
}

/// Which publisher's matching a status is.
const LINK: usize = 0;
const ROS: usize = 1;

/// Sets `watched`'s flag `which` from each matching status of `publisher`.
fn listen_matching(
    publisher: &zenoh::pubsub::Publisher<'static>,
    watched: &Arc<Watched>,
    which: usize,
) -> Result<zenoh::matching::MatchingListener<()>, RemoteError> {
    let on_change = Arc::clone(watched);
    Ok(publisher
        .matching_listener()
        .callback(move |status| {
            let mut matching = on_change
                .matching
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            matching[which] = status.matching();
            on_change.changed.notify_all();
        })
        .wait()?)
}

/// Declares the camera's publisher and matching listener and starts the thread.
pub fn spawn(
    session: &zenoh::Session,
    keys: &RobotKeys,
    domain: &Domain,
    process_name: &str,
    settings: CameraImageSettings,
    mut ros_camera: Option<RosCamera>,
) -> Result<(), RemoteError> {
    let publisher = session
        .declare_publisher(keys.key(CAMERA.key_suffix))
        .priority(priority(CAMERA.priority))
        .express(CAMERA.express)
        .congestion_control(CongestionControl::Drop)
        .wait()?;
    let watched = Arc::new(Watched::default());
    let listener = listen_matching(&publisher, &watched, LINK)?;
    let ros_listener = ros_camera
        .as_ref()
        .map(|camera| listen_matching(camera.publisher(), &watched, ROS))
        .transpose()?;
    let domain = domain.clone();
    let node_name = format!("{process_name}-camera");
    std::thread::Builder::new()
        .name(node_name.clone())
        .spawn(move || {
            let _listeners = (listener, ros_listener);
            let result = (|| -> Result<(), RemoteError> {
                let context = Context::new(&domain, &node_name)?;
                // The frame subscriber exists only while someone watches: unwatched, the link
                // holds no slot of the frame channel's shared memory.
                let mut frames = None;
                let mut gate = RateGate::<()>::with_max_hz(settings.max_hz);
                let mut encoder = CameraEncoder::default();
                let mut images = 0u64;
                while !termination::requested() {
                    let watchers = {
                        let matching = watched.matching.lock().unwrap_or_else(|p| p.into_inner());
                        let watchers = *matching;
                        if !watchers.contains(&true) {
                            if frames.take().is_some() {
                                info!(images, "camera: nobody watches; images stopped");
                            }
                            let _ = watched.changed.wait_timeout(matching, WAKE_BOUND);
                            continue;
                        }
                        watchers
                    };
                    if frames.is_none() {
                        frames = Some(context.subscriber_with_buffer(CAMERA_RGBD, 1)?);
                    }
                    let Some(subscriber) = frames.as_ref() else {
                        continue;
                    };
                    if let Err(error) = subscriber.listener().timed_wait(|_| {}, WAKE_BOUND) {
                        debug!(?error, "camera wait interrupted");
                    }
                    let Some(frame) = subscriber.receive_latest()? else {
                        continue;
                    };
                    gate.offer(());
                    if gate.take_due(MonotonicClock::read_ns()).is_none() {
                        continue;
                    }
                    match encoder.encode(&frame, &settings) {
                        Ok((jpeg, attachment)) => {
                            if watchers[LINK]
                                && let Err(error) = publisher
                                    .put(jpeg.to_vec())
                                    .attachment(attachment.to_json())
                                    .wait()
                            {
                                debug!(%error, "camera put failed");
                            }
                            if watchers[ROS]
                                && let Some(ros_camera) = ros_camera.as_mut()
                            {
                                ros_camera.put(jpeg, attachment.capture_ns);
                            }
                            images += 1;
                            if images == 1 {
                                info!("camera: a station watches; images sent");
                            }
                            tracing::trace!(
                                seq = attachment.frame_seq,
                                bytes = jpeg.len(),
                                "camera image"
                            );
                        }
                        Err(error) => warn!(%error, "camera image not encoded"),
                    }
                }
                Ok(())
            })();
            if let Err(error) = result {
                warn!(%error, "camera thread ended");
            }
        })?;
    Ok(())
}
