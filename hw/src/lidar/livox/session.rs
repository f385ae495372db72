//! The UDP session with one Mid-70, as the Livox SDK runs it (`device_discovery.cpp`,
//! `command_channel.cpp`, `lidar_data_handler.cpp`):
//!
//! 1. Find the device: either wait on the discovery port (55000) for the broadcast message
//!    carrying its broadcast code and take the device's address from the datagram, or go to a
//!    given address directly (`--lidar-ip`, for networks where broadcasts do not reach us).
//! 2. Handshake: tell it the host's IP and the host's data, command and IMU ports; retried
//!    every [`RETRY_PERIOD`] until acknowledged with return code 0. (The SDK sends this one
//!    command with packet type 1; so does this driver, for the same firmware.)
//! 3. Heartbeat every [`HEARTBEAT_PERIOD`] (the device drops a host silent for 3 s) and start
//!    sampling (retried until acknowledged).
//! 4. Silence: once handshaken, nothing heard (no point packet, no acknowledgement) for the
//!    silence timeout makes the device lost; the session reports it once and goes back to step
//!    1, so a device that comes back (or rebooted and forgot the host) is handshaken again.
//!
//! Everything here runs inside the driver's `capture_into` (no thread of its own): the caller
//! calls it continuously, as the `lidar` process does, and the session serves its timers
//! between datagrams. The sockets are non-blocking; waiting is one `poll(2)` on all of them.

use super::command::{
    self, Broadcast, CMD_BROADCAST, CMD_CONTROL_SAMPLE, CMD_HANDSHAKE, CMD_HEARTBEAT,
    CMD_PUSH_ABNORMAL_STATE, CMD_SET_GENERAL, Handshake, HeartbeatAck,
};
use super::config::{DeviceTarget, LivoxConfig};
use super::error::LivoxError;
use super::error_code::StatusCode;
use super::frame::{self, Frame, PacketType};
use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::os::fd::AsFd;
use std::time::{Duration, Instant};

/// How often the host sends its heartbeat.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);
/// How often an unanswered handshake or start-sampling command is sent again.
pub const RETRY_PERIOD: Duration = Duration::from_millis(250);
/// Socket receive buffer asked for the data port (the kernel caps it at `net.core.rmem_max`):
/// 4 MiB hold about 3 s of point packets.
pub const DATA_RECEIVE_BUFFER_BYTES: usize = 4 << 20;

/// Where the session stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SessionState {
    /// Waiting for the device's broadcast (discovery mode).
    Searching,
    /// Sending handshakes until one is acknowledged.
    Handshaking,
    /// Handshaken; sending start-sampling until acknowledged.
    Starting,
    /// Sampling acknowledged; point packets expected.
    Streaming,
}

/// Something the driver reacts to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SessionEvent {
    /// The device was lost after this long without a word; reconnecting.
    Lost {
        /// How long nothing came from the device.
        silent_for: Duration,
    },
    /// Sampling acknowledged (first time or again after a loss).
    Streaming {
        /// True after a loss (a reconnection), false the first time.
        reconnect: bool,
    },
}

/// Counters of the control link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SessionCounters {
    /// Control datagrams that were not valid frames (CRC, length, version, type).
    pub bad_frames: u64,
    /// Times the device was lost.
    pub losses: u64,
    /// Times sampling was acknowledged again after a loss.
    pub reconnects: u64,
    /// Heartbeats sent.
    pub heartbeats: u64,
}

/// The sockets and state of one device session.
pub struct Session {
    config: LivoxConfig,
    cmd: UdpSocket,
    data: UdpSocket,
    discovery: Option<UdpSocket>,
    state: SessionState,
    device: Option<SocketAddr>,
    host_ip: Option<Ipv4Addr>,
    seq: u16,
    next_send: Instant,
    next_heartbeat: Instant,
    last_heard: Instant,
    ever_streamed: bool,
    status: StatusCode,
    counters: SessionCounters,
    frame_out: Vec<u8>,
    frame_in: Vec<u8>,
}

fn bind(ip: Ipv4Addr, port: u16, what: &'static str) -> Result<UdpSocket, LivoxError> {
    let socket = UdpSocket::bind(SocketAddrV4::new(ip, port))
        .map_err(|source| LivoxError::Socket { what, source })?;
    socket
        .set_nonblocking(true)
        .map_err(|source| LivoxError::Socket { what, source })?;
    Ok(socket)
}

