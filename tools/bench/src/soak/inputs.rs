//! The bad inputs the soak writes into the stack's channels itself: the channels that accept
//! more than one writer (`operator/command`, `harvest/events`, `system/health`; the others refuse
//! a second publisher). Every payload is any-bit-pattern (harvest_ipc::any_bit_pattern), so random
//! bytes in every field are a message a buggy or hostile writer could send.

use harvest_ipc::catalogue::{HARVEST_EVENTS, OPERATOR_COMMAND, PROCESS_HEALTH};
use harvest_ipc::payloads::{
    DeviceErrorCode, HarvestEvent, OperatorCommand, OperatorCommandCode, ProcessHealth,
    ProcessRunState,
};
use harvest_ipc::wire_code::WireCode;
use harvest_ipc::{Context, FixedString, MonotonicClock, Payload, Publisher};
use rand::rngs::SmallRng;
use rand::{Rng, RngCore};

/// An unknown `HarvestEventKind` code.
const UNKNOWN_EVENT_KIND: u8 = 0xEE;
/// An unknown `OperatorCommandCode`.
const UNKNOWN_COMMAND_CODE: u16 = 0xBEEF;

/// The soak's writers into the stack's shared channels (each None when the channel refused it:
/// all writer slots taken).
pub struct BadInputWriters {
    operator: Option<Publisher<OperatorCommand>>,
    events: Option<Publisher<HarvestEvent>>,
    health: Option<Publisher<ProcessHealth>>,
}

impl BadInputWriters {
    pub fn open(context: &Context) -> Self {
        fn open<T: Payload>(
            context: &Context,
            channel: harvest_ipc::Channel<T>,
        ) -> Option<Publisher<T>> {
            match context.publisher(channel) {
                Ok(publisher) => Some(publisher),
                Err(error) => {
                    tracing::warn!(topic = channel.spec.topic, %error, "no bad inputs on this channel");
                    None
                }
            }
        }
        Self {
            operator: open(context, OPERATOR_COMMAND),
            events: open(context, HARVEST_EVENTS),
            health: open(context, PROCESS_HEALTH),
        }
    }

    /// Random bytes in every field of an operator command, except that the code is never the
    /// emergency stop's: a stop needs no token, so random bytes that happen to spell it stop
    /// the robot (as they should), which is not the refusal this input is meant to provoke.
    pub fn garbage_operator_command(&mut self, rng: &mut SmallRng) -> Result<String, String> {
        let stamp_ns = rng.random();
        send(
            &mut self.operator,
            "operator/command",
            stamp_ns,
            |command| {
                fill_random(command, rng);
                if command.code == OperatorCommandCode::EmergencyStop as u16 {
                    command.code = UNKNOWN_COMMAND_CODE;
                }
            },
            "random bytes on operator/command".to_owned(),
        )
    }

    /// The real token, an unknown command code, a NaN value.
    pub fn unknown_command_code(
        &mut self,
        rng: &mut SmallRng,
        token: &str,
    ) -> Result<String, String> {
        send(
            &mut self.operator,
            "operator/command",
            MonotonicClock::read_ns(),
            |command| {
                fill_random(command, rng);
                command.code = UNKNOWN_COMMAND_CODE;
                command.value = f64::NAN;
                command.platform_target_m = [f64::INFINITY, f64::NAN];
                command.token = FixedString::new(token);
                command.client = FixedString::new("soak bad input");
            },
            format!("code {UNKNOWN_COMMAND_CODE:#x} with the real token, NaN value"),
        )
    }

    /// Random bytes in a harvest event whose kind is an unknown code (a known kind with random
    /// fields would be counted by the harvest summary as a real event).
    pub fn garbage_harvest_event(&mut self, rng: &mut SmallRng) -> Result<String, String> {
        let stamp_ns = rng.random();
        send(
            &mut self.events,
            "harvest/events",
            stamp_ns,
            |event| {
                fill_random(event, rng);
                event.kind = WireCode::from_raw(UNKNOWN_EVENT_KIND);
            },
            format!("random bytes on harvest/events, kind {UNKNOWN_EVENT_KIND:#x}"),
        )
    }

    /// Random bytes in a heartbeat.
    pub fn garbage_heartbeat(&mut self, rng: &mut SmallRng) -> Result<String, String> {
        let stamp_ns = rng.random();
        send(
            &mut self.health,
            "system/health",
            stamp_ns,
            |beat| fill_random(beat, rng),
            "random bytes on system/health".to_owned(),
        )
    }

    /// A heartbeat named `process` with a pid that is not its own, state degraded.
    pub fn spoofed_heartbeat(&mut self, process: &str, wrong_pid: u32) -> Result<String, String> {
        send(
            &mut self.health,
            "system/health",
            MonotonicClock::read_ns(),
            |beat| {
                beat.process_name = FixedString::new(process);
                beat.pid = wrong_pid;
                beat.run_state = WireCode::new(ProcessRunState::Degraded);
                beat.last_device_error = WireCode::new(DeviceErrorCode::Fault);
                beat._reserved = [0; 2];
                beat.main_channel_count = u64::MAX;
                beat.detail_value = u64::MAX;
                beat.detail = FixedString::new("spoofed by the soak");
                beat.deadline_misses = u64::MAX;
            },
            format!("heartbeat as {process:?} with pid {wrong_pid}, degraded"),
        )
    }
}

/// Publishes one message filled by `fill`, stamped `stamp_ns`, on `publisher` (`topic` names it
/// when the channel refused the soak); returns `said`, what was sent in words.
fn send<T: Payload>(
    publisher: &mut Option<Publisher<T>>,
    topic: &str,
    stamp_ns: u64,
    fill: impl FnOnce(&mut T),
    said: String,
) -> Result<String, String> {
    publisher
        .as_mut()
        .ok_or_else(|| format!("{topic} refused the soak"))?
        .publish_with(stamp_ns, fill)
        .map(|_| said)
        .map_err(|error| error.to_string())
}

/// Random bytes over the whole payload (the header is stamped by the send).
fn fill_random<T: Payload>(value: &mut T, rng: &mut SmallRng) {
    // SAFETY: `T: Payload` requires `T: AnyBitPattern` (derived and checked at compile time: no
    // padding, every bit pattern a valid value), so any bytes written over it leave a valid `T`.
    let bytes = unsafe {
        std::slice::from_raw_parts_mut((value as *mut T).cast::<u8>(), std::mem::size_of::<T>())
    };
    rng.fill_bytes(bytes);
}
