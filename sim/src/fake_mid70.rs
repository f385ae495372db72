//! A fake Livox Mid-70 speaking the real SDK 1 protocol over UDP (for the driver's tests and
//! benchmark, never onboard): it broadcasts its code for discovery, answers handshake,
//! heartbeat, start/stop sampling and disconnect with the device's acknowledgements, drops a
//! host silent for 3 s as the device does, and streams point packets of the simulator's rosette
//! scan of an orchard scene ([`LidarDeviceServer`], the same renderer `harvest sim --lidar`
//! serves) at the Mid-70's 100,000 firings per second, paced by the wall clock.
//!
//! Faults on command ([`FakeFault`]): drop the next packets, corrupt them (truncated, wrong
//! length, version, data type, timestamp type, in turn, plus one control frame with a broken
//! CRC), go silent for a while (no datagram out, commands ignored, the clock running on), and
//! reboot (dark for a while, then the host forgotten and the device time restarted from 0).
//!
//! Device time: without synchronisation (timestamp type 0) the nanoseconds since the fake
//! (re)booted; under PTP (type 1) a master time that runs on across reboots.

use crate::lidar_device::{LidarDeviceConfig, LidarDeviceError, LidarDeviceServer};
use crate::orchard::World;
use crate::scenario::Scenario;
use harvest_hw::lidar::livox::command::{
    Broadcast, BroadcastCode, CMD_BROADCAST, CMD_SET_GENERAL, DEVICE_TYPE_MID70, HeartbeatAck,
    HostCommand, RET_OK,
};
use harvest_hw::lidar::livox::frame::{self, Frame, PacketType};
use harvest_hw::lidar::livox::point_packet::{
    DataType, PointPacketHeader, RawReturn, TimestampType, encode_point_packet,
};
use harvest_ipc::MonotonicClock;
use std::collections::VecDeque;
use std::net::{SocketAddr, SocketAddrV4, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A device drops a host whose heartbeat it has not seen for this long.
pub const HOST_TIMEOUT: Duration = Duration::from_secs(3);
/// Period of the discovery broadcast while no host is connected.
pub const BROADCAST_PERIOD: Duration = Duration::from_secs(1);
/// The PTP master's time at the fake's start (any large epoch: the driver maps it away).
const PTP_EPOCH_NS: u64 = 1_700_000_000_000_000_000;

/// How the fake device behaves.
#[derive(Debug, Clone)]
pub struct FakeMid70Config {
    pub code: BroadcastCode,
    /// Address of the device's command socket (port 0: any free port).
    pub cmd_bind: SocketAddrV4,
    /// Where to send the discovery broadcast (the host's discovery port); None: no broadcast.
    pub broadcast_to: Option<SocketAddr>,
    pub data_type: DataType,
    /// `NoSync` or `Ptp` (the fake has no PPS input).
    pub timestamp_type: TimestampType,
    /// Scenario preset of the scene and its seed.
    pub scenario: String,
    pub seed: u64,
    pub lidar: LidarDeviceConfig,
}

impl FakeMid70Config {
    /// A single-return, unsynchronised Mid-70 on loopback looking at the `default` scenario.
    pub fn loopback(code: BroadcastCode) -> Self {
        Self {
            code,
            cmd_bind: SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, 0),
            broadcast_to: None,
            data_type: DataType::ExtendedCartesian,
            timestamp_type: TimestampType::NoSync,
            scenario: "default".to_string(),
            seed: 1,
            lidar: LidarDeviceConfig::default(),
        }
    }
}

/// A fault to inject.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FakeFault {
    /// The next `packets` point packets are not sent.
    Drop { packets: u64 },
    /// The next `packets` point packets are sent damaged (and one control frame with a bad CRC).
    Corrupt { packets: u64 },
    /// Nothing is sent and commands are ignored for this long; the device keeps its host.
    Silent(Duration),
    /// Dark for this long, then the device starts over: host forgotten, time from 0.
    Reboot(Duration),
    /// The status word every packet and heartbeat acknowledgement carries from now on.
    Status(u32),
}

/// What the fake has done, counted.
#[derive(Debug, Default)]
pub struct FakeCounters {
    pub packets_sent: AtomicU64,
    pub packets_dropped: AtomicU64,
    pub packets_corrupted: AtomicU64,
    pub frames_corrupted: AtomicU64,
    pub handshakes: AtomicU64,
    pub heartbeats: AtomicU64,
    pub reboots: AtomicU64,
    pub broadcasts: AtomicU64,
}

/// A snapshot of [`FakeCounters`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FakeStats {
    pub packets_sent: u64,
    pub packets_dropped: u64,
    pub packets_corrupted: u64,
    pub frames_corrupted: u64,
    pub handshakes: u64,
    pub heartbeats: u64,
    pub reboots: u64,
    pub broadcasts: u64,
}

