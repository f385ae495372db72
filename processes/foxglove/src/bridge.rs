//! `harvest foxglove`: the bridge process. One ipc wait set wakes on every mapped stack
//! channel; each wake-up drains the queues, lets through what the viewing rates admit and maps
//! it onto the server's channels (encoded only for topics a client subscribed to). Camera frames
//! have a thread of their own ([`crate::camera_thread`]). A housekeeping interval sends the
//! heartbeat and (re)starts the server.

use crate::args::FoxgloveArgs;
use crate::camera_thread::{CameraSetup, CameraThread};
use crate::server::{LiveChannels, Server, ServerError};
use harvest_foxglove_mapping::mounting_files::{
    MountingError, camera_from_lidar_file, robot_from_camera_file,
};
use harvest_foxglove_mapping::{
    CameraMapper, JpegEncoder, MapError, Mounting, RateLimit, StackMapper, TimeBase,
};
use harvest_ipc::catalogue::{
    ARM_STATE, CAMERA_RGBD, EMERGENCY_STOP, HARVEST_EVENTS, LASER_SCAN_RESULT, LIDAR_POINTS,
    PERCEPTION_APPLES, VACUUM_STATE,
};
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{
    ArmId, Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Payload,
    Subscriber, Waiter,
};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::SystemTime;