impl Session {
    /// Opens the sockets and starts looking for the device (broadcast, handshake, sampling).
    pub fn open(config: LivoxConfig) -> Result<Self, LivoxError> {
        let bind_ip = config.host_ip.unwrap_or(Ipv4Addr::UNSPECIFIED);
        let cmd = bind(bind_ip, config.host_cmd_port, "command port")?;
        let data = bind(bind_ip, config.host_data_port, "data port")?;
        if let Err(error) = nix::sys::socket::setsockopt(
            &data,
            nix::sys::socket::sockopt::RcvBuf,
            &DATA_RECEIVE_BUFFER_BYTES,
        ) {
            tracing::warn!(%error, "cannot enlarge the data port's receive buffer");
        }
        let (discovery, device, state) = match config.target {
            DeviceTarget::Broadcast(_) => {
                let socket = bind(
                    Ipv4Addr::UNSPECIFIED,
                    config.discovery_port,
                    "discovery port",
                )?;
                socket
                    .set_broadcast(true)
                    .map_err(|source| LivoxError::Socket {
                        what: "discovery port",
                        source,
                    })?;
                (Some(socket), None, SessionState::Searching)
            }
            DeviceTarget::Address(ip) => (
                None,
                Some(SocketAddr::V4(SocketAddrV4::new(
                    ip,
                    config.device_cmd_port,
                ))),
                SessionState::Handshaking,
            ),
        };
        let now = Instant::now();
        Ok(Self {
            host_ip: config.host_ip,
            config,
            cmd,
            data,
            discovery,
            state,
            device,
            seq: 0,
            next_send: now,
            next_heartbeat: now,
            last_heard: now,
            ever_streamed: false,
            status: StatusCode::default(),
            counters: SessionCounters::default(),
            frame_out: Vec::with_capacity(frame::MAX_FRAME_LEN),
            frame_in: vec![0; 2048],
        })
    }

    /// Where the session stands.
    pub fn state(&self) -> SessionState {
        self.state
    }

    /// Counters since the session opened.
    pub fn counters(&self) -> SessionCounters {
        self.counters
    }

    /// The device's status word from its last heartbeat acknowledgement or abnormal push.
    pub fn status(&self) -> StatusCode {
        self.status
    }

    /// The device's command address once known.
    pub fn device(&self) -> Option<SocketAddr> {
        self.device
    }

    /// The local data port (for an ephemeral `--host-data-port 0`).
    pub fn data_port(&self) -> Result<u16, LivoxError> {
        port_of(&self.data, "data port")
    }

    /// The local command port.
    pub fn cmd_port(&self) -> Result<u16, LivoxError> {
        port_of(&self.cmd, "command port")
    }

    /// The data socket, for the driver to read point packets from.
    pub fn data_socket(&self) -> &UdpSocket {
        &self.data
    }

    /// True when `from` is the device (point packets from anyone else are ignored).
    pub fn is_device(&self, from: &SocketAddr) -> bool {
        self.device.is_some_and(|device| device.ip() == from.ip())
    }

    /// Records that the device was heard (a point packet arrived).
    pub fn heard(&mut self, at: Instant) {
        self.last_heard = at;
    }

    /// Reads every waiting control datagram, sends what is due, and checks for silence.
    pub fn service(&mut self, now: Instant) -> Result<Option<SessionEvent>, LivoxError> {
        let event = self.read_control(now)?;
        // Silence counts once connected; a lost device is reported once, then searched for
        // (or handshaken) without further reports until it answers again.
        if matches!(self.state, SessionState::Starting | SessionState::Streaming) {
            let silent_for = now.saturating_duration_since(self.last_heard);
            if silent_for >= self.config.silence_timeout {
                self.counters.losses += 1;
                self.state = match self.config.target {
                    DeviceTarget::Broadcast(_) => {
                        self.device = None;
                        SessionState::Searching
                    }
                    DeviceTarget::Address(_) => SessionState::Handshaking,
                };
                self.next_send = now;
                self.last_heard = now;
                tracing::warn!(?silent_for, "livox device silent; reconnecting");
                return Ok(Some(SessionEvent::Lost { silent_for }));
            }
        }
        match self.state {
            SessionState::Searching => {}
            SessionState::Handshaking if now >= self.next_send => {
                self.send_handshake()?;
                self.next_send = now + RETRY_PERIOD;
            }
            SessionState::Starting if now >= self.next_send => {
                self.send_command(PacketType::Command, CMD_CONTROL_SAMPLE, &[1])?;
                self.next_send = now + RETRY_PERIOD;
            }
            _ => {}
        }
        if matches!(self.state, SessionState::Starting | SessionState::Streaming)
            && now >= self.next_heartbeat
        {
            self.send_command(PacketType::Command, CMD_HEARTBEAT, &[])?;
            self.counters.heartbeats += 1;
            self.next_heartbeat = now + HEARTBEAT_PERIOD;
        }
        Ok(event)
    }

