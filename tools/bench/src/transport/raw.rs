//! Raw iceoryx2, without our layer: the same publish-subscribe and event services our layer
//! builds (same QoS), used directly. In poll mode the sender does not notify (nobody listens),
//! which is what a raw iceoryx2 user would do; our layer always notifies.

use super::{OnMessage, ReceivePort, SendPort};
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::WakeMode;
use crate::sender_write::PayloadWriter;
use crate::watchdog::{WATCH_PERIOD, Watchdog};
use harvest_ipc::{Domain, Flow, Ipc, MonotonicClock};
use iceoryx2::node::Node;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use iceoryx2::waitset::WaitSetRunResult;

/// The services of one benchmark payload in a domain (the node last, so it is dropped last).
struct RawServices<T: BenchMessage> {
    service: PubSubFactory<Ipc, T, ()>,
    events: EventFactory<Ipc>,
    name: String,
    _node: Node<Ipc>,
}

fn raw_error(operation: &'static str, service: &str, error: impl std::fmt::Debug) -> BenchError {
    BenchError::Iceoryx2 {
        operation,
        service: service.to_owned(),
        reason: format!("{error:?}"),
    }
}

impl<T: BenchMessage> RawServices<T> {
    fn open(domain: &Domain, node_name: &str, payload: &'static str) -> Result<Self, BenchError> {
        let name = format!("bench/{payload}");
        let node_name = NodeName::new(node_name).map_err(|e| raw_error("node name", &name, e))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&domain.iceoryx2_config())
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|e| raw_error("create node", &name, e))?;
        let service_name =
            ServiceName::new(&name).map_err(|e| raw_error("service name", &name, e))?;
        let qos = T::qos();
        let service = node
            .service_builder(&service_name)
            .publish_subscribe::<T>()
            .history_size(qos.history_size)
            .subscriber_max_buffer_size(qos.subscriber_max_buffer_size)
            .enable_safe_overflow(qos.safe_overflow)
            .max_publishers(qos.max_publishers)
            .max_subscribers(qos.max_subscribers)
            .max_nodes(qos.max_nodes)
            .open_or_create()
            .map_err(|e| raw_error("open publish-subscribe service", &name, e))?;
        let events = node
            .service_builder(&service_name)
            .event()
            .max_notifiers(qos.max_publishers)
            .max_listeners(qos.max_subscribers)
            .max_nodes(qos.max_nodes)
            .open_or_create()
            .map_err(|e| raw_error("open event service", &name, e))?;
        Ok(Self {
            service,
            events,
            name,
            _node: node,
        })
    }

    fn error(&self, operation: &'static str, error: impl std::fmt::Debug) -> BenchError {
        raw_error(operation, &self.name, error)
    }
}

/// Loans, writes in place, sends; notifies in event mode.
pub struct RawSender<T: BenchMessage> {
    publisher: Publisher<Ipc, T, ()>,
    notifier: Option<Notifier<Ipc>>,
    services: RawServices<T>,
    next_seq: u64,
}

impl<T: BenchMessage> RawSender<T> {
    pub fn open(
        domain: &Domain,
        mode: WakeMode,
        payload: &'static str,
    ) -> Result<Self, BenchError> {
        let services = RawServices::<T>::open(domain, "bench-raw-sender", payload)?;
        let publisher = services
            .service
            .publisher_builder()
            .max_loaned_samples(T::qos().max_loans)
            .create()
            .map_err(|error| services.error("create publisher", error))?;
        let notifier = match mode {
            WakeMode::Event => Some(
                services
                    .events
                    .notifier_builder()
                    .create()
                    .map_err(|error| services.error("create notifier", error))?,
            ),
            WakeMode::Poll => None,
        };
        Ok(Self {
            publisher,
            notifier,
            services,
            next_seq: 1,
        })
    }
}

