//! A fake valve board firmware running in a thread on the far end of a pseudo-terminal, so the
//! real serial driver can be tested end to end without an Arduino.
//!
//! Always compiled on Unix (no cargo feature) so any crate's tests can use it.
//!
//! It speaks the protocol of `hw/VALVE_PROTOCOL.md`, moves its valves over a configurable
//! actuation time, produces noisy pressures from a crude flow model, and injects faults on
//! demand: garbage between replies, silence, late replies, corrupt checksums, a stuck valve,
//! unsolicited fault lines, and a disconnect (closing the pty master).
//!
//! Pressure model (a test fixture, not a physics simulation): valve `2k-1` is taken as arm
//! `k`'s gate to the source and valve `2k` as its gate to atmosphere ([dual-arm Fig. 3] pairs
//! them per arm without fixing the roles); with `f` the opening fraction of each gate,
//! `source = S0 (1 - 0.3 (f1 + f3))` and `arm_k = source f(2k-1) (1 - f(2k))`, plus Gaussian
//! noise.

use super::line_assembler::LineAssembler;
use super::protocol::{
    MessageError, Reply, Request, Status, Tag, decode_frame, decode_request, encode_fault,
    encode_reply,
};
use super::serial::{SerialBoardConfig, SerialValveBoard};
use super::types::{
    BoardFault, Heartbeat, PressureReadings, VALVE_COUNT, ValveId, ValveState, ValveStates,
};
use super::{SerialBoardError, ValveBoard};
use crate::error_kind::{DeviceError, ErrorKind};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serialport::{SerialPort, TTYPort};
use std::io::{self, Read, Write};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tracing::{debug, trace};

/// Behaviour of the fake board.
#[derive(Debug, Clone, PartialEq)]
pub struct FakeBoardConfig {
    /// Time a valve takes between end stops, ms (the real gates take under 1000 ms; tests
    /// use less to run fast).
    pub actuation_ms: u32,
    /// How long a commanded valve may fail to move before the board declares it stuck, ms.
    pub stuck_detect_ms: u32,
    /// Source vacuum with every gate closed, mmH2O (below the 2500 mmH2O peak).
    pub source_vacuum_mmh2o: f32,
    /// Standard deviation of the Gaussian noise added to each pressure reading, mmH2O.
    pub pressure_noise_mmh2o: f32,
    /// Seed of the noise and garbage generator (runs are reproducible).
    pub seed: u64,
    /// Period of the firmware loop (valve motion, fault lines, control checks), ms.
    pub tick_ms: u32,
}

impl Default for FakeBoardConfig {
    fn default() -> Self {
        FakeBoardConfig {
            actuation_ms: 600,
            stuck_detect_ms: 1500,
            source_vacuum_mmh2o: 2400.0,
            pressure_noise_mmh2o: 5.0,
            seed: 0x5EED_0003,
            tick_ms: 2,
        }
    }
}

/// How the fake answers requests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultMode {
    /// Answer every request correctly.
    Healthy,
    /// Send noise before each reply: random bytes, a cut frame, a line with a bad checksum and
    /// an overlong line, then the correct reply.
    Garbage,
    /// Read requests and never answer.
    Silent,
    /// Answer with a wrong checksum.
    CorruptChecksum,
    /// Answer correctly but only after `delay_ms` (the firmware loop stalls meanwhile).
    Late {
        /// Delay before the reply, ms.
        delay_ms: u32,
    },
}

/// Counters kept by the fake board.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FakeBoardStats {
    /// Requests with a valid checksum received (answered or not).
    pub requests: u64,
    /// Replies written (including corrupt ones).
    pub replies: u64,
    /// Lines dropped because of framing or checksum errors.
    pub rejected_lines: u64,
}

/// Errors of [`FakeBoard::spawn`].
#[derive(Debug, thiserror::Error)]
pub enum FakeBoardError {
    /// The pseudo-terminal pair could not be created.
    #[error("cannot create pseudo-terminal for the fake valve board: {0}")]
    Pty(#[source] serialport::Error),
    /// The pty's device path is unknown.
    #[error("pseudo-terminal of the fake valve board has no device path")]
    NoPath,
    /// The firmware thread could not be started.
    #[error("cannot start the fake valve board thread: {0}")]
    Thread(#[source] io::Error),
    /// The serial driver could not connect to the fake.
    #[error("serial driver cannot connect to the fake valve board: {0}")]
    Driver(#[source] Box<super::serial::OpenError>),
}

impl DeviceError for FakeBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            FakeBoardError::Driver(e) => e.kind(),
            _ => ErrorKind::Other,
        }
    }
}