    /// When the session next has something to send (for the caller's wait).
    pub fn next_due(&self, now: Instant) -> Instant {
        let silence = self.last_heard + self.config.silence_timeout;
        let mut due = silence.max(now);
        match self.state {
            SessionState::Searching => {}
            SessionState::Handshaking | SessionState::Starting => due = due.min(self.next_send),
            SessionState::Streaming => {}
        }
        if matches!(self.state, SessionState::Starting | SessionState::Streaming) {
            due = due.min(self.next_heartbeat);
        }
        due
    }

    /// Blocks until a socket is readable or `until`; an interrupted wait returns early.
    pub fn wait(&self, now: Instant, until: Instant) -> Result<(), LivoxError> {
        let wait = until.saturating_duration_since(now);
        // Round up so a wait for 0.4 ms does not spin.
        let millis = wait.as_micros().div_ceil(1000).min(u128::from(u16::MAX)) as u16;
        let mut fds = vec![
            PollFd::new(self.data.as_fd(), PollFlags::POLLIN),
            PollFd::new(self.cmd.as_fd(), PollFlags::POLLIN),
        ];
        if let Some(discovery) = &self.discovery {
            fds.push(PollFd::new(discovery.as_fd(), PollFlags::POLLIN));
        }
        match poll(&mut fds, PollTimeout::from(millis)) {
            Ok(_) | Err(nix::errno::Errno::EINTR) => Ok(()),
            Err(errno) => Err(LivoxError::Link {
                what: "poll",
                source: errno.into(),
            }),
        }
    }

    fn read_control(&mut self, now: Instant) -> Result<Option<SessionEvent>, LivoxError> {
        let mut event = None;
        if self.discovery.is_some() {
            while let Some((len, from)) = recv(self.discovery.as_ref(), &mut self.frame_in)? {
                self.on_datagram(len, from, now, &mut event)?;
            }
        }
        while let Some((len, from)) = recv(Some(&self.cmd), &mut self.frame_in)? {
            self.on_datagram(len, from, now, &mut event)?;
        }
        Ok(event)
    }

    fn on_datagram(
        &mut self,
        len: usize,
        from: SocketAddr,
        now: Instant,
        event: &mut Option<SessionEvent>,
    ) -> Result<(), LivoxError> {
        let datagram = &self.frame_in[..len];
        let frame = match frame::decode_frame(datagram) {
            Ok(frame) => frame,
            Err(error) => {
                self.counters.bad_frames += 1;
                tracing::debug!(%error, %from, "control datagram dropped");
                return Ok(());
            }
        };
        if frame.cmd_set != CMD_SET_GENERAL {
            return Ok(());
        }
        let (packet_type, cmd_id) = (frame.packet_type, frame.cmd_id);
        let payload = frame.payload.to_vec();
        match (packet_type, cmd_id) {
            (PacketType::Message, CMD_BROADCAST) => self.on_broadcast(&payload, from, now)?,
            (_, _) if !self.is_device(&from) => {}
            (PacketType::Message, CMD_PUSH_ABNORMAL_STATE) if payload.len() >= 4 => {
                self.last_heard = now;
                self.set_status(u32::from_le_bytes([
                    payload[0], payload[1], payload[2], payload[3],
                ]));
            }
            (PacketType::Ack, CMD_HANDSHAKE) if self.state == SessionState::Handshaking => {
                match command::ret_code(cmd_id, &payload) {
                    Ok(command::RET_OK) => {
                        self.last_heard = now;
                        self.state = SessionState::Starting;
                        self.next_send = now;
                        self.next_heartbeat = now;
                        tracing::info!(device = ?self.device, "livox handshake acknowledged");
                    }
                    other => tracing::warn!(?other, "livox handshake refused"),
                }
            }
            (PacketType::Ack, CMD_CONTROL_SAMPLE) if self.state == SessionState::Starting => {
                match command::ret_code(cmd_id, &payload) {
                    Ok(command::RET_OK) => {
                        self.last_heard = now;
                        self.state = SessionState::Streaming;
                        let reconnect = self.ever_streamed;
                        if reconnect {
                            self.counters.reconnects += 1;
                        }
                        self.ever_streamed = true;
                        tracing::info!(reconnect, "livox sampling");
                        *event = Some(SessionEvent::Streaming { reconnect });
                    }
                    other => tracing::warn!(?other, "livox start sampling refused"),
                }
            }
            (PacketType::Ack, CMD_HEARTBEAT) => match HeartbeatAck::decode(&payload) {
                Ok(ack) => {
                    self.last_heard = now;
                    if ack.state != HeartbeatAck::STATE_INIT {
                        self.set_status(ack.status_code);
                    }
                }
                Err(error) => {
                    self.counters.bad_frames += 1;
                    tracing::debug!(%error, "heartbeat acknowledgement dropped");
                }
            },
            _ => {}
        }
        Ok(())
    }

