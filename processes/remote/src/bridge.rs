//! `harvest remote`: the robot's side of the link.
//!
//! - the **main loop** (a wait set): wakes on the mode, e-stop, health, events and detections
//!   channels and on a 10 ms tick; sends each channel of `harvest_remote::channel_policy::OUTBOUND`
//!   at its pace (the e-stop and the mode at once on change, every harvest event, the newest
//!   detections at <= 10 Hz, the newest arm and vacuum states at 20 Hz sampled on the tick, the
//!   fleet summary and the on-change channels again on their slow beat); until a stop message
//!   is heard, the e-stop as the mode carries it (the executive sends no stop message at a
//!   start where the stop is not engaged); sends the heartbeat;
//! - the **camera thread** (`camera_thread.rs`): a downscaled JPEG at <= 2 Hz while a
//!   subscriber matches, nothing otherwise;
//! - two **command lanes** (`command_lane.rs`): the command key and the e-stop key, each
//!   a queryable, a thread and its own `operator/command` publisher.
//!
//! With `--ros2-domain N` the same session also carries the robot as a ROS 2 node over
//! rmw_zenoh (`ros2_link.rs`): joint states, detections, events and diagnostics at the same
//! paces, and an e-stop from ROS.
//!
//! Every Zenoh publisher drops on congestion; the bridge reads the stack's channels like any
//! other subscriber, so a slow or cut link never blocks a process onboard. Without settings
//! the session neither listens nor connects: the robot is off the network until configured.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use harvest_ipc::catalogue::{
    ARM_STATE, EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_MODE, PERCEPTION_APPLES, PROCESS_HEALTH,
    VACUUM_STATE,
};
use harvest_ipc::payloads::{AppleDetections, ArmState, ProcessHealth, ProcessRunState};
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Waiter,
};
use harvest_remote::camera_image::CameraImageSettings;
use harvest_remote::channel_policy::{OUTBOUND, Outbound, SLOW_BEAT_MS, policy};
use harvest_remote::fleet_summary::{FleetSummary, SummaryBuilder};
use harvest_remote::state_encoding::{
    HealthContent, ModeContent, estop_content, estop_from_mode, health_content, json_bytes,
    mode_content,
};
use harvest_remote::{ChangeBeat, InboundGate, LinkSettings, RateGate, RobotKeys, RobotName};
use tracing::{info, warn};
use zenoh::Wait;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;

use crate::camera_thread;
use crate::command_lane::{self, LaneKind};
use crate::error::RemoteError;
use crate::link_session::{LinkArgs, open_session, priority};
use crate::ros2_link::Ros2Link;

/// The tick that samples the 200 Hz states and sends what is due: a fifth of the states'
/// period, so a gate that opens between two ticks waits at most 10 ms (18-20 Hz).
const TICK: Duration = Duration::from_millis(10);

/// `harvest remote` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct RemoteArgs {
    /// This robot's name on the link (`harvest/v1/<robot>/...`; default: the domain's name).
    #[arg(long)]
    pub robot: Option<RobotName>,
    #[command(flatten)]
    pub link: LinkArgs,
    /// The address of this robot's console as a station should open it (shown on the fleet
    /// page).
    #[arg(long)]
    pub console_url: Option<String>,
    /// Camera pixels per image pixel on the link.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub camera_scale: u32,
    /// JPEG quality on the link, 1-100.
    #[arg(long, default_value_t = 70, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg_quality: u8,
    /// Camera images a second at most (<= 2).
    #[arg(long, default_value_t = 2.0)]
    pub camera_hz: f64,
    /// How long a command waits for the executive's answer, ms.
    #[arg(long, default_value_t = 1500)]
    pub ack_timeout_ms: u64,
    /// Also appear as a ROS 2 node over rmw_zenoh in this ROS domain (`ROS_DOMAIN_ID`, 0-232):
    /// connect the link to the ROS machine's `rmw_zenohd` (`--connect tcp/HOST:7447`). Off by
    /// default; refused together with `[access]` rules (they cover the harvest keys only).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=232))]
    pub ros2_domain: Option<u32>,
}

