//! `harvest bench pipeline`: start the stack (or attach to one), subscribe to the pipeline's
//! channels with the stack's own ipc layer, collect for `--duration` after `--warmup`, stop the
//! stack, report.

use crate::error::BenchError;
use crate::pipeline::comparison::PipelineComparison;
use crate::pipeline::cpu_load::CpuLoad;
use crate::pipeline::jitter::{JitterResult, PeriodTracker};
use crate::pipeline::options::{BenchPipelineArgs, PipelineSettings, RunScheduling};
use crate::pipeline::report::{ChannelResult, PipelineReport, StageResult};
use crate::pipeline::stack::Stack;
use crate::pipeline::summary::Samples;
use crate::pipeline::svg::render_pipeline_svg;
use crate::pipeline::tracker::{PipelineTracker, Stage};
use crate::report::HostInfo;
use crate::run::{kernel_release, write_file};
use harvest_ipc::ArmId;
use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_STATE, ARM_TARGET, CAMERA_RGBD, HW_CAMERA_RGBD, PERCEPTION_APPLES,
    VACUUM_STATE,
};
use harvest_ipc::{
    Context, Domain, Flow, MonotonicClock, Payload, RunEnd, ScratchDomain, Subscriber, Waiter,
};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// How often the loop wakes without messages, to check the clock and the stack.
const TICK: Duration = Duration::from_millis(50);

/// Runs the pipeline benchmark: one run per scheduling variant of `--scheduling` (with the
/// launch file's settings, then without, by default), each in a fresh domain, with `--load`
/// busy threads spinning through all of them. With `--attach` it measures the stack running in
/// `domain` once. Writes `--json` and `--svg` (of the first run) if asked; print
/// [`PipelineComparison::table`].
pub fn run_bench_pipeline(
    args: &BenchPipelineArgs,
    domain: &Domain,
) -> Result<PipelineComparison, BenchError> {
    let settings = PipelineSettings::resolve(args)?;
    let load = CpuLoad::start(settings.load_threads);
    let mut runs = Vec::new();
    for scheduling in args.scheduling.runs(settings.attached) {
        runs.push(run_once(args, &settings, domain, scheduling)?);
    }
    drop(load);
    let comparison = PipelineComparison { runs };
    if let Some(path) = &args.json {
        write_file(path, &serde_json::to_string_pretty(&comparison)?)?;
    }
    if let (Some(path), Some(first)) = (&args.svg, comparison.runs.first()) {
        write_file(path, &render_pipeline_svg(first))?;
    }
    Ok(comparison)
}

/// One start-collect-stop of the stack (or one collection from the attached stack).
fn run_once(
    args: &BenchPipelineArgs,
    settings: &PipelineSettings,
    domain: &Domain,
    scheduling: RunScheduling,
) -> Result<PipelineReport, BenchError> {
    let cpus = std::thread::available_parallelism().map_or(1, usize::from);
    let own_domain = (!settings.attached).then(|| ScratchDomain::new("bpipe"));
    let domain = own_domain.as_deref().unwrap_or(domain);
    tracing::info!(
        domain = domain.name(),
        ?settings,
        ?scheduling,
        "bench pipeline run starting"
    );

    // The bench's ports exist before the stack starts, so no early message is missed; they are
    // dropped before the stack is stopped. On an error the stack is stopped by its Drop.
    let mut channels = PipelineChannels::open(domain)?;
    let mut stack = match &own_domain {
        Some(_) => Some(Stack::start(
            &harvest_exe(args)?,
            domain,
            args.launch.as_deref(),
            settings.warmup + settings.duration,
            scheduling == RunScheduling::Without,
        )?),
        None => None,
    };
    let Collected {
        tracker,
        jitters,
        channel_results,
        interrupted,
    } = channels.collect(settings, stack.as_mut())?;
    drop(channels);
    let stack_log = match stack {
        Some(stack) => {
            let log = stack.log_path.display().to_string();
            let status = stack.stop()?;
            if !status.success() {
                tracing::warn!(%status, log, "the stack ended with a failure");
            }
            Some(log)
        }
        None => None,
    };

    let leftover_files = match &own_domain {
        Some(domain) => {
            domain.remove_unused();
            harvest_ipc::cleanup::leftover_files(domain)
                .iter()
                .map(|path| path.display().to_string())
                .collect()
        }
        None => Vec::new(),
    };
    Ok(PipelineReport {
        tool: "harvest bench pipeline",
        settings: settings.clone(),
        scheduling,
        host: HostInfo {
            cpus,
            kernel: kernel_release(),
        },
        domain: domain.name().to_owned(),
        interrupted,
        hops: Stage::HOPS
            .iter()
            .map(|&stage| StageResult::new(stage, tracker.summary(stage)))
            .collect(),
        end_to_end: Stage::END_TO_END
            .iter()
            .map(|&stage| StageResult::new(stage, tracker.summary(stage)))
            .collect(),
        control_loop: jitters,
        channels: channel_results,
        stack_log,
        leftover_files,
    })
}