/// Shared between the test-facing handle and the firmware thread.
#[derive(Debug)]
struct Control {
    mode: FaultMode,
    /// Replies left before `mode` reverts to `Healthy`; `None` = for ever.
    mode_replies_left: Option<u32>,
    stuck: [bool; VALVE_COUNT],
    pending_faults: Vec<BoardFault>,
    stop: bool,
    stats: FakeBoardStats,
}

fn lock(control: &Mutex<Control>) -> MutexGuard<'_, Control> {
    control.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A running fake board. Dropping it stops the thread and closes the pty.
#[derive(Debug)]
pub struct FakeBoard {
    control: Arc<Mutex<Control>>,
    thread: Option<JoinHandle<()>>,
    /// The pty slave, held open so the master side does not see a hang-up before the driver
    /// opens the path; handed out by [`FakeBoard::take_port`].
    slave: Option<TTYPort>,
    port_path: String,
}

impl FakeBoard {
    /// Create a pty pair and start the firmware thread on its master side.
    pub fn spawn(config: FakeBoardConfig) -> Result<FakeBoard, FakeBoardError> {
        let (master, slave) = TTYPort::pair().map_err(FakeBoardError::Pty)?;
        let port_path = slave.name().ok_or(FakeBoardError::NoPath)?;
        let control = Arc::new(Mutex::new(Control {
            mode: FaultMode::Healthy,
            mode_replies_left: None,
            stuck: [false; VALVE_COUNT],
            pending_faults: Vec::new(),
            stop: false,
            stats: FakeBoardStats::default(),
        }));
        let thread_control = Arc::clone(&control);
        let thread = std::thread::Builder::new()
            .name("fake-valve-board".to_owned())
            .spawn(move || Firmware::new(master, thread_control, config).run())
            .map_err(FakeBoardError::Thread)?;
        debug!(port = %port_path, "fake valve board started");
        Ok(FakeBoard {
            control,
            thread: Some(thread),
            slave: Some(slave),
            port_path,
        })
    }

    /// Start a fake and connect the real serial driver to it by path (with the driver's
    /// handshake). `driver.path` is replaced by the fake's pty path.
    pub fn spawn_with_driver(
        config: FakeBoardConfig,
        driver: &SerialBoardConfig,
    ) -> Result<FakeBackedBoard, FakeBoardError> {
        let fake = FakeBoard::spawn(config)?;
        let driver_config = SerialBoardConfig {
            path: fake.port_path().to_owned(),
            ..driver.clone()
        };
        let driver = SerialValveBoard::open(&driver_config)
            .map_err(|e| FakeBoardError::Driver(Box::new(e)))?;
        Ok(FakeBackedBoard { driver, fake })
    }

    /// Device path of the pty slave (open it with the serial driver).
    pub fn port_path(&self) -> &str {
        &self.port_path
    }

    /// The already open pty slave, for [`SerialValveBoard::with_port`]. Once taken, closing it
    /// is seen by the fake as the host going away, and the fake stops.
    pub fn take_port(&mut self) -> Option<TTYPort> {
        self.slave.take()
    }

    /// Answer from now on according to `mode`.
    pub fn set_fault_mode(&self, mode: FaultMode) {
        let mut c = lock(&self.control);
        c.mode = mode;
        c.mode_replies_left = None;
    }

    /// Answer the next `replies` requests according to `mode`, then become healthy again.
    pub fn set_fault_mode_for(&self, mode: FaultMode, replies: u32) {
        let mut c = lock(&self.control);
        c.mode = mode;
        c.mode_replies_left = Some(replies);
    }

    /// Jam `valve`: it stops moving; once commanded to move it is declared stuck after
    /// `stuck_detect_ms`, with a `FAULT STUCK` line.
    pub fn stick_valve(&self, valve: ValveId) {
        if let Some(i) = valve.index() {
            lock(&self.control).stuck[i] = true;
        }
    }

    /// Send an unsolicited fault line, before the next reply or within one loop period.
    pub fn emit_fault(&self, fault: BoardFault) {
        lock(&self.control).pending_faults.push(fault);
    }

    /// Counters so far.
    pub fn stats(&self) -> FakeBoardStats {
        lock(&self.control).stats
    }