/// The robot's name: `--robot`, else the domain's name when it is a valid one, else `robot`.
fn robot_name(args: &RemoteArgs, domain: &Domain) -> RobotName {
    args.robot.clone().unwrap_or_else(|| {
        RobotName::parse(&domain.name().to_lowercase()).unwrap_or_else(|_| RobotName::fallback())
    })
}

/// The publishers of the table, by what they carry.
fn declare_publishers(
    session: &zenoh::Session,
    keys: &RobotKeys,
) -> Result<HashMap<Outbound, Publisher<'static>>, RemoteError> {
    let mut publishers = HashMap::new();
    for entry in OUTBOUND {
        let publisher = session
            .declare_publisher(keys.key(entry.key_suffix))
            .priority(priority(entry.priority))
            .express(entry.express)
            .congestion_control(CongestionControl::Drop)
            .wait()?;
        publishers.insert(entry.what, publisher);
    }
    Ok(publishers)
}

/// Sends `payload` on `what`'s key; a failed put is counted, never fatal (the link may be down).
fn put(
    publishers: &HashMap<Outbound, Publisher<'static>>,
    what: Outbound,
    payload: Vec<u8>,
    failed: &mut u64,
) {
    if let Some(publisher) = publishers.get(&what)
        && let Err(error) = publisher.put(payload).wait()
    {
        *failed += 1;
        tracing::debug!(?what, %error, "put failed");
    }
}

