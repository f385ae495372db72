//! Errors of the transport layer. Each names the channel and says what to do.

/// Creating the process's iceoryx2 node failed.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The node name is not one iceoryx2 accepts.
    #[error("invalid node name {name:?}: {reason}")]
    InvalidName {
        /// The name asked for (the process name).
        name: String,
        /// iceoryx2's reason for refusing it.
        reason: String,
    },
    /// iceoryx2 could not create the node (usually shared memory in `/dev/shm`).
    #[error(
        "cannot create the iceoryx2 node {name:?} in domain {domain:?}: {reason} \
(is /dev/shm full or not writable? `df -h /dev/shm`)"
    )]
    Create {
        /// The node name (the process name).
        name: String,
        /// The iceoryx2 domain (service-name prefix) the node was created in.
        domain: String,
        /// iceoryx2's error, as text.
        reason: String,
    },
}

/// Opening a channel (service + its event companion) or one of its ports failed. The variants
/// are chosen from iceoryx2's error enums (see `crate::context`), never from their text.
#[derive(Debug, thiserror::Error)]
pub enum OpenChannelError {
    /// The channel's service exists with another payload type, layout version, iceoryx2 version
    /// or a smaller QoS than the catalogue's.
    #[error(
        "channel {topic:?} in domain {domain:?} exists, but {mismatch} (this process expects \
{type_name} v{version}). A process of another version or a crashed stack left it behind: stop \
the other stack, or run `harvest clean --domain {domain}`"
    )]
    Incompatible {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// The payload type this process expects (the catalogue's type name).
        type_name: &'static str,
        /// The payload layout version this process expects.
        version: u32,
        /// The iceoryx2 domain the channel lives in.
        domain: String,
        /// How the existing service differs.
        mismatch: Incompatibility,
    },
    /// The channel already has as many ports of this kind as its QoS allows.
    #[error(
        "channel {topic:?} has no room for another {port}: its service allows {limit} \
(catalogue QoS); a stale process may still hold ports (`harvest clean`)"
    )]
    PortLimit {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// The kind of port that found no room.
        port: PortKind,
        /// The service's limit for `port`.
        limit: usize,
    },
    /// Shared memory for the port could not be allocated.
    #[error(
        "channel {topic:?}: no shared memory for the {port}'s data segment (`df -h /dev/shm`; \
its size is the payload size times subscribers x (buffer + borrowed) + history + loans)"
    )]
    OutOfMemory {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// The kind of port whose segment could not be allocated.
        port: PortKind,
    },
    /// Another failure creating a port.
    #[error("channel {topic:?}: cannot create the {port}: {reason}")]
    Port {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// The kind of port being created.
        port: PortKind,
        /// iceoryx2's error, as text.
        reason: String,
    },
    /// Another failure opening or creating the channel's services.
    #[error("channel {topic:?}: {reason}")]
    Service {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// iceoryx2's error, as text.
        reason: String,
    },
}

/// The kind of iceoryx2 port (or participant) a channel operation concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PortKind {
    /// The publisher of a channel's payloads.
    Publisher,
    /// A subscriber of a channel's payloads.
    Subscriber,
    /// The event notifier paired with every publisher.
    Notifier,
    /// The event listener paired with every subscriber.
    Listener,
    /// A node (process) attached to the channel's service.
    Node,
}

impl std::fmt::Display for PortKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Publisher => "publisher",
            Self::Subscriber => "subscriber",
            Self::Notifier => "notifier",
            Self::Listener => "listener",
            Self::Node => "node",
        })
    }
}

/// How an existing service differs from what the catalogue asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Incompatibility {
    /// Another payload type or layout version (iceoryx2 type name, size or alignment).
    PayloadType,
    /// Created by another iceoryx2 version.
    Iceoryx2Version,
    /// Another messaging pattern (a service of the same name that is not publish-subscribe, or
    /// an event companion that is not an event service).
    MessagingPattern,
    /// Other service attributes.
    Attributes,
    /// A smaller QoS setting than requested (names which).
    Qos(&'static str),
}