    /// Close the pty master (the board vanishes, as when its USB cable is pulled) and wait
    /// for the thread to end.
    pub fn disconnect(&mut self) {
        self.stop_thread();
    }

    fn stop_thread(&mut self) {
        lock(&self.control).stop = true;
        if let Some(thread) = self.thread.take()
            && thread.join().is_err()
        {
            debug!(port = %self.port_path, "fake valve board thread panicked");
        }
    }
}

impl Drop for FakeBoard {
    fn drop(&mut self) {
        self.stop_thread();
    }
}

/// The serial driver connected to its own fake board; drops the driver before the fake.
#[derive(Debug)]
pub struct FakeBackedBoard {
    /// The real driver under test.
    pub driver: SerialValveBoard,
    /// The fake on the other end of the pty.
    pub fake: FakeBoard,
}

impl ValveBoard for FakeBackedBoard {
    type Error = SerialBoardError;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error> {
        self.driver.set_valve(valve, open)
    }

    fn valve_states(&mut self) -> Result<ValveStates, Self::Error> {
        self.driver.valve_states()
    }

    fn pressures(&mut self) -> Result<PressureReadings, Self::Error> {
        self.driver.pressures()
    }

    fn close_all(&mut self) -> Result<(), Self::Error> {
        self.driver.close_all()
    }

    fn ping(&mut self) -> Result<Heartbeat, Self::Error> {
        self.driver.ping()
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        self.driver.take_faults()
    }
}

/// One simulated butterfly valve.
#[derive(Debug, Clone, Copy)]
struct SimValve {
    /// Opening fraction, 0 = closed end stop, 1 = open end stop.
    position: f32,
    target_open: bool,
    /// When the valve was last commanded to a position it is not at.
    commanded_at: Option<Instant>,
    /// Declared stuck (reported and latched).
    stuck: bool,
}

impl SimValve {
    fn target_position(&self) -> f32 {
        if self.target_open { 1.0 } else { 0.0 }
    }

    fn state(&self) -> ValveState {
        if self.stuck {
            ValveState::Stuck
        } else if self.position == self.target_position() {
            ValveState::settled(self.target_open)
        } else if self.target_open {
            ValveState::Opening
        } else {
            ValveState::Closing
        }
    }
}

/// The fake firmware's state, owned by its thread.
struct Firmware {
    port: TTYPort,
    control: Arc<Mutex<Control>>,
    config: FakeBoardConfig,
    started: Instant,
    last_step: Instant,
    valves: [SimValve; VALVE_COUNT],
    rng: SmallRng,
    noise: Option<Normal<f32>>,
    assembler: LineAssembler,
    out: Vec<u8>,
}

/// Why the firmware loop ended.
enum Exit {
    /// Asked to stop, or told to disconnect.
    Stopped,
    /// The host side closed (read or write failed).
    HostGone(io::Error),
}

impl Firmware {
    fn new(port: TTYPort, control: Arc<Mutex<Control>>, config: FakeBoardConfig) -> Firmware {
        let now = Instant::now();
        let closed = SimValve {
            position: 0.0,
            target_open: false,
            commanded_at: None,
            stuck: false,
        };
        Firmware {
            port,
            control,
            rng: SmallRng::seed_from_u64(config.seed),
            noise: Normal::new(0.0, config.pressure_noise_mmh2o.max(0.0)).ok(),
            config,
            started: now,
            last_step: now,
            valves: [closed; VALVE_COUNT],
            assembler: LineAssembler::new(),
            out: Vec::with_capacity(512),
        }
    }

    fn run(mut self) {
        let tick = Duration::from_millis(u64::from(self.config.tick_ms.max(1)));
        if let Err(error) = self.port.set_timeout(tick) {
            debug!(%error, "fake valve board cannot set its read timeout");
            return;
        }
        let exit = self.run_loop();
        match exit {
            Exit::Stopped => debug!("fake valve board stopped"),
            Exit::HostGone(error) => debug!(%error, "fake valve board: host side closed"),
        }
        // Dropping `self.port` closes the pty master: the host sees a hang-up.
    }

