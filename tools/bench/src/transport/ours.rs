//! Our layer: harvest_ipc `Context`, `Publisher`, `Subscriber` and `Waiter` on the payload's
//! catalogue channel (sweep sizes: an ad-hoc channel, `Channel::ad_hoc`), exactly as the
//! stack's processes use them.

use super::{OnMessage, ReceivePort, SendPort};
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::WakeMode;
use crate::payload_case::PayloadCase;
use crate::sender_write::PayloadWriter;
use crate::watchdog::{WATCH_PERIOD, Watchdog};
use harvest_ipc::error::WaitError;
use harvest_ipc::{
    Context, Domain, Flow, MonotonicClock, Publisher, RunEnd, RunError, Subscriber, Waiter,
};

/// Publishes on the channel of `payload` (see [`BenchMessage::channel`]).
pub struct OursSender<T: BenchMessage> {
    publisher: Publisher<T>,
    _context: Context,
}

impl<T: BenchMessage> OursSender<T> {
    pub fn open(domain: &Domain, payload: PayloadCase) -> Result<Self, BenchError> {
        let context = Context::new(domain, "bench-sender")?;
        let publisher = context.publisher(T::channel(payload.topic()))?;
        Ok(Self {
            publisher,
            _context: context,
        })
    }
}

impl<T: BenchMessage> SendPort<T> for OursSender<T> {
    fn send(&mut self, phase: Phase, writer: &mut PayloadWriter) -> Result<u64, BenchError> {
        // `Publisher::send` numbers messages last_seq + 1 and stamps publish_ns itself.
        let msg_seq = self.publisher.last_seq() + 1;
        let mut loan = self.publisher.loan()?;
        let capture_ns = MonotonicClock::read_ns();
        writer.write(&mut *loan, msg_seq, phase);
        loan.header_mut().capture_ns = capture_ns;
        let call_ns = MonotonicClock::read_ns();
        self.publisher.send(loan)?;
        Ok(MonotonicClock::read_ns().saturating_sub(call_ns))
    }
}

/// Subscribes to the channel of `payload` (default buffer) and wakes through a `Waiter`
/// (event mode) or spins on `Subscriber::receive` (poll mode).
pub struct OursReceiver<T: BenchMessage> {
    subscriber: Subscriber<T>,
    waiter: Option<Waiter>,
    _context: Context,
}

impl<T: BenchMessage> OursReceiver<T> {
    pub fn open(domain: &Domain, mode: WakeMode, payload: PayloadCase) -> Result<Self, BenchError> {
        let context = Context::new(domain, "bench-receiver")?;
        let subscriber = context.subscriber(T::channel(payload.topic()))?;
        let waiter = match mode {
            WakeMode::Event => Some(Waiter::new()?),
            WakeMode::Poll => None,
        };
        Ok(Self {
            subscriber,
            waiter,
            _context: context,
        })
    }
}

impl<T: BenchMessage> ReceivePort<T> for OursReceiver<T> {
    fn run_phase(
        &mut self,
        watchdog: &mut Watchdog,
        on_message: &mut OnMessage<'_, T>,
    ) -> Result<(), BenchError> {
        let subscriber = &self.subscriber;
        let Some(waiter) = &self.waiter else {
            loop {
                match subscriber.poll()? {
                    Some(sample) => {
                        let recv_ns = MonotonicClock::read_ns();
                        if on_message(&sample, recv_ns)? == Flow::Stop {
                            return Ok(());
                        }
                    }
                    None => {
                        watchdog.poll_check()?;
                        std::hint::spin_loop();
                    }
                }
            }
        };
        let waitset = waiter.waitset();
        let _listener = waitset
            .attach_notification(subscriber.listener())
            .map_err(|error| WaitError {
                reason: format!("attach listener: {error:?}"),
            })?;
        let tick = waitset
            .attach_interval(WATCH_PERIOD)
            .map_err(|error| WaitError {
                reason: format!("attach interval: {error:?}"),
            })?;
        let end = waiter.run(|attachment| -> Result<Flow, BenchError> {
            if attachment.has_event_from(&tick) {
                watchdog.check()?;
                return Ok(Flow::Continue);
            }
            while let Some(sample) = subscriber.receive()? {
                let recv_ns = MonotonicClock::read_ns();
                if on_message(&sample, recv_ns)? == Flow::Stop {
                    return Ok(Flow::Stop);
                }
            }
            Ok(Flow::Continue)
        });
        match end {
            Ok(RunEnd::Stopped) => Ok(()),
            Ok(RunEnd::Signal) => Err(BenchError::Interrupted),
            Err(RunError::Callback(error)) => Err(error),
            Err(RunError::Wait(error)) => Err(error.into()),
        }
    }
}