/// Runs `harvest remote` until SIGINT/SIGTERM.
pub fn run(args: &RemoteArgs, domain: &Domain, process_name: &str) -> Result<(), RemoteError> {
    let camera_settings = CameraImageSettings {
        scale: args.camera_scale,
        jpeg_quality: args.jpeg_quality,
        max_hz: args.camera_hz,
    };
    if let Some(problem) = camera_settings.problem() {
        return Err(RemoteError::Invalid(problem));
    }
    let robot = robot_name(args, domain);
    let keys = RobotKeys::new(robot.clone());
    let settings = args.link.settings(LinkSettings::default())?;
    let key_root = format!("{}/{robot}", harvest_remote::keys::ROOT);
    let session = open_session(&settings, &key_root)?;
    if settings.listen.is_empty() && settings.connect.is_empty() {
        info!(%robot, "no listener and no connection configured: the link is off the network");
    } else {
        info!(%robot, listen = ?settings.listen, connect = ?settings.connect, "link up");
    }
    let _alive = session.liveliness().declare_token(keys.alive()).wait()?;
    let publishers = declare_publishers(&session, &keys)?;
    let mut ros2 = match args.ros2_domain {
        Some(_) if settings.access.is_some() => {
            return Err(RemoteError::Invalid(
                "--ros2-domain with [access] rules in the link settings: the rules cover the \
                 harvest/v1 keys only, so ROS 2 peers would be refused; use a link without \
                 [access] (a trusted wired link to the ROS machine)"
                    .to_owned(),
            ));
        }
        Some(ros_domain_id) => Some(Ros2Link::declare(
            &session,
            &robot,
            ros_domain_id,
            domain,
            process_name,
        )?),
        None => None,
    };

    let gate = Arc::new(Mutex::new(InboundGate::new(keys.clone())));
    let ack_timeout = Duration::from_millis(args.ack_timeout_ms);
    for kind in [LaneKind::EmergencyStop, LaneKind::Command] {
        command_lane::spawn(
            kind,
            &session,
            &keys,
            domain,
            process_name,
            Arc::clone(&gate),
            ack_timeout,
        )?;
    }
    let ros_camera = ros2.as_mut().and_then(Ros2Link::take_camera);
    camera_thread::spawn(
        &session,
        &keys,
        domain,
        process_name,
        camera_settings,
        ros_camera,
    )?;

    let context = Context::new(domain, process_name)?;
    let mut health = HealthReporter::new(&context)?;
    let arms_in = [
        context.subscriber(ARM_STATE[0])?,
        context.subscriber(ARM_STATE[1])?,
    ];
    let vacuum_in = context.subscriber(VACUUM_STATE)?;
    let mode_in = context.subscriber(OPERATOR_MODE)?;
    let estop_in = context.subscriber(EMERGENCY_STOP)?;
    let health_in = context.subscriber_with_buffer(PROCESS_HEALTH, 64)?;
    let events_in = context.subscriber_with_buffer(HARVEST_EVENTS, 64)?;
    let detections_in = context.subscriber(PERCEPTION_APPLES)?;

    let waiter = Waiter::new()?;
    let tick = waiter.attach_interval(TICK)?;
    let heartbeat = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let _wakes = [
        waiter.attach_listener(mode_in.listener())?,
        waiter.attach_listener(estop_in.listener())?,
        waiter.attach_listener(health_in.listener())?,
        waiter.attach_listener(events_in.listener())?,
        waiter.attach_listener(detections_in.listener())?,
    ];

    // What the policy table says: the beat of an on-change key, the rate of a latest-only one.
    let beat_ns = |what| match policy(what).pace {
        harvest_remote::Pace::OnChange { beat_ms } => beat_ms * 1_000_000,
        _ => SLOW_BEAT_MS * 1_000_000,
    };
    let rate = |what| match policy(what).pace {
        harvest_remote::Pace::Latest { max_hz } => max_hz,
        _ => 1.0,
    };
    let mut arm_gates = [
        RateGate::<ArmState>::with_max_hz(rate(Outbound::ArmState(1))),
        RateGate::<ArmState>::with_max_hz(rate(Outbound::ArmState(2))),
    ];
    let mut vacuum_gate = RateGate::<Vec<u8>>::with_max_hz(rate(Outbound::VacuumState));
    let mut detections_gate =
        RateGate::<Box<AppleDetections>>::with_max_hz(rate(Outbound::Detections));
    let mut mode_beat = ChangeBeat::<ModeContent>::new(beat_ns(Outbound::Mode));
    let mut last_mode_json: Option<Vec<u8>> = None;
    let mut estop_beat = ChangeBeat::<(u8, String)>::new(beat_ns(Outbound::EmergencyStop));
    let mut last_estop_json: Option<Vec<u8>> = None;
    let mut estop_heard = false;
    // Per process: its beat and its last heartbeat (sent again on the beat).
    let mut health_beats: HashMap<String, (ChangeBeat<HealthContent>, ProcessHealth)> =
        HashMap::new();
    let mut summary_beat = ChangeBeat::<FleetSummary>::new(beat_ns(Outbound::Summary));
    let mut summary = SummaryBuilder::new(
        robot.as_str(),
        args.console_url.clone(),
        MonotonicClock::read_ns(),
    );
    let mut last_state_seq = [0u64; 3];
    let mut sent = 0u64;
    let mut failed = 0u64;
    let mut ticks = 0u64;

    let end = waiter.run(|attachment| -> Result<Flow, RemoteError> {
        let now_ns = MonotonicClock::read_ns();
        // The stop first.
        estop_in.try_drain(|stop| -> Result<(), RemoteError> {
            estop_heard = true;
            summary.on_estop(stop);
            let json = json_bytes(stop);
            if estop_beat.due(&estop_content(stop), now_ns) {
                put(
                    &publishers,
                    Outbound::EmergencyStop,
                    json.clone(),
                    &mut failed,
                );
                sent += 1;
            }
            last_estop_json = Some(json);
            Ok(())
        })?;
        mode_in.try_drain(|mode| -> Result<(), RemoteError> {
            summary.on_mode(mode);
            let json = json_bytes(mode);
            if mode_beat.due(&mode_content(mode), now_ns) {
                put(&publishers, Outbound::Mode, json.clone(), &mut failed);
                sent += 1;
            }
            last_mode_json = Some(json);
            // No stop message heard yet: the stop as the mode carries it.
            if !estop_heard {
                let stop = estop_from_mode(mode);
                let json = json_bytes(&stop);
                if estop_beat.due(&estop_content(&stop), now_ns) {
                    put(
                        &publishers,
                        Outbound::EmergencyStop,
                        json.clone(),
                        &mut failed,
                    );
                    sent += 1;
                }
                last_estop_json = Some(json);
            }
            Ok(())
        })?;
        health_in.try_drain(|beat| -> Result<(), RemoteError> {
            summary.on_health(beat);
            let content = health_content(beat);
            let entry = health_beats
                .entry(content.0.clone())
                .or_insert_with(|| (ChangeBeat::new(beat_ns(Outbound::Health)), *beat));
            if entry.0.due(&content, now_ns) {
                put(&publishers, Outbound::Health, json_bytes(beat), &mut failed);
                sent += 1;
                if let Some(ros2) = ros2.as_mut() {
                    ros2.health(beat);
                }
            }
            entry.1 = *beat;
            Ok(())
        })?;
        events_in.try_drain(|event| -> Result<(), RemoteError> {
            summary.on_event(event);
            put(
                &publishers,
                Outbound::HarvestEvents,
                json_bytes(event),
                &mut failed,
            );
            sent += 1;
            if let Some(ros2) = ros2.as_mut() {
                ros2.event(event);
            }
            Ok(())
        })?;
        if let Some(detections) = detections_in.receive_latest()? {
            detections_gate.offer(Box::new(*detections));
        }
        if let Some(detections) = detections_gate.take_due(now_ns) {
            put(
                &publishers,
                Outbound::Detections,
                json_bytes(&*detections),
                &mut failed,
            );
            sent += 1;
            if let Some(ros2) = ros2.as_mut() {
                ros2.detections(&detections);
            }
        }
        if attachment.has_event_from(&tick) {
            for (i, arm_in) in arms_in.iter().enumerate() {
                if let Some(state) = arm_in.receive_latest()?
                    && state.header.msg_seq != last_state_seq[i]
                {
                    last_state_seq[i] = state.header.msg_seq;
                    arm_gates[i].offer(*state);
                }
                if let Some(state) = arm_gates[i].take_due(now_ns) {
                    put(
                        &publishers,
                        Outbound::ArmState(i as u8 + 1),
                        json_bytes(&state),
                        &mut failed,
                    );
                    sent += 1;
                    if let Some(ros2) = ros2.as_mut() {
                        ros2.arm_state(&state);
                    }
                }
            }
            if let Some(state) = vacuum_in.receive_latest()?
                && state.header.msg_seq != last_state_seq[2]
            {
                last_state_seq[2] = state.header.msg_seq;
                vacuum_gate.offer(json_bytes(&*state));
            }
            if let Some(json) = vacuum_gate.take_due(now_ns) {
                put(&publishers, Outbound::VacuumState, json, &mut failed);
                sent += 1;
            }
            // The slow beats of the on-change channels.
            if estop_beat.beat_due(now_ns).is_some()
                && let Some(json) = &last_estop_json
            {
                put(
                    &publishers,
                    Outbound::EmergencyStop,
                    json.clone(),
                    &mut failed,
                );
            }
            if mode_beat.beat_due(now_ns).is_some()
                && let Some(json) = &last_mode_json
            {
                put(&publishers, Outbound::Mode, json.clone(), &mut failed);
            }
            for (beat, last) in health_beats.values_mut() {
                if beat.beat_due(now_ns).is_some() {
                    put(&publishers, Outbound::Health, json_bytes(last), &mut failed);
                    if let Some(ros2) = ros2.as_mut() {
                        ros2.health(last);
                    }
                }
            }
            // The summary is rebuilt every tenth tick (10 Hz): it changes with events and modes.
            ticks += 1;
            let line = ticks.is_multiple_of(10).then(|| summary.summary());
            if let Some(line) = line
                && summary_beat.due(&line, now_ns)
            {
                put(
                    &publishers,
                    Outbound::Summary,
                    serde_json::to_vec(&line).unwrap_or_default(),
                    &mut failed,
                );
            }
        }
        if attachment.has_event_from(&heartbeat) {
            let counters = gate.lock().map(|g| g.counters()).unwrap_or_default();
            health.report(
                ProcessRunState::Running,
                sent,
                "refused_commands",
                counters.refused(),
            )?;
        }
        Ok(Flow::Continue)
    });
    let counters = gate.lock().map(|g| g.counters()).unwrap_or_default();
    let ros2_failed = ros2.as_ref().map_or(0, Ros2Link::failed_puts);
    info!(sent, failed, ros2_failed, ?counters, "remote link stopping");
    if failed > 0 {
        warn!(failed, "puts failed while the link ran");
    }
    end.map_err(harvest_ipc::waiter::RunError::flatten)?;
    drop(session);
    Ok(())
}
