//! The control nodes (each arm, the vacuum supervisor) re-run from their tick records: every
//! tick of the live node is on its `*/ticks` channel ([`NodeTickRecord`]: the tick's time, the
//! stop and mode samples it read, what its devices answered, the stamps of every message it
//! read). The check builds this build's node, gives it at each recorded tick the same stop,
//! mode, messages (found in the recording by topic and stamps) and device answers
//! ([`crate::check::recorded_devices`]), runs the runtime's own [`Runner::tick`] at the
//! recorded time, and compares what the tick sends with what the live tick sent: a recorded
//! output belongs to the tick whose window holds its publish stamp (from the tick's time to its
//! record's publish stamp), so each tick is compared with its own messages. A process restart
//! (the tick count back at 1) starts a fresh node, as the live restart did.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use harvest_ipc::catalogue::{Channel, OPERATOR_MODE, SAFETY_VIOLATION};
use harvest_ipc::codec::decode_prefix;
use harvest_ipc::payload::boxed_zeroed;
use harvest_ipc::payloads::{
    MODE_SLOT, NodeTickRecord, OperatorModeState, SafetyViolation, StopHeard,
};
use harvest_ipc::{Header, Payload};
use harvest_node::{
    InputVisitor, Inputs, LatestInPlace, Loaned, Node, OutputVisitor, Outputs, Runner,
    RunnerConfig, Transport,
    ports::{Drain, Latest, Out},
};
use harvest_recording::payload_codec::decode_scanned;
use harvest_recording::scan::ScannedMessage;
use harvest_robot_model::ModeSource;

use crate::check::json_diff::PUBLISHER_STAMPS;
use crate::check::recorded_devices::RecordedDevices;
use crate::check::recorded_inputs::NoFailure;
use crate::check::report::{ChannelCheck, CheckError};
use crate::check::scan_recording::{scan, undecodable};

/// Whether a recorded message (topic, encoded payload) on one of a node's output channels was
/// written by that node (channels with several writers: `harvest/events`,
/// `vacuum/valve_request`).
pub type Owns = fn(&str, &[u8]) -> bool;

/// Builds a fresh node and its recorded devices.
pub type BuildNode<N> = Box<dyn Fn() -> Result<(N, <N as Node>::Devices), CheckError>>;

/// One control node to re-run: how to build it, where its records are.
pub struct ControlNode<N: Node> {
    /// Its name in the report (`arm1`, `vacuum`).
    pub name: &'static str,
    /// Its tick records' channel.
    pub ticks: Channel<NodeTickRecord>,
    /// A fresh node and its recorded devices, once per run of the process in the recording.
    pub build: BuildNode<N>,
    /// The live process's limit of failed device reads in a row.
    pub max_read_failures: u32,
    pub owns: Owns,
}

/// What the re-run of one control node found.
pub struct ControlCheck {
    pub name: &'static str,
    /// Ticks re-run, and ticks recorded before the recording holds the node's start (a process
    /// started before the recorder): not re-run.
    pub ticks_rerun: u64,
    pub ticks_before_start: u64,
    /// Ticks re-run (to build the node's state) whose outputs are not compared: they began
    /// before the recorder heard the node's channels, or after the last message of the node
    /// it recorded (it stopped first).
    pub ticks_before_recorder: u64,
    pub ticks_after_recorder: u64,
    /// Ticks missing between two recorded ones (the recorder lost their records): the
    /// re-run steps over them, so a difference after a gap may come from it.
    pub ticks_lost: u64,
    /// The re-run node ended its run at a tick after which the live one went on (a
    /// difference: tick number and error), and the ticks not re-run after it.
    pub rerun_failure: Option<String>,
    pub ticks_after_failure: u64,
    /// Messages a tick read that the recording does not hold, and ticks that read more than a
    /// record names.
    pub inputs_missing: u64,
    pub inputs_incomplete_ticks: u64,
    /// One comparison per output channel, in the node's order.
    pub channels: Vec<ChannelCheck>,
    pub recorded_span_ns: u64,
    pub rerun_wall_s: f64,
}

impl ControlCheck {
    pub fn differs(&self) -> bool {
        self.rerun_failure.is_some() || self.channels.iter().any(ChannelCheck::differs)
    }
}