    fn run_loop(&mut self) -> Exit {
        let mut rx = [0u8; 256];
        loop {
            if lock(&self.control).stop {
                return Exit::Stopped;
            }
            self.step_valves();
            if let Err(error) = self.flush_faults() {
                return Exit::HostGone(error);
            }
            let n = match self.port.read(&mut rx) {
                Ok(0) => return Exit::HostGone(io::Error::from(io::ErrorKind::UnexpectedEof)),
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                    ) =>
                {
                    continue;
                }
                Err(e) => return Exit::HostGone(e),
            };
            for &byte in &rx[..n] {
                let line = match self.assembler.push(byte) {
                    None => continue,
                    Some(Err(_)) => None,
                    Some(Ok(line)) => match decode_frame(line) {
                        Ok(frame) => match frame.tag {
                            Tag::Seq(seq) => Some((seq, decode_request(frame.body))),
                            Tag::Unsolicited => None,
                        },
                        Err(_) => None,
                    },
                };
                // A corrupt or truncated request is ignored, as firmware must (its sequence
                // number cannot be trusted); the host times out and retries.
                let Some((seq, request)) = line else {
                    lock(&self.control).stats.rejected_lines += 1;
                    continue;
                };
                if let Err(error) = self.answer(seq, request) {
                    return Exit::HostGone(error);
                }
            }
        }
    }

    /// Move the valves toward their targets and latch stuck ones.
    fn step_valves(&mut self) {
        let now = Instant::now();
        let dt_ms = now.duration_since(self.last_step).as_secs_f32() * 1000.0;
        self.last_step = now;
        let rate_per_ms = 1.0 / self.config.actuation_ms.max(1) as f32;
        let jammed = lock(&self.control).stuck;
        let mut newly_stuck = [false; VALVE_COUNT];
        for (i, valve) in self.valves.iter_mut().enumerate() {
            if valve.stuck {
                continue;
            }
            let target = valve.target_position();
            if valve.position == target {
                valve.commanded_at = None;
                continue;
            }
            if jammed[i] {
                let waited_ms = valve
                    .commanded_at
                    .map(|t| now.duration_since(t).as_millis())
                    .unwrap_or(0);
                if waited_ms >= u128::from(self.config.stuck_detect_ms) {
                    valve.stuck = true;
                    newly_stuck[i] = true;
                }
                continue;
            }
            let step = dt_ms * rate_per_ms;
            valve.position = if target > valve.position {
                (valve.position + step).min(target)
            } else {
                (valve.position - step).max(target)
            };
        }
        if newly_stuck.iter().any(|&s| s) {
            let mut c = lock(&self.control);
            for (valve, _) in ValveId::ALL.iter().zip(newly_stuck).filter(|(_, s)| *s) {
                c.pending_faults.push(BoardFault::ValveStuck(*valve));
            }
        }
    }

    fn command(&mut self, index: usize, open: bool) {
        let valve = &mut self.valves[index];
        if valve.target_open != open || valve.commanded_at.is_none() {
            valve.target_open = open;
            if valve.position != valve.target_position() {
                valve.commanded_at = Some(Instant::now());
            }
        }
    }

    fn states(&self) -> ValveStates {
        let mut states = [ValveState::Closed; VALVE_COUNT];
        for (s, v) in states.iter_mut().zip(&self.valves) {
            *s = v.state();
        }
        ValveStates(states)
    }

    fn pressures(&mut self) -> PressureReadings {
        let f: [f32; VALVE_COUNT] = std::array::from_fn(|i| self.valves[i].position);
        let source = self.config.source_vacuum_mmh2o * (1.0 - 0.3 * (f[0] + f[2]));
        let ideal = [
            source * f[0] * (1.0 - f[1]),
            source * f[2] * (1.0 - f[3]),
            source,
        ];
        let noisy = ideal.map(|v| {
            v + self
                .noise
                .as_ref()
                .map(|n| n.sample(&mut self.rng))
                .unwrap_or(0.0)
        });
        PressureReadings::from_array(noisy)
    }

    fn uptime_ms(&self) -> u32 {
        // Wraps like the Arduino's millis().
        (self.started.elapsed().as_millis() % (u128::from(u32::MAX) + 1)) as u32
    }

    /// Write fault lines queued by the handle or by valve supervision.
    fn flush_faults(&mut self) -> io::Result<()> {
        let faults = std::mem::take(&mut lock(&self.control).pending_faults);
        if faults.is_empty() {
            return Ok(());
        }
        self.out.clear();
        for fault in &faults {
            encode_fault(fault, &mut self.out);
        }
        trace!(count = faults.len(), "fake valve board sends fault lines");
        self.port.write_all(&self.out)
    }

    fn answer(&mut self, seq: u8, request: Result<Request, MessageError>) -> io::Result<()> {
        self.step_valves();
        // Faults queued before this request go out before its reply.
        self.flush_faults()?;
        let reply = match request {
            Ok(Request::Ping) => Reply::Pong {
                uptime_ms: self.uptime_ms(),
            },
            Ok(Request::Set { valve, open }) => match valve.index() {
                Some(i) if self.valves[i].stuck => Reply::Error(Status::Fault),
                Some(i) => {
                    self.command(i, open);
                    Reply::SetAck { valve, open }
                }
                None => Reply::Error(Status::Range),
            },
            Ok(Request::Valves) => Reply::Valves(self.states()),
            Ok(Request::Pressures) => Reply::Pressures(self.pressures()),
            Ok(Request::CloseAll) => {
                for i in 0..VALVE_COUNT {
                    if !self.valves[i].stuck {
                        self.command(i, false);
                    }
                }
                Reply::ClosedAll
            }
            Err(MessageError::BadArgument { field: "valve", .. }) => Reply::Error(Status::Range),
            Err(_) => Reply::Error(Status::Syntax),
        };
        let mode = {
            let mut c = lock(&self.control);
            c.stats.requests += 1;
            let mode = c.mode;
            if let Some(left) = c.mode_replies_left.as_mut() {
                *left = left.saturating_sub(1);
                if *left == 0 {
                    c.mode = FaultMode::Healthy;
                    c.mode_replies_left = None;
                }
            }
            mode
        };
        self.out.clear();
        match mode {
            FaultMode::Healthy => {}
            FaultMode::Silent => {
                trace!(seq, "fake valve board stays silent");
                return Ok(());
            }
            FaultMode::Garbage => self.push_garbage(),
            FaultMode::Late { delay_ms } => {
                std::thread::sleep(Duration::from_millis(u64::from(delay_ms)));
            }
            FaultMode::CorruptChecksum => {}
        }
        let frame_start = self.out.len();
        encode_reply(seq, &reply, &mut self.out);
        if mode == FaultMode::CorruptChecksum {
            corrupt_checksum(&mut self.out[frame_start..]);
        }
        lock(&self.control).stats.replies += 1;
        self.port.write_all(&self.out)
    }

    /// Noise of every kind the host must survive, appended to `self.out`.
    fn push_garbage(&mut self) {
        let noise_len = self.rng.random_range(3..24);
        for _ in 0..noise_len {
            let byte: u8 = self.rng.random();
            self.out.push(byte);
        }
        self.out.extend_from_slice(b"\n\r\n");
        // A frame cut short (as after a board reset mid-line).
        self.out.extend_from_slice(b"$OK PO");
        // A complete line whose checksum is wrong.
        let start = self.out.len();
        encode_reply(0, &Reply::Pong { uptime_ms: 123_456 }, &mut self.out);
        corrupt_checksum(&mut self.out[start..]);
        // An overlong line.
        self.out.push(b'$');
        self.out.extend(std::iter::repeat_n(b'Z', 120));
        self.out.push(b'\n');
    }
}

