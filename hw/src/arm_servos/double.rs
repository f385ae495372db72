//! A servo double for testing what a control loop does when the servos fail: an ideal servo
//! (each accepted set-point is reached at once, `hold` keeps the position) whose reads and
//! writes fail on command, and which logs every call with the time it was made.
//!
//! The test keeps a [`ServoDoubleControl`] (cheap to clone, shared across threads) to inject
//! failures and read the call log while the loop under test owns the [`ServoDouble`].

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use harvest_ipc::MonotonicClock;

use super::{ArmServos, JOINT_COUNT, JointFeedback};
use crate::error_kind::{DeviceError, ErrorKind};

/// A failure the double was told to produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ServoDoubleError {
    /// Reads fail ([`ServoDoubleControl::fail_reads`]).
    #[error("encoder read failed (injected)")]
    ReadFailed,
    /// Writes fail ([`ServoDoubleControl::fail_writes`]).
    #[error("servo write failed (injected)")]
    WriteFailed,
}

impl DeviceError for ServoDoubleError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Timeout
    }
}

/// What the loop asked of the servos.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ServoCallKind {
    /// `feedback()`.
    Read,
    /// `command(position, _)`.
    Command {
        /// The set-points: D in m, theta/phi/twist in rad.
        position: [f64; JOINT_COUNT],
    },
    /// `hold()`.
    Hold,
}

/// One logged call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoCall {
    /// When it was made (monotonic clock).
    pub at_ns: u64,
    /// What was called.
    pub kind: ServoCallKind,
    /// Whether the double let it succeed.
    pub succeeded: bool,
}

#[derive(Debug, Default)]
struct Shared {
    fail_reads: AtomicBool,
    fail_writes: AtomicBool,
    calls: Mutex<Vec<ServoCall>>,
}

/// The test's handle on a [`ServoDouble`]: failure switches and the call log.
#[derive(Debug, Clone, Default)]
pub struct ServoDoubleControl(Arc<Shared>);

impl ServoDoubleControl {
    /// Every `feedback()` fails from now on (`true`) or succeeds again (`false`).
    pub fn fail_reads(&self, fail: bool) {
        self.0.fail_reads.store(fail, Ordering::SeqCst);
    }

    /// Every `command()` and `hold()` fails from now on (`true`) or succeeds again (`false`).
    pub fn fail_writes(&self, fail: bool) {
        self.0.fail_writes.store(fail, Ordering::SeqCst);
    }

    /// Every call so far, in order.
    pub fn calls(&self) -> Vec<ServoCall> {
        self.0
            .calls
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    fn log(&self, kind: ServoCallKind, succeeded: bool) {
        let call = ServoCall {
            at_ns: MonotonicClock::read_ns(),
            kind,
            succeeded,
        };
        self.0
            .calls
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(call);
    }
}

/// The double itself (see the module documentation).
#[derive(Debug)]
pub struct ServoDouble {
    control: ServoDoubleControl,
    position: [f64; JOINT_COUNT],
}

impl ServoDouble {
    /// A double standing at `position`, with its control handle.
    pub fn new(position: [f64; JOINT_COUNT]) -> (Self, ServoDoubleControl) {
        let control = ServoDoubleControl::default();
        let double = Self {
            control: control.clone(),
            position,
        };
        (double, control)
    }

    fn write(&self, kind: ServoCallKind) -> Result<(), ServoDoubleError> {
        let fail = self.control.0.fail_writes.load(Ordering::SeqCst);
        self.control.log(kind, !fail);
        if fail {
            Err(ServoDoubleError::WriteFailed)
        } else {
            Ok(())
        }
    }
}

impl ArmServos for ServoDouble {
    type Error = ServoDoubleError;

    fn command(
        &mut self,
        position: [f64; JOINT_COUNT],
        _velocity: [f64; JOINT_COUNT],
    ) -> Result<(), Self::Error> {
        self.write(ServoCallKind::Command { position })?;
        self.position = position;
        Ok(())
    }

    fn hold(&mut self) -> Result<(), Self::Error> {
        self.write(ServoCallKind::Hold)
    }

    fn feedback(&mut self) -> Result<Option<JointFeedback>, Self::Error> {
        let fail = self.control.0.fail_reads.load(Ordering::SeqCst);
        self.control.log(ServoCallKind::Read, !fail);
        if fail {
            return Err(ServoDoubleError::ReadFailed);
        }
        Ok(Some(JointFeedback {
            capture_ns: MonotonicClock::read_ns(),
            position: self.position,
            velocity: [0.0; JOINT_COUNT],
            fault_bits: 0,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fails_on_command_and_logs_every_call() {
        let (mut servos, control) = ServoDouble::new([0.1, 0.0, 0.0, 0.0]);
        assert!(servos.feedback().is_ok_and(|f| f.is_some()));
        control.fail_reads(true);
        control.fail_writes(true);
        assert_eq!(servos.feedback(), Err(ServoDoubleError::ReadFailed));
        assert_eq!(servos.hold(), Err(ServoDoubleError::WriteFailed));
        assert!(servos.command([0.2, 0.0, 0.0, 0.0], [0.0; 4]).is_err());
        control.fail_reads(false);
        control.fail_writes(false);
        assert!(servos.command([0.2, 0.0, 0.0, 0.0], [0.0; 4]).is_ok());
        let position = servos.feedback().ok().flatten().map(|f| f.position);
        assert_eq!(position, Some([0.2, 0.0, 0.0, 0.0]));
        let calls = control.calls();
        assert_eq!(calls.len(), 6);
        assert_eq!(
            calls.iter().map(|c| c.succeeded).collect::<Vec<_>>(),
            [true, false, false, false, true, true]
        );
        assert!(calls.windows(2).all(|w| w[0].at_ns <= w[1].at_ns));
    }
}
