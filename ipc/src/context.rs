//! A process's connection to its domain: one iceoryx2 node, through which typed ports are made.

use crate::any_bit_pattern::AnyBitPattern;
use crate::catalogue::{Channel, ChannelSpec};
use crate::domain::Domain;
use crate::error::{Incompatibility, NodeError, OpenChannelError, PortKind};
use crate::payload::Payload;
use crate::publisher::Publisher;
use crate::subscriber::Subscriber;
use iceoryx2::node::Node;
use iceoryx2::port::listener::{Listener, ListenerCreateError};
use iceoryx2::port::notifier::{Notifier, NotifierCreateError};
use iceoryx2::port::publisher::PublisherCreateError;
use iceoryx2::port::subscriber::SubscriberCreateError;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::event::{EventOpenError, EventOpenOrCreateError};
use iceoryx2::service::builder::publish_subscribe::{
    PublishSubscribeOpenError, PublishSubscribeOpenOrCreateError,
};
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
    /// SIGINT/SIGTERM end a loop through [`crate::termination`].
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

    /// The process's iceoryx2 node.
    pub fn node(&self) -> &Node<Ipc> {
        &self.node
    }

    /// The domain the node lives in.
    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    /// The name the process was launched under (its node name).
    pub fn process_name(&self) -> &str {
        &self.process_name
    }

    /// A publisher on a catalogue channel.
    pub fn publisher<T: Payload>(
        &self,
        channel: Channel<T>,
    ) -> Result<Publisher<T>, OpenChannelError> {
        let (service, events) = self.open(channel)?;
        let topic = channel.spec.topic;
        let publisher = service
            .publisher_builder()
            .max_loaned_samples(channel.spec.qos.max_loans)
            .create()
            .map_err(|error| match error {
                PublisherCreateError::ExceedsMaxSupportedPublishers => {
                    OpenChannelError::PortLimit {
                        topic,
                        port: PortKind::Publisher,
                        limit: service.static_config().max_publishers(),
                    }
                }
                PublisherCreateError::UnableToCreateDataSegment => OpenChannelError::OutOfMemory {
                    topic,
                    port: PortKind::Publisher,
                },
                other => OpenChannelError::Port {
                    topic,
                    port: PortKind::Publisher,
                    reason: other.to_string(),
                },
            })?;
        let notifier: Notifier<Ipc> =
            events
                .notifier_builder()
                .create()
                .map_err(|error| match error {
                    NotifierCreateError::ExceedsMaxSupportedNotifiers => {
                        OpenChannelError::PortLimit {
                            topic,
                            port: PortKind::Notifier,
                            limit: events.static_config().max_notifiers(),
                        }
                    }
                    other => OpenChannelError::Port {
                        topic,
                        port: PortKind::Notifier,
                        reason: other.to_string(),
                    },
                })?;
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
        let topic = channel.spec.topic;
        let buffer_size = buffer_size.clamp(1, channel.spec.qos.subscriber_max_buffer_size);
        let subscriber = service
            .subscriber_builder()
            .buffer_size(buffer_size)
            .create()
            .map_err(|error| match error {
                SubscriberCreateError::ExceedsMaxSupportedSubscribers => {
                    OpenChannelError::PortLimit {
                        topic,
                        port: PortKind::Subscriber,
                        limit: service.static_config().max_subscribers(),
                    }
                }
                other => OpenChannelError::Port {
                    topic,
                    port: PortKind::Subscriber,
                    reason: other.to_string(),
                },
            })?;
        let listener: Listener<Ipc> =
            events
                .listener_builder()
                .create()
                .map_err(|error| match error {
                    ListenerCreateError::ExceedsMaxSupportedListeners => {
                        OpenChannelError::PortLimit {
                            topic,
                            port: PortKind::Listener,
                            limit: events.static_config().max_listeners(),
                        }
                    }
                    other => OpenChannelError::Port {
                        topic,
                        port: PortKind::Listener,
                        reason: other.to_string(),
                    },
                })?;
        Ok(Subscriber::new(channel, subscriber, listener))
    }

    fn open<T: Payload>(&self, channel: Channel<T>) -> Result<ServicePair<T>, OpenChannelError> {
        // A generic payload type (a benchmark's) is checked for padding here, once per type.
        let () = <T as AnyBitPattern>::LAYOUT_CHECK;
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
            .subscriber_max_borrowed_samples(crate::catalogue::SUBSCRIBER_MAX_BORROWED_SAMPLES)
            .enable_safe_overflow(qos.safe_overflow)
            .max_publishers(qos.max_publishers)
            .max_subscribers(qos.max_subscribers)
            .max_nodes(qos.max_nodes)
            .open_or_create()
            .map_err(|error| self.service_error(spec, ServiceFailure::from(error)))?;
        let events = self
            .node
            .service_builder(&name)
            .event()
            .max_notifiers(qos.max_publishers)
            .max_listeners(qos.max_subscribers)
            .max_nodes(qos.max_nodes)
            .open_or_create()
            .map_err(|error| self.service_error(spec, ServiceFailure::from(error)))?;
        Ok((service, events))
    }

    fn service_error(&self, spec: ChannelSpec, failure: ServiceFailure) -> OpenChannelError {
        match failure {
            ServiceFailure::Incompatible(mismatch) => OpenChannelError::Incompatible {
                topic: spec.topic,
                type_name: spec.type_name,
                version: spec.version,
                domain: self.domain.name().to_owned(),
                mismatch,
            },
            ServiceFailure::NodeLimit => OpenChannelError::PortLimit {
                topic: spec.topic,
                port: PortKind::Node,
                limit: spec.qos.max_nodes,
            },
            ServiceFailure::Other(reason) => OpenChannelError::Service {
                topic: spec.topic,
                reason,
            },
        }
    }
}