impl std::fmt::Display for ControlCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "check: {} re-run on its {} recorded ticks",
            self.name, self.ticks_rerun
        )?;
        if self.ticks_before_start > 0 {
            writeln!(
                f,
                "    {} tick(s) not re-run: recorded before the recording holds the process's first tick",
                self.ticks_before_start
            )?;
        }
        if self.ticks_before_recorder > 0 {
            writeln!(
                f,
                "    {} tick(s) re-run but not compared: they began before the recorder heard the node's channels",
                self.ticks_before_recorder
            )?;
        }
        if self.ticks_after_recorder > 0 {
            writeln!(
                f,
                "    {} tick(s) at the end re-run but not compared: after the last message of the node the recorder kept",
                self.ticks_after_recorder
            )?;
        }
        if self.ticks_lost > 0 {
            writeln!(
                f,
                "    {} tick record(s) missing from the recording (stepped over: a difference after a gap may come from it)",
                self.ticks_lost
            )?;
        }
        if let Some(failure) = &self.rerun_failure {
            writeln!(
                f,
                "    the re-run node stopped where the live one went on: {failure}; {} later tick(s) not re-run",
                self.ticks_after_failure
            )?;
        }
        if self.inputs_missing > 0 || self.inputs_incomplete_ticks > 0 {
            writeln!(
                f,
                "    {} message(s) read by the live node not in the recording; {} tick(s) read more than their record names",
                self.inputs_missing, self.inputs_incomplete_ticks
            )?;
        }
        for channel in &self.channels {
            write!(f, "{channel}")?;
        }
        Ok(())
    }
}

/// A re-run control node of any type.
pub trait ControlRerun {
    fn name(&self) -> &'static str;
    fn ticks_topic(&self) -> &'static str;
    /// The topics the node reads and those it writes, in its visiting order.
    fn topics(&self) -> Result<(Vec<&'static str>, Vec<&'static str>), CheckError>;
    fn owns(&self) -> Owns;
    /// `None` when the recording holds none of the node's tick records.
    fn rerun(
        &self,
        recorded: &Recorded,
        tolerance: Option<f64>,
    ) -> Result<Option<ControlCheck>, CheckError>;
}

/// A recorded output message.
struct RecordedOutput {
    log_time_ns: u64,
    publish_ns: u64,
    bytes: Vec<u8>,
}

/// One node's tick records as recorded, and the topics it writes.
#[derive(Default)]
struct NodeRecords {
    /// In recorded order, with the log time of each.
    records: Vec<NodeTickRecord>,
    log_times_ns: Vec<u64>,
    /// When the recorder received the first record, on the stack clock (its publish stamp
    /// plus the delay between the message's publish and log times).
    first_heard_ns: Option<u64>,
    output_topics: Vec<&'static str>,
}

/// What the check reads from a recording for the control nodes and the monitor, in one pass.
#[derive(Default)]
pub struct Recorded {
    /// Per node, by its ticks topic.
    nodes: HashMap<&'static str, NodeRecords>,
    /// Input messages per topic, by (msg_seq, publish_ns).
    inputs: HashMap<&'static str, HashMap<(u64, u64), Vec<u8>>>,
    /// Output messages per (ticks topic, output topic), the node's own only.
    outputs: HashMap<(&'static str, &'static str), Vec<RecordedOutput>>,
    /// The recorded `safety/violation` messages, with their log times.
    pub violations: Vec<(u64, SafetyViolation)>,
    pub first_log_time_ns: Option<u64>,
    last_log_time_ns: u64,
}