/// Why the fake cannot start.
#[derive(Debug, thiserror::Error)]
pub enum FakeMid70Error {
    #[error("fake mid-70 socket: {0}")]
    Socket(#[from] std::io::Error),
    #[error("fake mid-70 scene: {0}")]
    Scene(String),
    #[error(transparent)]
    Device(#[from] LidarDeviceError),
}

/// The running fake (its thread stops when this is dropped).
pub struct FakeMid70 {
    cmd_addr: SocketAddr,
    faults: mpsc::Sender<FakeFault>,
    counters: Arc<FakeCounters>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl FakeMid70 {
    /// Binds the sockets, builds the scene and starts the device thread.
    pub fn start(config: FakeMid70Config) -> Result<Self, FakeMid70Error> {
        let scenario =
            Scenario::preset(&config.scenario).map_err(|e| FakeMid70Error::Scene(e.to_string()))?;
        let world = World::generate(&scenario, config.seed)
            .map_err(|e| FakeMid70Error::Scene(e.to_string()))?;
        let server = LidarDeviceServer::new(config.lidar)?;
        let cmd = UdpSocket::bind(config.cmd_bind)?;
        cmd.set_nonblocking(true)?;
        let data = UdpSocket::bind(SocketAddrV4::new(*config.cmd_bind.ip(), 0))?;
        let cmd_addr = cmd.local_addr()?;
        let (faults, fault_rx) = mpsc::channel();
        let counters = Arc::new(FakeCounters::default());
        let stop = Arc::new(AtomicBool::new(false));
        let mut device = Device {
            config,
            world,
            server,
            cmd,
            data,
            faults: fault_rx,
            counters: Arc::clone(&counters),
            stop: Arc::clone(&stop),
            host: None,
            sampling: false,
            boot: Instant::now(),
            dark_until: None,
            rebooting: false,
            drop_next: 0,
            corrupt_next: 0,
            corrupt_kind: 0,
            corrupt_frames_next: 0,
            status: 0,
            next_first_ns: None,
            next_broadcast: Instant::now(),
            queue: VecDeque::new(),
            scratch: Vec::new(),
            frame_out: Vec::new(),
            packet_out: Vec::new(),
            frame_in: vec![0; 2048],
        };
        device.status = device.sync_bits();
        let thread = std::thread::Builder::new()
            .name("fake-mid70".into())
            .spawn(move || device.run())?;
        Ok(Self {
            cmd_addr,
            faults,
            counters,
            stop,
            thread: Some(thread),
        })
    }

    /// The device's command address (what `--lidar-ip` and `--lidar-cmd-port` point at).
    pub fn cmd_addr(&self) -> SocketAddr {
        self.cmd_addr
    }

    /// Injects a fault (ignored once the device thread has ended).
    pub fn inject(&self, fault: FakeFault) {
        let _ = self.faults.send(fault);
    }

    pub fn stats(&self) -> FakeStats {
        let c = &self.counters;
        let get = |counter: &AtomicU64| counter.load(Ordering::Relaxed);
        FakeStats {
            packets_sent: get(&c.packets_sent),
            packets_dropped: get(&c.packets_dropped),
            packets_corrupted: get(&c.packets_corrupted),
            frames_corrupted: get(&c.frames_corrupted),
            handshakes: get(&c.handshakes),
            heartbeats: get(&c.heartbeats),
            reboots: get(&c.reboots),
            broadcasts: get(&c.broadcasts),
        }
    }
}

impl Drop for FakeMid70 {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The connected host.
#[derive(Debug, Clone, Copy)]
struct Host {
    cmd: SocketAddr,
    data: SocketAddr,
    last_heartbeat: Instant,
}

struct Device {
    config: FakeMid70Config,
    world: World,
    server: LidarDeviceServer,
    cmd: UdpSocket,
    data: UdpSocket,
    faults: mpsc::Receiver<FakeFault>,
    counters: Arc<FakeCounters>,
    stop: Arc<AtomicBool>,
    host: Option<Host>,
    sampling: bool,
    boot: Instant,
    dark_until: Option<Instant>,
    rebooting: bool,
    drop_next: u64,
    corrupt_next: u64,
    corrupt_kind: u8,
    /// Heartbeat acknowledgements still to be preceded by a copy with a broken CRC.
    corrupt_frames_next: u64,
    status: u32,
    /// Device time of the next packet's first firing.
    next_first_ns: Option<u64>,
    next_broadcast: Instant,
    /// Rendered firings not yet packed.
    queue: VecDeque<RawReturn>,
    scratch: Vec<RawReturn>,
    frame_out: Vec<u8>,
    packet_out: Vec<u8>,
    frame_in: Vec<u8>,
}

fn count(counter: &AtomicU64) {
    counter.fetch_add(1, Ordering::Relaxed);
}

impl Device {
    fn run(mut self) {
        while !self.stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            while let Ok(fault) = self.faults.try_recv() {
                self.inject(fault, now);
            }
            let dark = self.dark_until.is_some_and(|until| now < until);
            if !dark && self.dark_until.take().is_some() && self.rebooting {
                self.reboot(now);
            }
            self.serve_commands(now, dark);
            if let Some(host) = self.host
                && now.duration_since(host.last_heartbeat) > HOST_TIMEOUT
            {
                tracing::debug!("fake mid-70: host silent for 3 s, dropped");
                self.host = None;
                self.sampling = false;
            }
            if !dark && self.host.is_none() && now >= self.next_broadcast {
                self.broadcast();
                self.next_broadcast = now + BROADCAST_PERIOD;
            }
            let next_due = self.stream(dark);
            let wake = next_due.min(Instant::now() + Duration::from_millis(2));
            if let Some(wait) = wake.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
    }

    fn sync_bits(&self) -> u32 {
        match self.config.timestamp_type {
            // PTP signal present, time sync 1 (PTP).
            TimestampType::Ptp => (1 << 13) | (1 << 14),
            _ => 0,
        }
    }

    fn device_now_ns(&self) -> u64 {
        match self.config.timestamp_type {
            TimestampType::Ptp => PTP_EPOCH_NS + MonotonicClock::read_ns(),
            _ => self.boot.elapsed().as_nanos() as u64,
        }
    }

    fn inject(&mut self, fault: FakeFault, now: Instant) {
        tracing::debug!(?fault, "fake mid-70 fault");
        match fault {
            FakeFault::Drop { packets } => self.drop_next += packets,
            FakeFault::Corrupt { packets } => {
                self.corrupt_next += packets;
                self.corrupt_frames_next += 1;
            }
            FakeFault::Silent(duration) => {
                self.dark_until = Some(now + duration);
                self.rebooting = false;
            }
            FakeFault::Reboot(duration) => {
                self.dark_until = Some(now + duration);
                self.rebooting = true;
                self.host = None;
                self.sampling = false;
            }
            FakeFault::Status(code) => self.status = code | self.sync_bits(),
        }
    }

    fn reboot(&mut self, now: Instant) {
        count(&self.counters.reboots);
        self.rebooting = false;
        self.host = None;
        self.sampling = false;
        self.boot = now;
        self.next_first_ns = None;
        self.queue.clear();
        self.next_broadcast = now;
    }

    fn broadcast(&mut self) {
        let Some(to) = self.config.broadcast_to else {
            return;
        };
        let payload = Broadcast {
            code: self.config.code,
            device_type: DEVICE_TYPE_MID70,
        }
        .encode();
        if self.send_frame(PacketType::Message, 0, CMD_BROADCAST, &payload, to) {
            count(&self.counters.broadcasts);
        }
    }

    fn send_frame(
        &mut self,
        packet_type: PacketType,
        seq: u16,
        cmd_id: u8,
        payload: &[u8],
        to: SocketAddr,
    ) -> bool {
        let frame = Frame {
            packet_type,
            seq,
            cmd_set: CMD_SET_GENERAL,
            cmd_id,
            payload,
        };
        if frame::encode_frame(&frame, &mut self.frame_out).is_err() {
            return false;
        }
        self.cmd.send_to(&self.frame_out, to).is_ok()
    }

    fn serve_commands(&mut self, now: Instant, dark: bool) {
        loop {
            let (len, from) = match self.cmd.recv_from(&mut self.frame_in) {
                Ok(received) => received,
                Err(error) if error.kind() == std::io::ErrorKind::WouldBlock => return,
                Err(_) => continue,
            };
            if dark {
                continue;
            }
            let Ok(frame) = frame::decode_frame(&self.frame_in[..len]) else {
                continue;
            };
            if frame.packet_type == PacketType::Message {
                continue;
            }
            let (seq, cmd_set, cmd_id) = (frame.seq, frame.cmd_set, frame.cmd_id);
            let Ok(command) = HostCommand::decode(cmd_set, cmd_id, frame.payload) else {
                continue;
            };
            let known_host = self.host.is_some_and(|host| host.cmd == from);
            let ret = match command {
                HostCommand::Handshake(handshake) => {
                    count(&self.counters.handshakes);
                    self.host = Some(Host {
                        cmd: from,
                        data: SocketAddr::new(handshake.host_ip.into(), handshake.data_port),
                        last_heartbeat: now,
                    });
                    self.sampling = false;
                    RET_OK
                }
                // A device answers only the host it is connected to.
                _ if !known_host => continue,
                HostCommand::Heartbeat => {
                    count(&self.counters.heartbeats);
                    if let Some(host) = &mut self.host {
                        host.last_heartbeat = now;
                    }
                    let ack = HeartbeatAck {
                        ret_code: RET_OK,
                        state: HeartbeatAck::STATE_NORMAL,
                        feature: 0,
                        status_code: self.status,
                    }
                    .encode();
                    if self.corrupt_frames_next > 0 {
                        self.corrupt_frames_next -= 1;
                        // A control frame with a broken CRC-32 ahead of the good one.
                        let frame = Frame {
                            packet_type: PacketType::Ack,
                            seq,
                            cmd_set,
                            cmd_id,
                            payload: &ack,
                        };
                        if frame::encode_frame(&frame, &mut self.frame_out).is_ok() {
                            if let Some(last) = self.frame_out.last_mut() {
                                *last ^= 0x5a;
                            }
                            let _ = self.cmd.send_to(&self.frame_out, from);
                            count(&self.counters.frames_corrupted);
                        }
                    }
                    self.send_frame(PacketType::Ack, seq, cmd_id, &ack, from);
                    continue;
                }
                HostCommand::ControlSample { start } => {
                    self.sampling = start;
                    RET_OK
                }
                HostCommand::Disconnect => {
                    self.host = None;
                    self.sampling = false;
                    RET_OK
                }
                HostCommand::Other { .. } => 1,
            };
            self.send_frame(PacketType::Ack, seq, cmd_id, &[ret], from);
        }
    }

    /// Sends every packet whose last firing has happened; returns when the next one is due.
    fn stream(&mut self, dark: bool) -> Instant {
        let data_type = self.config.data_type;
        let span_ns = data_type.packet_span_ns();
        let now_ns = self.device_now_ns();
        let aligned = now_ns / span_ns * span_ns;
        let streaming = !dark && self.sampling && self.host.is_some();
        let mut first_ns = match self.next_first_ns {
            Some(first) if streaming => first,
            // Not streaming: the device fires on, its packets go nowhere.
            _ => aligned,
        };
        if !streaming {
            self.next_first_ns = Some(first_ns);
            return Instant::now() + Duration::from_nanos(span_ns);
        }
        while first_ns + span_ns <= now_ns {
            self.send_packet(first_ns);
            first_ns += span_ns;
        }
        self.next_first_ns = Some(first_ns);
        Instant::now() + Duration::from_nanos(first_ns + span_ns - now_ns)
    }

    fn send_packet(&mut self, first_ns: u64) {
        let data_type = self.config.data_type;
        let firings = data_type.firings();
        if self.queue.len() < firings {
            self.render(firings);
        }
        self.scratch.clear();
        for _ in 0..firings {
            let firing = self.queue.pop_front().unwrap_or_default();
            for _ in 0..data_type.returns_per_firing() {
                self.scratch.push(firing);
            }
        }
        let Some(host) = self.host else {
            return;
        };
        if self.drop_next > 0 {
            self.drop_next -= 1;
            count(&self.counters.packets_dropped);
            return;
        }
        let header = PointPacketHeader {
            slot: 1,
            lidar_id: 1,
            status_code: self.status,
            timestamp_type: self.config.timestamp_type,
            data_type,
            timestamp: first_ns.to_le_bytes(),
        };
        if encode_point_packet(&header, &self.scratch, &mut self.packet_out).is_err() {
            return;
        }
        if self.corrupt_next > 0 {
            self.corrupt_next -= 1;
            self.corrupt_packet();
            count(&self.counters.packets_corrupted);
        }
        match self.data.send_to(&self.packet_out, host.data) {
            Ok(_) => count(&self.counters.packets_sent),
            Err(error) => tracing::trace!(%error, "fake mid-70 packet not sent"),
        }
    }

    /// Damages the encoded packet one way after another.
    fn corrupt_packet(&mut self) {
        let out = &mut self.packet_out;
        match self.corrupt_kind % 5 {
            0 => out.truncate(out.len() / 2),
            1 => out.push(0),
            2 => out[0] = 4,
            3 => out[9] = 3,
            _ => out[8] = 2,
        }
        self.corrupt_kind = self.corrupt_kind.wrapping_add(1);
    }

    /// Renders the next firings of the scan (a tenth of a second at a time, so the scene's
    /// object buckets are rebuilt ten times a second as `harvest sim` does).
    fn render(&mut self, at_least: usize) {
        let batch = self.config.lidar.spec.points_per_frame().max(at_least);
        let queue = &mut self.queue;
        self.server.scan_firings(&self.world, batch, |point| {
            queue.push_back(match point {
                Some(point) => RawReturn {
                    x_mm: (point.x_m * 1000.0).round() as i32,
                    y_mm: (point.y_m * 1000.0).round() as i32,
                    z_mm: (point.z_m * 1000.0).round() as i32,
                    reflectivity: point.intensity.clamp(0.0, 255.0) as u8,
                    tag: 0,
                },
                None => RawReturn::default(),
            });
            true
        });
    }
}