fn harvest_exe(args: &BenchPipelineArgs) -> Result<PathBuf, BenchError> {
    match &args.harvest_exe {
        Some(path) => Ok(path.clone()),
        None => std::env::current_exe().map_err(|source| BenchError::Spawn {
            exe: PathBuf::from("<current exe>"),
            source,
        }),
    }
}

/// What one subscription saw.
#[derive(Debug, Default)]
struct ChannelTally {
    received: u64,
    first_publish_ns: Option<u64>,
    last_publish_ns: u64,
    delivery: Samples,
    dropped_at_start: u64,
}

impl ChannelTally {
    fn on_message(&mut self, publish_ns: u64, recv_ns: u64, recording: bool) {
        if !recording {
            return;
        }
        self.received += 1;
        self.first_publish_ns.get_or_insert(publish_ns);
        self.last_publish_ns = publish_ns;
        self.delivery.push(recv_ns.saturating_sub(publish_ns));
    }

    fn result<T: Payload>(&self, subscriber: &Subscriber<T>) -> ChannelResult {
        let span_ns = self
            .first_publish_ns
            .map_or(0, |first| self.last_publish_ns.saturating_sub(first));
        ChannelResult {
            topic: subscriber.channel().spec.topic,
            received: self.received,
            rate_hz: if span_ns > 0 {
                (self.received.saturating_sub(1)) as f64 / (span_ns as f64 * 1e-9)
            } else {
                0.0
            },
            dropped: subscriber
                .dropped_count()
                .saturating_sub(self.dropped_at_start),
            delivery: self.delivery.summary(),
        }
    }
}

/// Receives every message waiting on `subscriber`, oldest first.
fn drain<T: Payload>(
    subscriber: &Subscriber<T>,
    tally: &mut ChannelTally,
    recording: bool,
    mut each: impl FnMut(&T),
) -> Result<(), BenchError> {
    while let Some(sample) = subscriber.receive()? {
        let recv_ns = MonotonicClock::read_ns();
        tally.on_message(sample.header().publish_ns, recv_ns, recording);
        each(&sample);
    }
    Ok(())
}

/// What one collection produced.
struct Collected {
    tracker: PipelineTracker,
    jitters: Vec<JitterResult>,
    channel_results: Vec<ChannelResult>,
    /// SIGINT/SIGTERM ended it early.
    interrupted: bool,
}

/// The bench's subscriptions (the context last, so it is dropped last).
struct PipelineChannels {
    /// The device's frames; None when the channel has no subscriber slot left (it allows two:
    /// the driver and one observer, e.g. a recorder of the hardware layer).
    device_frames: Option<Subscriber<harvest_ipc::payloads::RgbdFrame>>,
    frames: Subscriber<harvest_ipc::payloads::RgbdFrame>,
    detections: Subscriber<harvest_ipc::payloads::AppleDetections>,
    targets: [Subscriber<harvest_ipc::payloads::ArmTarget>; 2],
    commands: [Subscriber<harvest_ipc::payloads::ArmCommand>; 2],
    states: [Subscriber<harvest_ipc::payloads::ArmState>; 2],
    /// The vacuum supervisor's 200 Hz loop publishes its state once per tick.
    vacuum_states: Subscriber<harvest_ipc::payloads::VacuumState>,
    _context: Context,
}