/// Reads `files` once for every node in `nodes` and the monitor's recorded findings.
pub fn read_recording(
    files: &[PathBuf],
    nodes: &[Box<dyn ControlRerun>],
) -> Result<Recorded, CheckError> {
    let mut recorded = Recorded::default();
    let mut input_topics: Vec<&'static str> = vec![OPERATOR_MODE.spec.topic];
    let mut output_topics: Vec<(&'static str, &'static str, Owns)> = Vec::new();
    for node in nodes {
        let (inputs, outputs) = node.topics()?;
        input_topics.extend(inputs);
        for &topic in &outputs {
            output_topics.push((node.ticks_topic(), topic, node.owns()));
        }
        recorded.nodes.insert(
            node.ticks_topic(),
            NodeRecords {
                output_topics: outputs,
                ..NodeRecords::default()
            },
        );
    }
    for topic in &input_topics {
        recorded.inputs.entry(topic).or_default();
    }
    scan(files, |message: &ScannedMessage<'_>| {
        let topic = message.channel.topic.as_str();
        let log_time_ns = message.log_time;
        recorded.first_log_time_ns.get_or_insert(log_time_ns);
        recorded.last_log_time_ns = recorded.last_log_time_ns.max(log_time_ns);
        if let Some(node) = recorded.nodes.get_mut(topic) {
            let mut record = NodeTickRecord::default();
            NodeTickRecord::decode_into(message.data, &mut record)
                .map_err(|_| undecodable(topic, log_time_ns))?;
            if record.emergency_stop_heard.get().is_err() || record.device_read.get().is_err() {
                return Err(undecodable(topic, log_time_ns));
            }
            let delay_ns = log_time_ns.saturating_sub(message.publish_time);
            node.first_heard_ns
                .get_or_insert(record.header.publish_ns.saturating_add(delay_ns));
            node.records.push(record);
            node.log_times_ns.push(log_time_ns);
        }
        if topic == SAFETY_VIOLATION.spec.topic {
            let value = decode_scanned(SAFETY_VIOLATION, message)
                .ok_or_else(|| undecodable(topic, log_time_ns))?;
            recorded.violations.push((log_time_ns, value));
        }
        if let Some(messages) = recorded.inputs.get_mut(topic) {
            let header = header_of(message.data).ok_or_else(|| undecodable(topic, log_time_ns))?;
            messages.insert((header.msg_seq, header.publish_ns), message.data.to_vec());
        }
        for &(ticks_topic, output_topic, owns) in &output_topics {
            if output_topic == topic && owns(topic, message.data) {
                let header =
                    header_of(message.data).ok_or_else(|| undecodable(topic, log_time_ns))?;
                recorded
                    .outputs
                    .entry((ticks_topic, output_topic))
                    .or_default()
                    .push(RecordedOutput {
                        log_time_ns,
                        publish_ns: header.publish_ns,
                        bytes: message.data.to_vec(),
                    });
            }
        }
        Ok(())
    })?;
    Ok(recorded)
}

/// The header every payload's encoding starts with.
fn header_of(bytes: &[u8]) -> Option<Header> {
    decode_prefix::<Header>(bytes)
        .ok()
        .map(|(header, _)| header)
}

/// Visits a node's slots and lists their topics.
struct Topics(Vec<&'static str>);

impl InputVisitor for Topics {
    type Error = std::convert::Infallible;
    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Latest<T>,
    ) -> Result<(), Self::Error> {
        self.0.push(channel.spec.topic);
        Ok(())
    }
    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Drain<T>,
    ) -> Result<(), Self::Error> {
        self.0.push(channel.spec.topic);
        Ok(())
    }
    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut LatestInPlace<T>,
    ) -> Result<(), Self::Error> {
        self.0.push(channel.spec.topic);
        Ok(())
    }
}

impl OutputVisitor for Topics {
    type Error = std::convert::Infallible;
    fn output<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Out<T>,
    ) -> Result<(), Self::Error> {
        self.0.push(channel.spec.topic);
        Ok(())
    }
    fn loaned<T: Payload + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Loaned<T>,
    ) -> Result<(), Self::Error> {
        self.0.push(channel.spec.topic);
        Ok(())
    }
}

/// A recorded message decoded as `T`.
pub(crate) fn decode<T: Payload + Copy>(bytes: &[u8]) -> Option<T> {
    let mut value = boxed_zeroed::<T>();
    T::decode_into(bytes, &mut value).ok()?;
    Some(*value)
}

/// One output topic of a node: its recorded messages, each with the index of its tick record
/// (`None`: outside every recorded tick), sorted by tick; how far the re-run has come; what it
/// found.
struct TopicComparison<'a> {
    recorded: Vec<(Option<usize>, &'a RecordedOutput)>,
    cursor: usize,
    check: ChannelCheck,
    /// Messages compared in total: recorded, and sent by the re-run.
    totals: (u64, u64),
}

impl TopicComparison<'_> {
    /// Where the recorded messages of tick `tick` are (skipping earlier ones, of ticks not
    /// re-run).
    fn take(&mut self, tick: usize) -> std::ops::Range<usize> {
        let list = &self.recorded;
        while self.cursor < list.len() && list[self.cursor].0.is_none_or(|index| index < tick) {
            self.cursor += 1;
        }
        let start = self.cursor;
        while self.cursor < list.len() && list[self.cursor].0 == Some(tick) {
            self.cursor += 1;
        }
        start..self.cursor
    }
}