/// Change the two checksum digits of an encoded frame (`...*XY\n`) to a different value.
fn corrupt_checksum(frame: &mut [u8]) {
    let n = frame.len();
    if n >= 3 {
        let digit = &mut frame[n - 2];
        *digit = if *digit == b'0' { b'1' } else { b'0' };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::valve_board::protocol::{FrameError, decode_frame, encode_reply};

    #[test]
    fn corrupt_checksum_breaks_the_frame() {
        let mut out = Vec::new();
        encode_reply(4, &Reply::ClosedAll, &mut out);
        corrupt_checksum(&mut out);
        let content = &out[1..out.len() - 1];
        assert!(matches!(
            decode_frame(content),
            Err(FrameError::ChecksumMismatch { .. })
        ));
    }

    #[test]
    fn sim_valve_states() {
        let mut v = SimValve {
            position: 0.0,
            target_open: false,
            commanded_at: None,
            stuck: false,
        };
        assert_eq!(v.state(), ValveState::Closed);
        v.target_open = true;
        assert_eq!(v.state(), ValveState::Opening);
        v.position = 1.0;
        assert_eq!(v.state(), ValveState::Open);
        v.target_open = false;
        assert_eq!(v.state(), ValveState::Closing);
        v.stuck = true;
        assert_eq!(v.state(), ValveState::Stuck);
    }
}