/// What opening or creating one of a channel's two services ran into, sorted by iceoryx2's
/// error variants.
#[derive(Debug)]
enum ServiceFailure {
    Incompatible(Incompatibility),
    /// The service already has its maximum of nodes.
    NodeLimit,
    /// Anything else, with iceoryx2's error (its `Display` names the variant).
    Other(String),
}

impl From<PublishSubscribeOpenOrCreateError> for ServiceFailure {
    fn from(error: PublishSubscribeOpenOrCreateError) -> Self {
        use Incompatibility::{Attributes, Iceoryx2Version, MessagingPattern, PayloadType, Qos};
        use PublishSubscribeOpenError as Open;
        let PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError(open) = error else {
            return Self::Other(error.to_string());
        };
        Self::Incompatible(match open {
            Open::IncompatibleTypes => PayloadType,
            Open::VersionMismatch => Iceoryx2Version,
            Open::IncompatibleMessagingPattern => MessagingPattern,
            Open::IncompatibleAttributes => Attributes,
            Open::DoesNotSupportRequestedMinBufferSize => Qos("subscriber max buffer size"),
            Open::DoesNotSupportRequestedMinHistorySize => Qos("history size"),
            Open::DoesNotSupportRequestedMinSubscriberBorrowedSamples => {
                Qos("subscriber max borrowed samples")
            }
            Open::DoesNotSupportRequestedAmountOfPublishers => Qos("max publishers"),
            Open::DoesNotSupportRequestedAmountOfSubscribers => Qos("max subscribers"),
            Open::DoesNotSupportRequestedAmountOfNodes => Qos("max nodes"),
            Open::IncompatibleOverflowBehavior => Qos("overflow behaviour"),
            Open::ExceedsMaxNumberOfNodes => return Self::NodeLimit,
            other => return Self::Other(other.to_string()),
        })
    }
}

impl From<EventOpenOrCreateError> for ServiceFailure {
    fn from(error: EventOpenOrCreateError) -> Self {
        use EventOpenError as Open;
        use Incompatibility::{Attributes, MessagingPattern, Qos};
        let EventOpenOrCreateError::EventOpenError(open) = error else {
            return Self::Other(format!("event companion: {error}"));
        };
        Self::Incompatible(match open {
            Open::IncompatibleMessagingPattern => MessagingPattern,
            Open::IncompatibleAttributes => Attributes,
            Open::DoesNotSupportRequestedAmountOfNotifiers => Qos("max publishers (notifiers)"),
            Open::DoesNotSupportRequestedAmountOfListeners => Qos("max subscribers (listeners)"),
            Open::DoesNotSupportRequestedAmountOfNodes => Qos("max nodes"),
            Open::ExceedsMaxNumberOfNodes => return Self::NodeLimit,
            other => return Self::Other(format!("event companion: {other}")),
        })
    }
}