/// The comparison of one node's outputs, tick by tick.
struct Comparison<'a> {
    /// One per output topic, in the node's order.
    topics: Vec<TopicComparison<'a>>,
    tolerance: Option<f64>,
    start_ns: u64,
    /// The tick being re-run (index of its record) and its record's log time.
    tick: usize,
    tick_log_ns: u64,
    /// Whether the recorder heard the tick's outputs (false before it heard the node at all).
    heard: bool,
    undecodable: Option<CheckError>,
}

impl Comparison<'_> {
    fn compare<T: Payload + Copy>(&mut self, topic: &'static str, sent: &[T]) {
        let (tick, tolerance, start_ns, tick_log_ns) =
            (self.tick, self.tolerance, self.start_ns, self.tick_log_ns);
        let Some(this) = self.topics.iter_mut().find(|t| t.check.topic == topic) else {
            return;
        };
        let taken = this.take(tick);
        if !self.heard {
            return;
        }
        let recorded = &this.recorded[taken];
        this.totals.0 += recorded.len() as u64;
        this.totals.1 += sent.len() as u64;
        for index in 0..recorded.len().max(sent.len()) {
            let recorded_message = match recorded.get(index) {
                Some((_, output)) => match decode::<T>(&output.bytes) {
                    Some(value) => Some((output.log_time_ns, value.to_json())),
                    None if index < sent.len() => {
                        self.undecodable
                            .get_or_insert(undecodable(topic, output.log_time_ns));
                        return;
                    }
                    None => Some((output.log_time_ns, serde_json::Value::Null)),
                },
                None => None,
            };
            // A message only the re-run sent is placed at its tick, after those compared.
            this.check.compare_message(
                recorded_message,
                sent.get(index).map(Payload::to_json),
                &PUBLISHER_STAMPS,
                tolerance,
                start_ns,
                tick_log_ns,
            );
        }
    }
}

/// One recorded tick as the runner's transport: the stop, the mode and the messages the live
/// tick read; what the tick sends is compared at once.
struct RecordedTick<'a, 'b> {
    record: &'a NodeTickRecord,
    inputs: &'a HashMap<&'static str, HashMap<(u64, u64), Vec<u8>>>,
    missing: &'b mut u64,
    comparison: &'b mut Comparison<'a>,
}

impl<'a> RecordedTick<'a, '_> {
    /// The messages the live tick read into `slot`, from the recording (a message the
    /// recording lacks is counted and left out).
    fn messages<T: Payload + Copy>(
        &mut self,
        slot: u8,
        topic: &'static str,
    ) -> impl Iterator<Item = T> + use<'a, '_, T> {
        let (record, inputs) = (self.record, self.inputs);
        let missing = &mut *self.missing;
        record
            .inputs
            .as_slice()
            .iter()
            .filter(move |input| input.slot == slot)
            .filter_map(move |input| {
                let found = inputs
                    .get(topic)
                    .and_then(|messages| messages.get(&(input.msg_seq, input.publish_ns)))
                    .and_then(|bytes| decode::<T>(bytes));
                *missing += u64::from(found.is_none());
                found
            })
    }
}

struct Fill<'t, 'a, 'b> {
    tick: &'t mut RecordedTick<'a, 'b>,
    slot: u8,
}

impl Fill<'_, '_, '_> {
    fn next_slot(&mut self) -> u8 {
        let slot = self.slot;
        self.slot = self.slot.saturating_add(1);
        slot
    }
}

impl InputVisitor for Fill<'_, '_, '_> {
    type Error = NoFailure;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Latest<T>,
    ) -> Result<(), NoFailure> {
        let index = self.next_slot();
        slot.begin();
        for message in self.tick.messages::<T>(index, channel.spec.topic) {
            slot.set(message);
        }
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Drain<T>,
    ) -> Result<(), NoFailure> {
        let index = self.next_slot();
        slot.begin();
        for message in self.tick.messages::<T>(index, channel.spec.topic) {
            slot.push(message);
        }
        Ok(())
    }

    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        _slot: &mut LatestInPlace<T>,
    ) -> Result<(), NoFailure> {
        // The control nodes read no large messages.
        self.next_slot();
        Ok(())
    }
}

struct Compare<'t, 'a, 'b> {
    tick: &'t mut RecordedTick<'a, 'b>,
}