/// Why the bridge stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// An option is out of range.
    #[error("harvest foxglove: {0}")]
    InvalidOption(String),
    /// The calibration or extrinsic file cannot be used.
    #[error(transparent)]
    Mounting(#[from] MountingError),
    #[error(transparent)]
    Server(#[from] ServerError),
    /// The camera thread could not start or failed.
    #[error("camera thread: {0}")]
    Camera(String),
    /// The transport (node, channel, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(BridgeError);

/// Runs the bridge until SIGINT/SIGTERM.
pub fn run(args: &FoxgloveArgs, domain: &Domain, process_name: &str) -> Result<(), BridgeError> {
    run_until(args, domain, process_name, &AtomicBool::new(false))
}

/// A stack channel the bridge reads, with its rate limit (in a cell: the wait set holds the
/// subscriber's listener borrowed while the loop drains it).
struct Input<T: Payload> {
    subscriber: Subscriber<T>,
    limit: Cell<RateLimit>,
}

impl<T: Payload> Input<T> {
    fn open(
        context: &Context,
        channel: harvest_ipc::Channel<T>,
        args: &FoxgloveArgs,
        buffer: usize,
    ) -> Result<Self, BridgeError> {
        Ok(Self {
            subscriber: context.subscriber_with_buffer(channel, buffer)?,
            limit: Cell::new(RateLimit::new(
                args.rates().min_interval(channel.spec.topic),
            )),
        })
    }

    /// Maps every queued message the rate limit admits.
    fn drain(
        &self,
        mut map: impl FnMut(&T, u64) -> Result<(), MapError<std::convert::Infallible>>,
    ) -> Result<u64, BridgeError> {
        let mut mapped = 0;
        while let Some(sample) = self.subscriber.receive()? {
            let now_ns = MonotonicClock::read_ns();
            let mut limit = self.limit.get();
            let admitted = limit.admit(now_ns);
            self.limit.set(limit);
            if admitted {
                // The live sink cannot fail: mapping errors only come from recorded input.
                let _ = map(&sample, now_ns);
                mapped += 1;
            }
        }
        Ok(mapped)
    }
}

/// [`run`] that also stops once `stop` is set (checked every heartbeat period).
pub fn run_until(
    args: &FoxgloveArgs,
    domain: &Domain,
    process_name: &str,
    stop: &AtomicBool,
) -> Result<(), BridgeError> {
    if let Some(problem) = args.problem() {
        return Err(BridgeError::InvalidOption(problem));
    }
    let mounting = Mounting {
        robot_from_camera: args
            .calibration
            .as_deref()
            .map(robot_from_camera_file)
            .transpose()?,
        camera_from_lidar: args
            .lidar_extrinsic
            .as_deref()
            .map(camera_from_lidar_file)
            .transpose()?,
    };
    let time = live_time_base();
    let foxglove_context = foxglove::Context::new();
    let mut channels = LiveChannels::new(&foxglove_context)?;
    let mut server = Server::new(foxglove_context, args.listen, args.client_backlog)?;
    server.ensure_started();

    let camera = CameraThread::spawn(CameraSetup {
        domain: domain.clone(),
        node_name: format!("{process_name}-camera"),
        mapper: CameraMapper::new(args.image(), time, mounting.robot_from_camera),
        encoder: JpegEncoder::new(args.image()),
        limit: RateLimit::new(args.rates().min_interval(CAMERA_RGBD.spec.topic)),
        channels: channels.clone(),
    })
    .map_err(|error| BridgeError::Camera(error.to_string()))?;

    let context = Context::new(domain, process_name)?;
    let mut health = HealthReporter::new(&context)?;
    let detections = Input::open(&context, PERCEPTION_APPLES, args, 64)?;
    let arm_states = [
        Input::open(&context, ARM_STATE[0], args, 64)?,
        Input::open(&context, ARM_STATE[1], args, 64)?,
    ];
    let vacuum = Input::open(&context, VACUUM_STATE, args, 64)?;
    // Every event matters (the log, the apple states): the largest buffer.
    let events = Input::open(&context, HARVEST_EVENTS, args, usize::MAX)?;
    let emergency_stop = Input::open(&context, EMERGENCY_STOP, args, 16)?;
    let lidar = Input::open(&context, LIDAR_POINTS, args, 1)?;
    let laser = Input::open(&context, LASER_SCAN_RESULT, args, 16)?;

    let waiter = Waiter::new()?;
    let _guards = [
        waiter.attach_listener(detections.subscriber.listener())?,
        waiter.attach_listener(arm_states[0].subscriber.listener())?,
        waiter.attach_listener(arm_states[1].subscriber.listener())?,
        waiter.attach_listener(vacuum.subscriber.listener())?,
        waiter.attach_listener(events.subscriber.listener())?,
        waiter.attach_listener(emergency_stop.subscriber.listener())?,
        waiter.attach_listener(lidar.subscriber.listener())?,
        waiter.attach_listener(laser.subscriber.listener())?,
    ];
    let housekeeping = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let mut mapper = StackMapper::new(time, args.image(), mounting);
    let mut mapped: u64 = 0;
    let mut camera_failed = false;
    tracing::info!(
        listen = %args.listen,
        camera_hz = args.camera_rate_hz,
        state_hz = args.state_rate_hz,
        image_scale = args.image_scale,
        "foxglove bridge running"
    );
    let result = waiter.run(|attachment| -> Result<Flow, BridgeError> {
        let sink = &mut channels;
        mapped += detections.drain(|message, now| mapper.detections(message, now, sink))?;
        for arm in ArmId::ALL {
            mapped += arm_states[arm.index()]
                .drain(|message, now| mapper.arm_state(arm, message, now, sink))?;
        }
        mapped += vacuum.drain(|message, now| mapper.vacuum(message, now, sink))?;
        mapped += events.drain(|message, now| mapper.event(message, now, sink))?;
        mapped += emergency_stop.drain(|message, now| mapper.emergency_stop(message, now, sink))?;
        mapped += lidar.drain(|message, now| mapper.lidar(message, now, sink))?;
        mapped += laser.drain(|message, now| mapper.laser_scan(message, now, sink))?;
        if attachment.has_event_from(&housekeeping) {
            server.ensure_started();
            camera_failed = camera.is_finished();
            let state = if server.is_running() && !camera_failed {
                ProcessRunState::Running
            } else {
                ProcessRunState::Degraded
            };
            let camera_sent = camera.counters.sent.load(Ordering::Relaxed);
            if let Err(error) = health.report(
                state,
                mapped + camera_sent,
                "clients",
                server.client_count() as u64,
            ) {
                tracing::debug!(%error, "heartbeat not sent");
            }
            tracing::debug!(
                clients = server.client_count(),
                mapped,
                sent = sink.sent,
                camera_received = camera.counters.received.load(Ordering::Relaxed),
                camera_sent,
                encode_us = camera.counters.last_encode_us.load(Ordering::Relaxed),
                "bridge"
            );
            if camera_failed || stop.load(Ordering::SeqCst) {
                return Ok(Flow::Stop);
            }
        }
        Ok(Flow::Continue)
    });
    let _ = health.report(ProcessRunState::Stopping, mapped, "clients", 0);
    let camera_result = camera.stop();
    server.stop();
    result.map_err(|error| error.flatten())?;
    camera_result.map_err(BridgeError::Camera)?;
    if camera_failed {
        return Err(BridgeError::Camera("the camera thread ended".to_owned()));
    }
    Ok(())
}

/// Live messages carry wall-clock time (what Foxglove shows as the time of day).
fn live_time_base() -> TimeBase {
    let monotonic_ns = MonotonicClock::read_ns();
    let realtime_ns = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |since| since.as_nanos() as u64);
    TimeBase::realtime(monotonic_ns, realtime_ns)
}
