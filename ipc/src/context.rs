//! A process's connection to its domain: one iceoryx2 node, through which typed ports are made.

use crate::catalogue::Channel;
use crate::domain::Domain;
use crate::error::{NodeError, OpenChannelError};
use crate::payload::Payload;
use crate::publisher::Publisher;
use crate::subscriber::Subscriber;
use iceoryx2::node::Node;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

/// The iceoryx2 service flavour of the stack: inter-process, single-threaded ports.
pub type Ipc = ipc::Service;

/// A channel's publish-subscribe service and its companion event service.
type ServicePair<T> = (PubSubFactory<Ipc, T, ()>, EventFactory<Ipc>);

/// One process's node in one domain.
pub struct Context {
    node: Node<Ipc>,
    domain: Domain,
    process_name: String,
}

impl Context {
    /// Creates the node `process_name` in `domain`. Signals are not handled by iceoryx2 here:
    /// each process decides how SIGINT/SIGTERM end its loop (see [`crate::waiter`]).
    pub fn new(domain: &Domain, process_name: &str) -> Result<Self, NodeError> {
        let name = NodeName::new(process_name).map_err(|error| NodeError::InvalidName {
            name: process_name.to_owned(),
            reason: format!("{error:?}"),
        })?;
        let node = NodeBuilder::new()
            .name(&name)
            .config(&domain.iceoryx2_config())
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|error| NodeError::Create {
                name: process_name.to_owned(),
                domain: domain.name().to_owned(),
                reason: format!("{error:?}"),
            })?;
        Ok(Self {
            node,
            domain: domain.clone(),
            process_name: process_name.to_owned(),
        })
    }

    pub fn node(&self) -> &Node<Ipc> {
        &self.node
    }

    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    pub fn process_name(&self) -> &str {
        &self.process_name
    }

    /// A publisher on a catalogue channel.
    pub fn publisher<T: Payload>(
        &self,
        channel: Channel<T>,
    ) -> Result<Publisher<T>, OpenChannelError> {
        let (service, events) = self.open(channel)?;
        let publisher = service
            .publisher_builder()
            .max_loaned_samples(channel.spec.qos.max_loans)
            .create()
            .map_err(|error| port_error(channel, "publisher", format!("{error:?}")))?;
        let notifier: Notifier<Ipc> = events
            .notifier_builder()
            .create()
            .map_err(|error| port_error(channel, "notifier", format!("{error:?}")))?;
        Ok(Publisher::new(channel, publisher, notifier))
    }

    /// A subscriber with the channel's default buffer.
    pub fn subscriber<T: Payload>(
        &self,
        channel: Channel<T>,
    ) -> Result<Subscriber<T>, OpenChannelError> {
        self.subscriber_with_buffer(channel, channel.spec.qos.default_buffer_size)
    }

    /// A subscriber with `buffer_size` slots (clamped to the channel's maximum).
    pub fn subscriber_with_buffer<T: Payload>(
        &self,
        channel: Channel<T>,
        buffer_size: usize,
    ) -> Result<Subscriber<T>, OpenChannelError> {
        let (service, events) = self.open(channel)?;
        let buffer_size = buffer_size.clamp(1, channel.spec.qos.subscriber_max_buffer_size);
        let subscriber = service
            .subscriber_builder()
            .buffer_size(buffer_size)
            .create()
            .map_err(|error| port_error(channel, "subscriber", format!("{error:?}")))?;
        let listener: Listener<Ipc> = events
            .listener_builder()
            .create()
            .map_err(|error| port_error(channel, "listener", format!("{error:?}")))?;
        Ok(Subscriber::new(channel, subscriber, listener))
    }

    fn open<T: Payload>(&self, channel: Channel<T>) -> Result<ServicePair<T>, OpenChannelError> {
        let spec = channel.spec;
        let name =
            ServiceName::new(&spec.service_name()).map_err(|error| OpenChannelError::Service {
                topic: spec.topic,
                reason: format!("invalid service name: {error:?}"),
            })?;
        let qos = spec.qos;
        let service = self
            .node
            .service_builder(&name)
            .publish_subscribe::<T>()
            .history_size(qos.history_size)
            .subscriber_max_buffer_size(qos.subscriber_max_buffer_size)
            .enable_safe_overflow(qos.safe_overflow)
            .max_publishers(qos.max_publishers)
            .max_subscribers(qos.max_subscribers)
            .max_nodes(qos.max_nodes)
            .open_or_create()
            .map_err(|error| {
                let reason = format!("{error:?}");
                if reason.contains("Incompatible") || reason.contains("DoesNotSupport") {
                    OpenChannelError::Incompatible {
                        topic: spec.topic,
                        type_name: spec.type_name,
                        version: spec.version,
                        domain: self.domain.name().to_owned(),
                        reason,
                    }
                } else {
                    OpenChannelError::Service {
                        topic: spec.topic,
                        reason,
                    }
                }
            })?;
        let events = self
            .node
            .service_builder(&name)
            .event()
            .max_notifiers(qos.max_publishers)
            .max_listeners(qos.max_subscribers)
            .max_nodes(qos.max_nodes)
            .open_or_create()
            .map_err(|error| OpenChannelError::Service {
                topic: spec.topic,
                reason: format!("event companion: {error:?}"),
            })?;
        Ok((service, events))
    }
}

fn port_error<T: Payload>(
    channel: Channel<T>,
    port: &'static str,
    reason: String,
) -> OpenChannelError {
    if reason.contains("Exceeds") {
        OpenChannelError::Exhausted {
            topic: channel.spec.topic,
            port,
            reason,
        }
    } else {
        OpenChannelError::Port {
            topic: channel.spec.topic,
            port,
            reason,
        }
    }
}