impl OutputVisitor for Compare<'_, '_, '_> {
    type Error = NoFailure;

    fn output<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Out<T>,
    ) -> Result<(), NoFailure> {
        self.tick
            .comparison
            .compare(channel.spec.topic, slot.pending());
        slot.flush(|_| Ok(()))
    }

    fn loaned<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Loaned<T>,
    ) -> Result<(), NoFailure> {
        let _ = slot.take_send::<()>();
        Ok(())
    }
}

impl Transport for RecordedTick<'_, '_> {
    type Error = NoFailure;

    fn emergency_stop(&mut self) -> Result<Option<bool>, NoFailure> {
        Ok(match self.record.emergency_stop_heard.get() {
            Ok(StopHeard::Engaged) => Some(true),
            Ok(StopHeard::Released) => Some(false),
            // Unknown codes are refused when the recording is read.
            Ok(StopHeard::Nothing) | Err(_) => None,
        })
    }

    fn operator_mode(&mut self) -> Result<Option<OperatorModeState>, NoFailure> {
        Ok(self
            .messages::<OperatorModeState>(MODE_SLOT, OPERATOR_MODE.spec.topic)
            .last())
    }

    fn read_inputs<I: Inputs>(&mut self, inputs: &mut I) -> Result<(), NoFailure> {
        inputs.visit(&mut Fill {
            tick: self,
            slot: 0,
        })
    }

    fn publish<O: Outputs>(&mut self, outputs: &mut O) -> Result<(), NoFailure> {
        outputs.visit(&mut Compare { tick: self })
    }
}