impl PipelineChannels {
    fn open(domain: &Domain) -> Result<Self, BenchError> {
        let context = Context::new(domain, "bench-pipeline")?;
        // Small messages: the largest buffer, so a briefly descheduled bench loses nothing.
        // Frames: the default buffer (only headers are read; slots are released at once).
        const LARGE: usize = usize::MAX;
        let [one, two] = ArmId::ALL.map(ArmId::index);
        let device_frames = match context.subscriber(HW_CAMERA_RGBD) {
            Ok(subscriber) => Some(subscriber),
            Err(error) => {
                tracing::warn!(%error, "not observing the camera device: its hop has no data");
                None
            }
        };
        Ok(Self {
            device_frames,
            frames: context.subscriber(CAMERA_RGBD)?,
            detections: context.subscriber_with_buffer(PERCEPTION_APPLES, LARGE)?,
            targets: [
                context.subscriber_with_buffer(ARM_TARGET[one], LARGE)?,
                context.subscriber_with_buffer(ARM_TARGET[two], LARGE)?,
            ],
            commands: [
                context.subscriber_with_buffer(ARM_COMMAND[one], LARGE)?,
                context.subscriber_with_buffer(ARM_COMMAND[two], LARGE)?,
            ],
            states: [
                context.subscriber_with_buffer(ARM_STATE[one], LARGE)?,
                context.subscriber_with_buffer(ARM_STATE[two], LARGE)?,
            ],
            vacuum_states: context.subscriber_with_buffer(VACUUM_STATE, LARGE)?,
            _context: context,
        })
    }

