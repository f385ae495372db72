//! The client side of the operator channels, for command-line tools: send one command on
//! `operator/command` and wait (event-driven, bounded) for its acknowledgement on
//! `operator/ack`. The console, which keeps its own loop, uses the same channels directly.

use std::time::{Duration, Instant};

use crate::MonotonicClock;
use crate::catalogue::{OPERATOR_ACK, OPERATOR_COMMAND};
use crate::context::Context;
use crate::error::{OpenChannelError, ReceiveError, SendError};
use crate::payloads::{OperatorAck, OperatorCommand};
use crate::publisher::Publisher;
use crate::subscriber::Subscriber;

/// Why a request got no answer.
#[derive(Debug, thiserror::Error)]
pub enum OperatorClientError {
    #[error(transparent)]
    /// Opening the operator channels failed.
    Open(#[from] OpenChannelError),
    #[error(transparent)]
    /// Sending the command failed.
    Send(#[from] SendError),
    #[error(transparent)]
    /// Receiving the acknowledgement failed.
    Receive(#[from] ReceiveError),
}

/// One client session's ports.
pub struct OperatorClient {
    commands: Publisher<OperatorCommand>,
    acks: Subscriber<OperatorAck>,
    next_request_id: u64,
}

impl OperatorClient {
    /// Opens the ports. The acknowledgement subscriber exists before the first command is
    /// sent, so no answer is missed.
    pub fn new(context: &Context) -> Result<Self, OperatorClientError> {
        let acks = context.subscriber_with_buffer(OPERATOR_ACK, 64)?;
        let commands = context.publisher(OPERATOR_COMMAND)?;
        // Request ids start from the clock so two runs of a tool in one session differ.
        let next_request_id = MonotonicClock::read_ns().max(1);
        Ok(Self {
            commands,
            acks,
            next_request_id,
        })
    }

    /// Sends `message` with a fresh request id (written into it); returns that id.
    pub fn send(&mut self, mut message: OperatorCommand) -> Result<u64, OperatorClientError> {
        let request_id = self.next_request_id;
        self.next_request_id += 1;
        message.request_id = request_id;
        message.header.capture_ns = MonotonicClock::read_ns();
        self.commands.publish(&message)?;
        Ok(request_id)
    }

    /// The acknowledgement of `request_id` of `session_id`, waiting up to `timeout`; `None` if
    /// none came (no executive running?).
    pub fn wait_ack(
        &self,
        session_id: u64,
        request_id: u64,
        timeout: Duration,
    ) -> Result<Option<OperatorAck>, OperatorClientError> {
        let deadline = Instant::now() + timeout;
        loop {
            while let Some(ack) = self.acks.receive()? {
                if ack.session_id == session_id && ack.request_id == request_id {
                    return Ok(Some(*ack));
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            if let Err(error) = self.acks.listener().timed_wait(|_| {}, deadline - now) {
                tracing::debug!(?error, "waiting for an acknowledgement interrupted");
            }
        }
    }
}
