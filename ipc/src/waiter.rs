//! The event loop of every process: an iceoryx2 wait set that wakes on channel events and
//! timers, and ends on SIGINT/SIGTERM through [`crate::termination`]. No sleeping, no polling.

use crate::context::Ipc;
use crate::error::WaitError;
use crate::termination;
use iceoryx2::prelude::*;
use iceoryx2::waitset::WaitSetRunResult;

/// What the callback wants after handling a wake-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Keep waiting.
    Continue,
    /// End the loop.
    Stop,
}

/// Why [`Waiter::run`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunEnd {
    /// SIGINT or SIGTERM.
    Signal,
    /// The callback returned [`Flow::Stop`].
    Stopped,
}

/// A wait set that ends on SIGINT/SIGTERM ([`crate::termination`]).
pub struct Waiter {
    waitset: WaitSet<Ipc>,
}

impl Waiter {
    /// Creates the wait set and installs the termination handler.
    pub fn new() -> Result<Self, WaitError> {
        termination::install_handler().map_err(|error| WaitError {
            reason: format!("cannot install the SIGINT/SIGTERM handler: {error}"),
        })?;
        // iceoryx2's own signal handling stays off: `crate::termination` is the one mechanism.
        let waitset = WaitSetBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|error| WaitError {
                reason: format!("cannot create wait set: {error:?}"),
            })?;
        Ok(Self { waitset })
    }

    /// Attach listeners (`waiter.waitset().attach_notification(subscriber.listener())`) and
    /// intervals here; keep the returned guards alive while running.
    pub fn waitset(&self) -> &WaitSet<Ipc> {
        &self.waitset
    }

    /// Wakes the loop every `period` (a device's clock, housekeeping, heartbeats).
    pub fn attach_interval(
        &self,
        period: std::time::Duration,
    ) -> Result<WaitSetGuard<'_, 'static, Ipc>, WaitError> {
        self.waitset
            .attach_interval(period)
            .map_err(|error| WaitError {
                reason: format!("attach interval {period:?}: {error:?}"),
            })
    }

    /// Wakes the loop when `listener` (a subscriber's) receives an event.
    pub fn attach_listener<'waitset, 'listener>(
        &'waitset self,
        listener: &'listener iceoryx2::port::listener::Listener<Ipc>,
    ) -> Result<WaitSetGuard<'waitset, 'listener, Ipc>, WaitError> {
        self.waitset
            .attach_notification(listener)
            .map_err(|error| WaitError {
                reason: format!("attach listener: {error:?}"),
            })
    }

    /// Runs until SIGINT/SIGTERM ([`crate::termination::requested`], checked before every
    /// wait), or until `on_wake` returns `Stop` or an error (which is returned).
    pub fn run<E>(
        &self,
        mut on_wake: impl FnMut(WaitSetAttachmentId<Ipc>) -> Result<Flow, E>,
    ) -> Result<RunEnd, RunError<E>> {
        let mut failure = None;
        loop {
            if termination::requested() {
                return Ok(RunEnd::Signal);
            }
            let result =
                self.waitset
                    .wait_and_process_once(|attachment| match on_wake(attachment) {
                        Ok(Flow::Continue) => CallbackProgression::Continue,
                        Ok(Flow::Stop) => CallbackProgression::Stop,
                        Err(error) => {
                            failure = Some(error);
                            CallbackProgression::Stop
                        }
                    });
            if let Some(error) = failure.take() {
                return Err(RunError::Callback(error));
            }
            match result {
                // A signal interrupted the wait (the loop's check says whether it was one of
                // ours), or a batch of wake-ups was handled: wait again.
                Ok(WaitSetRunResult::Interrupt | WaitSetRunResult::AllEventsHandled) => {}
                // Not produced with signal handling disabled; it means the same if it were.
                Ok(WaitSetRunResult::TerminationRequest) => return Ok(RunEnd::Signal),
                Ok(WaitSetRunResult::StopRequest) => return Ok(RunEnd::Stopped),
                Err(error) => {
                    return Err(RunError::Wait(WaitError {
                        reason: error.to_string(),
                    }));
                }
            }
        }
    }
}

/// The loop ended with an error.
#[derive(Debug, thiserror::Error)]
pub enum RunError<E> {
    #[error(transparent)]
    /// Waiting failed.
    Wait(WaitError),
    #[error(transparent)]
    /// The callback returned an error.
    Callback(E),
}

impl<E: From<WaitError>> RunError<E> {
    /// One error type for callers whose error already covers wait-set failures.
    pub fn flatten(self) -> E {
        match self {
            Self::Wait(error) => E::from(error),
            Self::Callback(error) => error,
        }
    }
}