    /// Waits for messages until warm-up + duration have passed (or a signal), feeding them in
    /// pipeline order to the tracker, the jitter trackers and the channel tallies.
    fn collect(
        &mut self,
        settings: &PipelineSettings,
        mut stack: Option<&mut Stack>,
    ) -> Result<Collected, BenchError> {
        let waiter = Waiter::new()?;
        let _device_guard = match &self.device_frames {
            Some(subscriber) => Some(waiter.attach_listener(subscriber.listener())?),
            None => None,
        };
        let _guards = [
            waiter.attach_listener(self.frames.listener())?,
            waiter.attach_listener(self.detections.listener())?,
            waiter.attach_listener(self.targets[0].listener())?,
            waiter.attach_listener(self.targets[1].listener())?,
            waiter.attach_listener(self.commands[0].listener())?,
            waiter.attach_listener(self.commands[1].listener())?,
            waiter.attach_listener(self.states[0].listener())?,
            waiter.attach_listener(self.states[1].listener())?,
            waiter.attach_listener(self.vacuum_states.listener())?,
        ];
        let _tick = waiter.attach_interval(TICK)?;

        let mut tracker = PipelineTracker::new();
        let mut device_tally = ChannelTally::default();
        // Channel tallies in the order of [`Self::all_results`].
        let mut tallies: [ChannelTally; 8] = Default::default();
        let mut command_periods: [PeriodTracker; 2] = Default::default();
        let mut state_periods: [PeriodTracker; 2] = Default::default();
        let mut vacuum_periods = PeriodTracker::default();
        let mut vacuum_tally = ChannelTally::default();
        let start = Instant::now();
        let record_from = start + settings.warmup;
        let end = record_from + settings.duration;
        let mut recording = false;
        let channels = &*self;
        let run_end = waiter.run(|_attachment| -> Result<Flow, BenchError> {
            let now = Instant::now();
            if !recording && now >= record_from {
                recording = true;
                tracker.start_recording();
                for (tally, dropped) in tallies.iter_mut().zip(channels.dropped_counts()) {
                    tally.dropped_at_start = dropped;
                }
                if let Some(subscriber) = &channels.device_frames {
                    device_tally.dropped_at_start = subscriber.dropped_count();
                }
                vacuum_tally.dropped_at_start = channels.vacuum_states.dropped_count();
                tracing::info!("warm-up over: collecting");
            }
            let [
                t_frames,
                t_detections,
                t_target1,
                t_target2,
                t_cmd1,
                t_cmd2,
                t_state1,
                t_state2,
            ] = &mut tallies;
            if let Some(subscriber) = &channels.device_frames {
                drain(subscriber, &mut device_tally, recording, |frame| {
                    tracker.on_device_frame(frame.header());
                })?;
            }
            drain(&channels.frames, t_frames, recording, |frame| {
                tracker.on_frame(frame.header());
            })?;
            drain(&channels.detections, t_detections, recording, |set| {
                tracker.on_detections(
                    &set.header,
                    set.source_frame_seq,
                    set.source_capture_ns,
                    set.processing_ns,
                );
            })?;
            for (arm, tally) in [t_target1, t_target2].into_iter().enumerate() {
                drain(&channels.targets[arm], tally, recording, |target| {
                    tracker.on_target(
                        arm,
                        &target.header,
                        target.apple_id,
                        target.source_capture_ns,
                    );
                })?;
            }
            for (arm, tally) in [t_cmd1, t_cmd2].into_iter().enumerate() {
                let periods = &mut command_periods[arm];
                drain(&channels.commands[arm], tally, recording, |command| {
                    periods.on_message(&command.header, recording);
                    tracker.on_command(
                        arm,
                        &command.header,
                        command.apple_id,
                        command.source_capture_ns,
                    );
                })?;
            }
            for (arm, tally) in [t_state1, t_state2].into_iter().enumerate() {
                let periods = &mut state_periods[arm];
                drain(&channels.states[arm], tally, recording, |state| {
                    periods.on_message(&state.header, recording);
                })?;
            }
            drain(
                &channels.vacuum_states,
                &mut vacuum_tally,
                recording,
                |state| vacuum_periods.on_message(&state.header, recording),
            )?;
            if let Some(stack) = stack.as_deref_mut() {
                stack.check_running()?;
            }
            Ok(if now >= end {
                Flow::Stop
            } else {
                Flow::Continue
            })
        });
        let interrupted = match run_end {
            Ok(RunEnd::Stopped) => false,
            Ok(RunEnd::Signal) => {
                tracing::warn!("interrupted: reporting what was collected");
                true
            }
            Err(error) => return Err(error.flatten()),
        };
        let mut jitters = Vec::new();
        for arm in ArmId::ALL {
            jitters.push(command_periods[arm.index()].result(ARM_COMMAND[arm.index()].spec.topic));
            jitters.push(state_periods[arm.index()].result(ARM_STATE[arm.index()].spec.topic));
        }
        jitters.push(vacuum_periods.result(VACUUM_STATE.spec.topic));
        let mut channel_results = Vec::new();
        if let Some(subscriber) = &self.device_frames {
            channel_results.push(device_tally.result(subscriber));
        }
        channel_results.extend(self.all_results(&tallies));
        channel_results.push(vacuum_tally.result(&self.vacuum_states));
        Ok(Collected {
            tracker,
            jitters,
            channel_results,
            interrupted,
        })
    }

    fn dropped_counts(&self) -> [u64; 8] {
        [
            self.frames.dropped_count(),
            self.detections.dropped_count(),
            self.targets[0].dropped_count(),
            self.targets[1].dropped_count(),
            self.commands[0].dropped_count(),
            self.commands[1].dropped_count(),
            self.states[0].dropped_count(),
            self.states[1].dropped_count(),
        ]
    }

    fn all_results(&self, tallies: &[ChannelTally; 8]) -> Vec<ChannelResult> {
        vec![
            tallies[0].result(&self.frames),
            tallies[1].result(&self.detections),
            tallies[2].result(&self.targets[0]),
            tallies[3].result(&self.targets[1]),
            tallies[4].result(&self.commands[0]),
            tallies[5].result(&self.commands[1]),
            tallies[6].result(&self.states[0]),
            tallies[7].result(&self.states[1]),
        ]
    }
}
