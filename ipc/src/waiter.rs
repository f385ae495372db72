//! The event loop of every process: an iceoryx2 wait set that wakes on channel events and
//! timers, and ends on SIGINT/SIGTERM. No sleeping, no polling.

use crate::context::Ipc;
use crate::error::WaitError;
use iceoryx2::prelude::*;
use iceoryx2::waitset::WaitSetRunResult;

/// What the callback wants after handling a wake-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    Continue,
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

/// A wait set that handles termination signals.
pub struct Waiter {
    waitset: WaitSet<Ipc>,
}

impl Waiter {
    pub fn new() -> Result<Self, WaitError> {
        let waitset = WaitSetBuilder::new()
            .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
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

    /// Runs until a signal, or until `on_wake` returns `Stop` or an error (which is returned).
    pub fn run<E>(
        &self,
        mut on_wake: impl FnMut(WaitSetAttachmentId<Ipc>) -> Result<Flow, E>,
    ) -> Result<RunEnd, RunError<E>> {
        let mut failure = None;
        let result = self
            .waitset
            .wait_and_process(|attachment| match on_wake(attachment) {
                Ok(Flow::Continue) => CallbackProgression::Continue,
                Ok(Flow::Stop) => CallbackProgression::Stop,
                Err(error) => {
                    failure = Some(error);
                    CallbackProgression::Stop
                }
            });
        if let Some(error) = failure {
            return Err(RunError::Callback(error));
        }
        match result {
            Ok(WaitSetRunResult::Interrupt | WaitSetRunResult::TerminationRequest) => {
                Ok(RunEnd::Signal)
            }
            Ok(WaitSetRunResult::StopRequest | WaitSetRunResult::AllEventsHandled) => {
                Ok(RunEnd::Stopped)
            }
            Err(error) => Err(RunError::Wait(WaitError {
                reason: format!("{error:?}"),
            })),
        }
    }
}

/// The loop ended with an error.
#[derive(Debug, thiserror::Error)]
pub enum RunError<E> {
    #[error(transparent)]
    Wait(WaitError),
    #[error(transparent)]
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