impl std::fmt::Display for Incompatibility {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::PayloadType => f.write_str("with another payload type or layout version"),
            Self::Iceoryx2Version => f.write_str("created by another iceoryx2 version"),
            Self::MessagingPattern => f.write_str("with another messaging pattern"),
            Self::Attributes => f.write_str("with other service attributes"),
            Self::Qos(setting) => write!(f, "with a smaller {setting} than the catalogue's QoS"),
        }
    }
}

/// Sending failed.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    /// The publisher already holds as many loans as the channel's QoS allows.
    #[error(
        "channel {topic:?}: cannot loan a sample: all {max_loans} loans of the publisher are in \
use (send or drop a loan first)"
    )]
    LoansExhausted {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// The publisher's loan limit (catalogue QoS).
        max_loans: usize,
    },
    /// Every sample of the publisher's data segment is in use (held by subscribers or loans).
    #[error(
        "channel {topic:?}: cannot loan a sample: every sample of the publisher's data segment is \
in use (subscribers hold them longer than the QoS budgets)"
    )]
    OutOfMemory {
        /// The channel's topic in the catalogue.
        topic: &'static str,
    },
    /// Another failure loaning a sample.
    #[error("channel {topic:?}: cannot loan a sample: {reason}")]
    Loan {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// iceoryx2's error, as text.
        reason: String,
    },
    /// Delivering the sample (or notifying its listeners) failed.
    #[error("channel {topic:?}: send failed: {reason}")]
    Send {
        /// The channel's topic in the catalogue.
        topic: &'static str,
        /// iceoryx2's error, as text.
        reason: String,
    },
}

/// Receiving failed.
#[derive(Debug, thiserror::Error)]
#[error("channel {topic:?}: receive failed: {reason}")]
pub struct ReceiveError {
    /// The channel's topic in the catalogue.
    pub topic: &'static str,
    /// iceoryx2's error, as text.
    pub reason: String,
}

/// Waiting for events failed.
#[derive(Debug, thiserror::Error)]
#[error("wait set: {reason}")]
pub struct WaitError {
    /// iceoryx2's error, as text.
    pub reason: String,
}

/// Any failure of the transport layer, for a process error that only passes them on: one
/// `Ipc(#[from] IpcError)` variant plus [`crate::from_ipc_errors!`] instead of a variant per
/// transport error in every process.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// Creating the node failed.
    #[error(transparent)]
    Node(#[from] NodeError),
    /// Opening a channel or a port failed.
    #[error(transparent)]
    Channel(#[from] OpenChannelError),
    /// Loaning or sending a sample failed.
    #[error(transparent)]
    Send(#[from] SendError),
    /// Receiving a sample failed.
    #[error(transparent)]
    Receive(#[from] ReceiveError),
    /// Waiting for events failed.
    #[error(transparent)]
    Wait(#[from] WaitError),
}

/// Implements `From<E>` for every transport error `E` on an error type that has
/// `From<IpcError>` (usually an `Ipc(#[from] IpcError)` variant), so `?` works on each of them.
#[macro_export]
macro_rules! from_ipc_errors {
    ($target:ty) => {
        $crate::from_ipc_errors!(@one $target, $crate::error::NodeError);
        $crate::from_ipc_errors!(@one $target, $crate::error::OpenChannelError);
        $crate::from_ipc_errors!(@one $target, $crate::error::SendError);
        $crate::from_ipc_errors!(@one $target, $crate::error::ReceiveError);
        $crate::from_ipc_errors!(@one $target, $crate::error::WaitError);
    };
    (@one $target:ty, $source:ty) => {
        impl From<$source> for $target {
            fn from(error: $source) -> Self {
                Self::from($crate::error::IpcError::from(error))
            }
        }
    };
}
