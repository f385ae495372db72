//! Errors of the transport layer. Each names the channel and says what to do.

/// Creating the process's iceoryx2 node failed.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    #[error("invalid node name {name:?}: {reason}")]
    InvalidName { name: String, reason: String },
    #[error(
        "cannot create the iceoryx2 node {name:?} in domain {domain:?}: {reason} \
(is /dev/shm full or not writable? `df -h /dev/shm`)"
    )]
    Create {
        name: String,
        domain: String,
        reason: String,
    },
}

/// Opening a channel (service + its event companion) failed.
#[derive(Debug, thiserror::Error)]
pub enum OpenChannelError {
    #[error(
        "channel {topic:?} exists with an incompatible payload type or QoS \
(expected {type_name} v{version}): {reason}. A process of another version or a crashed stack \
left it behind: stop the other stack, or run `harvest clean --domain {domain}`"
    )]
    Incompatible {
        topic: &'static str,
        type_name: &'static str,
        version: u32,
        domain: String,
        reason: String,
    },
    #[error(
        "channel {topic:?} has no room for another {port}: {reason}. The catalogue's QoS \
(max publishers/subscribers/nodes) is exceeded; a stale process may still hold ports"
    )]
    Exhausted {
        topic: &'static str,
        port: &'static str,
        reason: String,
    },
    #[error(
        "channel {topic:?}: cannot create {port}: {reason}. Shared memory may be exhausted (`df -h /dev/shm`)"
    )]
    Port {
        topic: &'static str,
        port: &'static str,
        reason: String,
    },
    #[error("channel {topic:?}: {reason}")]
    Service { topic: &'static str, reason: String },
}

/// Sending failed.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    #[error(
        "channel {topic:?}: cannot loan a sample: {reason} (all loans in use, or shared memory exhausted)"
    )]
    Loan { topic: &'static str, reason: String },
    #[error("channel {topic:?}: send failed: {reason}")]
    Send { topic: &'static str, reason: String },
}

/// Receiving failed.
#[derive(Debug, thiserror::Error)]
#[error("channel {topic:?}: receive failed: {reason}")]
pub struct ReceiveError {
    pub topic: &'static str,
    pub reason: String,
}

/// Waiting for events failed.
#[derive(Debug, thiserror::Error)]
#[error("wait set: {reason}")]
pub struct WaitError {
    pub reason: String,
}

/// Any failure of the transport layer, for a process error that only passes them on: one
/// `Ipc(#[from] IpcError)` variant plus [`crate::from_ipc_errors!`] instead of a variant per
/// transport error in every process.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    #[error(transparent)]
    Node(#[from] NodeError),
    #[error(transparent)]
    Channel(#[from] OpenChannelError),
    #[error(transparent)]
    Send(#[from] SendError),
    #[error(transparent)]
    Receive(#[from] ReceiveError),
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