impl<T: BenchMessage> SendPort<T> for RawSender<T> {
    fn send(&mut self, phase: Phase, writer: &mut PayloadWriter) -> Result<u64, BenchError> {
        let msg_seq = self.next_seq;
        let uninit = self
            .publisher
            .loan_uninit()
            .map_err(|error| self.services.error("loan", error))?;
        // SAFETY: `T: Payload` guarantees every bit pattern is a valid `T`, and loaned
        // shared-memory bytes are always initialized (as in harvest_ipc's Publisher::loan).
        let mut sample = unsafe { uninit.assume_init() };
        let publish_ns = writer.write_stamped(sample.payload_mut(), msg_seq, phase);
        sample
            .send()
            .map_err(|error| self.services.error("send", error))?;
        self.next_seq += 1;
        if let Some(notifier) = &self.notifier {
            notifier
                .notify()
                .map_err(|error| self.services.error("notify", error))?;
        }
        Ok(MonotonicClock::read_ns().saturating_sub(publish_ns))
    }
}

/// Subscribes (the QoS's default buffer) and waits in an iceoryx2 wait set (event mode) or
/// spins on `receive` (poll mode).
pub struct RawReceiver<T: BenchMessage> {
    subscriber: Subscriber<Ipc, T, ()>,
    listener: Option<Listener<Ipc>>,
    waitset: Option<WaitSet<Ipc>>,
    services: RawServices<T>,
}

impl<T: BenchMessage> RawReceiver<T> {
    pub fn open(
        domain: &Domain,
        mode: WakeMode,
        payload: &'static str,
    ) -> Result<Self, BenchError> {
        let services = RawServices::<T>::open(domain, "bench-raw-receiver", payload)?;
        let subscriber = services
            .service
            .subscriber_builder()
            .buffer_size(T::qos().default_buffer_size)
            .create()
            .map_err(|error| services.error("create subscriber", error))?;
        let (listener, waitset) = match mode {
            WakeMode::Event => {
                let listener = services
                    .events
                    .listener_builder()
                    .create()
                    .map_err(|error| services.error("create listener", error))?;
                let waitset = WaitSetBuilder::new()
                    .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
                    .create::<Ipc>()
                    .map_err(|error| services.error("create wait set", error))?;
                (Some(listener), Some(waitset))
            }
            WakeMode::Poll => (None, None),
        };
        Ok(Self {
            subscriber,
            listener,
            waitset,
            services,
        })
    }
}

impl<T: BenchMessage> ReceivePort<T> for RawReceiver<T> {
    fn run_phase(
        &mut self,
        watchdog: &mut Watchdog,
        on_message: &mut OnMessage<'_, T>,
    ) -> Result<(), BenchError> {
        let subscriber = &self.subscriber;
        let services = &self.services;
        let receive = || {
            subscriber
                .receive()
                .map_err(|error| services.error("receive", error))
        };
        let (Some(listener), Some(waitset)) = (&self.listener, &self.waitset) else {
            loop {
                match receive()? {
                    Some(sample) => {
                        let recv_ns = MonotonicClock::read_ns();
                        if on_message(sample.payload(), recv_ns)? == Flow::Stop {
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
        let _listener_guard = waitset
            .attach_notification(listener)
            .map_err(|error| services.error("attach listener", error))?;
        let tick = waitset
            .attach_interval(WATCH_PERIOD)
            .map_err(|error| services.error("attach interval", error))?;
        let mut failure = None;
        let mut on_wake = |attachment: WaitSetAttachmentId<Ipc>| -> Result<Flow, BenchError> {
            if attachment.has_event_from(&tick) {
                watchdog.check()?;
                return Ok(Flow::Continue);
            }
            listener
                .try_wait(|_| {})
                .map_err(|error| services.error("drain events", error))?;
            while let Some(sample) = receive()? {
                let recv_ns = MonotonicClock::read_ns();
                if on_message(sample.payload(), recv_ns)? == Flow::Stop {
                    return Ok(Flow::Stop);
                }
            }
            Ok(Flow::Continue)
        };
        let result = waitset.wait_and_process(|attachment| match on_wake(attachment) {
            Ok(Flow::Continue) => CallbackProgression::Continue,
            Ok(Flow::Stop) => CallbackProgression::Stop,
            Err(error) => {
                failure = Some(error);
                CallbackProgression::Stop
            }
        });
        if let Some(error) = failure {
            return Err(error);
        }
        match result {
            Ok(WaitSetRunResult::StopRequest | WaitSetRunResult::AllEventsHandled) => Ok(()),
            Ok(WaitSetRunResult::Interrupt | WaitSetRunResult::TerminationRequest) => {
                Err(BenchError::Interrupted)
            }
            Err(error) => Err(services.error("wait", error)),
        }
    }
}