impl<N> ControlRerun for ControlNode<N>
where
    N: Node,
    N::Devices: RecordedDevices,
{
    fn name(&self) -> &'static str {
        self.name
    }

    fn ticks_topic(&self) -> &'static str {
        self.ticks.spec.topic
    }

    fn topics(&self) -> Result<(Vec<&'static str>, Vec<&'static str>), CheckError> {
        let (node, _) = (self.build)()?;
        let (mut inputs, mut outputs) = (Topics(Vec::new()), Topics(Vec::new()));
        let Ok(()) = Inputs::visit(&mut node.inputs(), &mut inputs);
        let Ok(()) = Outputs::visit(&mut node.outputs(), &mut outputs);
        Ok((inputs.0, outputs.0))
    }

    fn owns(&self) -> Owns {
        self.owns
    }

    fn rerun(
        &self,
        recorded: &Recorded,
        tolerance: Option<f64>,
    ) -> Result<Option<ControlCheck>, CheckError> {
        let Some(node) = recorded.nodes.get(self.ticks_topic()) else {
            return Ok(None);
        };
        let (records, log_times) = (&node.records, &node.log_times_ns);
        let name = self.name;
        if records.is_empty() {
            return Ok(None);
        }
        // The recorder opens the tick channels' taps after every other (catalogue order):
        // a tick that began after it heard the first record had its outputs heard too.
        let heard_from_ns = node.first_heard_ns.unwrap_or(u64::MAX);
        let start_ns = recorded.first_log_time_ns.unwrap_or_default();
        // Each recorded output with the tick whose window holds its publish stamp.
        let topics: Vec<TopicComparison> = node
            .output_topics
            .iter()
            .map(|&topic| {
                let list = recorded
                    .outputs
                    .get(&(self.ticks_topic(), topic))
                    .map_or(&[][..], Vec::as_slice);
                let mut entries: Vec<(Option<usize>, &RecordedOutput)> = list
                    .iter()
                    .map(|output| {
                        let index =
                            records.partition_point(|r| r.header.publish_ns < output.publish_ns);
                        let tick = records
                            .get(index)
                            .filter(|record| record.header.capture_ns <= output.publish_ns)
                            .map(|_| index);
                        (tick, output)
                    })
                    .collect();
                entries
                    .sort_by_key(|(tick, output)| (tick.unwrap_or(usize::MAX), output.publish_ns));
                TopicComparison {
                    recorded: entries,
                    cursor: 0,
                    check: ChannelCheck::new(topic),
                    totals: (0, 0),
                }
            })
            .collect();
        // The recorder may stop between a tick's outputs and its record, or part-way through
        // them: the tick of the last output it kept, and those after it, are not compared.
        let heard_until_ns = topics
            .iter()
            .flat_map(|topic| &topic.recorded)
            .filter_map(|(tick, _)| *tick)
            .max()
            .map_or(0, |last| records[last].header.capture_ns);
        let mut comparison = Comparison {
            topics,
            tolerance,
            start_ns,
            tick: 0,
            tick_log_ns: 0,
            heard: false,
            undecodable: None,
        };
        let mut check = ControlCheck {
            name,
            ticks_rerun: 0,
            ticks_before_start: 0,
            ticks_before_recorder: 0,
            ticks_after_recorder: 0,
            ticks_lost: 0,
            rerun_failure: None,
            ticks_after_failure: 0,
            inputs_missing: 0,
            inputs_incomplete_ticks: 0,
            channels: Vec::new(),
            recorded_span_ns: recorded.last_log_time_ns.saturating_sub(start_ns),
            rerun_wall_s: 0.0,
        };
        let started = Instant::now();
        // Ticks re-run with their outputs compared.
        let mut rerun_ticks = vec![false; records.len()];
        let mut runner: Option<Runner<N>> = None;
        let mut previous_tick = 0u64;
        // The re-run failed where the live node went on: no re-run until the next restart.
        let mut failed = false;
        for (index, record) in records.iter().enumerate() {
            if record.tick <= previous_tick || (runner.is_none() && record.tick == 1) {
                // The process (re)started: a fresh node, as the live restart had.
                failed = false;
                runner = if record.tick == 1 {
                    let (node, devices) = (self.build)()?;
                    let mode_source = if record.without_operator == 1 {
                        ModeSource::WithoutOperator
                    } else {
                        ModeSource::Executive
                    };
                    Some(Runner::new(
                        node,
                        devices,
                        RunnerConfig {
                            max_read_failures: self.max_read_failures,
                            mode_source,
                        },
                    ))
                } else {
                    None
                };
            } else if record.tick > previous_tick + 1 && runner.is_some() {
                check.ticks_lost += record.tick - previous_tick - 1;
            }
            previous_tick = record.tick;
            let Some(live) = runner.as_mut() else {
                if failed {
                    check.ticks_after_failure += 1;
                } else {
                    check.ticks_before_start += 1;
                }
                continue;
            };
            live.devices_mut()
                .answer(record)
                .map_err(|error| CheckError::Node(format!("{name}: {error}")))?;
            check.inputs_incomplete_ticks += u64::from(record.inputs_complete == 0);
            comparison.tick = index;
            let (before, after) = (
                record.header.capture_ns < heard_from_ns,
                record.header.capture_ns >= heard_until_ns,
            );
            comparison.heard = !before && !after;
            check.ticks_before_recorder += u64::from(before);
            check.ticks_after_recorder += u64::from(after && !before);
            comparison.tick_log_ns = log_times.get(index).copied().unwrap_or(start_ns);
            let mut transport = RecordedTick {
                record,
                inputs: &recorded.inputs,
                missing: &mut check.inputs_missing,
                comparison: &mut comparison,
            };
            let outcome = live.tick(&mut transport, record.header.capture_ns);
            check.ticks_rerun += 1;
            rerun_ticks[index] = comparison.heard;
            if let Some(error) = comparison.undecodable.take() {
                return Err(error);
            }
            if let Err(error) = outcome {
                // The live process published this record and ended here too when no later
                // tick of the same run follows; otherwise the re-run differs.
                let live_went_on = records
                    .get(index + 1)
                    .is_some_and(|next| next.tick > record.tick);
                if live_went_on && check.rerun_failure.is_none() {
                    check.rerun_failure = Some(format!("tick {}: {error}", record.tick));
                }
                failed = live_went_on;
                runner = None;
            }
        }
        check.rerun_wall_s = started.elapsed().as_secs_f64();
        let mut channels = Vec::with_capacity(comparison.topics.len());
        for topic in comparison.topics {
            let mut channel = topic.check;
            let (recorded_count, rerun_count) = topic.totals;
            if recorded_count != rerun_count {
                channel.count_mismatch = Some((recorded_count, rerun_count));
            }
            let outside = topic
                .recorded
                .iter()
                .filter(|(tick, _)| tick.is_none_or(|index| !rerun_ticks[index]))
                .count();
            if outside > 0 {
                channel.not_rerun = outside as u64;
                channel.not_rerun_reason = Some(
                    "sent outside the ticks re-run and compared (before the recorder heard the node or after it stopped, the process's last messages at exit, or after the re-run stopped)"
                        .to_owned(),
                );
            }
            channels.push(channel);
        }
        check.channels = channels;
        Ok(Some(check))
    }
}