    fn on_broadcast(
        &mut self,
        payload: &[u8],
        from: SocketAddr,
        now: Instant,
    ) -> Result<(), LivoxError> {
        let DeviceTarget::Broadcast(code) = self.config.target else {
            return Ok(());
        };
        let Ok(broadcast) = Broadcast::decode(payload) else {
            self.counters.bad_frames += 1;
            return Ok(());
        };
        if broadcast.code != code || self.state != SessionState::Searching {
            return Ok(());
        }
        tracing::info!(%code, %from, device_type = broadcast.device_type, "livox device found");
        // The SDK answers to the address the broadcast came from.
        self.device = Some(from);
        self.state = SessionState::Handshaking;
        self.next_send = now;
        self.last_heard = now;
        Ok(())
    }

    fn set_status(&mut self, code: u32) {
        let status = StatusCode(code);
        if status != self.status {
            let conditions: Vec<&str> = status.conditions().collect();
            tracing::warn!(
                status_code = format_args!("{code:#010x}"),
                severity = ?status.severity(),
                ?conditions,
                "livox device status changed"
            );
            self.status = status;
        }
    }

    /// Takes the status word a point packet carries.
    pub fn packet_status(&mut self, code: u32) {
        self.set_status(code);
    }

    fn host_ip(&mut self) -> Result<Ipv4Addr, LivoxError> {
        if let Some(ip) = self.host_ip {
            return Ok(ip);
        }
        let device = self
            .device
            .ok_or_else(|| LivoxError::Config("no device address".into()))?;
        // The local address the kernel routes towards the device (the SDK's `FindLocalIp`).
        let probe = UdpSocket::bind("0.0.0.0:0")
            .and_then(|socket| socket.connect(device).map(|()| socket))
            .and_then(|socket| socket.local_addr())
            .map_err(|source| LivoxError::Socket {
                what: "route to device",
                source,
            })?;
        match probe.ip() {
            std::net::IpAddr::V4(ip) => {
                self.host_ip = Some(ip);
                Ok(ip)
            }
            std::net::IpAddr::V6(ip) => Err(LivoxError::Config(format!(
                "host address towards the device is IPv6 ({ip}); give --host-ip"
            ))),
        }
    }

    fn send_handshake(&mut self) -> Result<(), LivoxError> {
        let data_port = self.data_port()?;
        let handshake = Handshake {
            host_ip: self.host_ip()?,
            data_port,
            cmd_port: self.cmd_port()?,
            sensor_port: data_port,
        };
        self.send_command(PacketType::Ack, CMD_HANDSHAKE, &handshake.encode())
    }

    fn send_command(
        &mut self,
        packet_type: PacketType,
        cmd_id: u8,
        payload: &[u8],
    ) -> Result<(), LivoxError> {
        let Some(device) = self.device else {
            return Ok(());
        };
        self.seq = self.seq.wrapping_add(1).max(1);
        let frame = Frame {
            packet_type,
            seq: self.seq,
            cmd_set: CMD_SET_GENERAL,
            cmd_id,
            payload,
        };
        frame::encode_frame(&frame, &mut self.frame_out)
            .map_err(|error| LivoxError::Config(error.to_string()))?;
        match self.cmd.send_to(&self.frame_out, device) {
            Ok(_) => Ok(()),
            // A device that is away (ICMP port unreachable on loopback, no route) is the
            // silence the session already handles.
            Err(error) if is_transient(&error) => {
                tracing::debug!(%error, "livox command not sent");
                Ok(())
            }
            Err(source) => Err(LivoxError::Link {
                what: "send command",
                source,
            }),
        }
    }
}

fn port_of(socket: &UdpSocket, what: &'static str) -> Result<u16, LivoxError> {
    socket
        .local_addr()
        .map(|address| address.port())
        .map_err(|source| LivoxError::Socket { what, source })
}

/// Errors of a datagram socket that mean "the peer is not there now", not a broken socket.
pub fn is_transient(error: &std::io::Error) -> bool {
    use std::io::ErrorKind as Kind;
    matches!(
        error.kind(),
        Kind::ConnectionRefused
            | Kind::ConnectionReset
            | Kind::HostUnreachable
            | Kind::NetworkUnreachable
            | Kind::Interrupted
    )
}

/// One datagram from a non-blocking socket, or None when none is waiting.
pub fn recv(
    socket: Option<&UdpSocket>,
    buffer: &mut [u8],
) -> Result<Option<(usize, SocketAddr)>, LivoxError> {
    let Some(socket) = socket else {
        return Ok(None);
    };
    loop {
        match socket.recv_from(buffer) {
            Ok(received) => return Ok(Some(received)),
            Err(error) if error.kind() == std::io::ErrorKind::WouldBlock => return Ok(None),
            Err(error) if is_transient(&error) => continue,
            Err(source) => {
                return Err(LivoxError::Link {
                    what: "receive",
                    source,
                });
            }
        }
    }
}
