//! Why a mapping step failed.

/// A mapping failed.
#[derive(Debug, thiserror::Error)]
pub enum MapError<E> {
    /// The sink could not take a message (disk full, closed connection).
    #[error("writing a mapped message: {0}")]
    Sink(E),
    /// A recorded payload did not decode as its channel's type.
    #[error("{topic}: cannot decode the recorded payload: {reason}")]
    Decode { topic: String, reason: String },
    /// An image could not be encoded.
    #[error("{topic}: cannot encode the image: {reason}")]
    Image { topic: String, reason: String },
}
