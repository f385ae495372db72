//! The simulated tractor pulling the robot's trailer along the row ([dual-arm sec. 2.2] and
//! 4.1), served on `hw/tractor/command` (in) and `hw/tractor/feedback` (out, 20 Hz).
//!
//! Dynamics: `dx/dt = clamp((r - x) / tau, 0, v)` toward the target `r` (the tractor creeps at
//! the row's `speed_m_per_s`, `tau` = 0.5 s of final approach), snapping onto the target once
//! within 1 mm. It only drives forward: targets behind the trailer, past the end of the row or
//! not finite are refused (the target is kept) and the feedback says so. A stop makes the
//! current position the target. The physics thread turns the position into the robot's offset
//! along the row ([`crate::world_motion`]).

use harvest_ipc::catalogue::{HW_TRACTOR_COMMAND, HW_TRACTOR_FEEDBACK};
use harvest_ipc::payloads::TractorStatus;
use harvest_ipc::payloads::{TractorCommand, TractorFeedback};
use harvest_ipc::{Context, MonotonicClock, Publisher, Subscriber};
use std::time::{Duration, Instant};

/// Feedback period of the simulated tractor.
pub const TRACTOR_FEEDBACK_PERIOD: Duration = Duration::from_millis(50);
/// Time constant of the final approach, s.
const APPROACH_TIME_CONSTANT_S: f64 = 0.5;
/// The trailer stops on the target once this close, m.
const ARRIVAL_TOLERANCE_M: f64 = 1e-3;

/// The tractor's motion along the row (pure, steppable).
#[derive(Debug, Clone, PartialEq)]
pub struct TractorMotion {
    speed_m_per_s: f64,
    row_end_m: f64,
    position_m: f64,
    target_m: f64,
    velocity_m_per_s: f64,
    last_command_ns: u64,
    status: TractorStatus,
}

impl TractorMotion {
    /// Standing at `start_m` on a row ending at `row_end_m`, creeping at `speed_m_per_s`.
    pub fn new(speed_m_per_s: f64, start_m: f64, row_end_m: f64) -> Self {
        Self {
            speed_m_per_s,
            row_end_m,
            position_m: start_m,
            target_m: start_m,
            velocity_m_per_s: 0.0,
            last_command_ns: 0,
            status: TractorStatus::Ok,
        }
    }

    pub fn position_m(&self) -> f64 {
        self.position_m
    }

    pub fn in_motion(&self) -> bool {
        self.position_m != self.target_m
    }

    /// Acts on one command; returns whether it was accepted.
    pub fn apply(&mut self, stop: bool, target_m: f64, command_ns: u64) -> bool {
        self.last_command_ns = command_ns;
        if stop {
            self.target_m = self.position_m;
            self.velocity_m_per_s = 0.0;
            self.status = TractorStatus::Ok;
            return true;
        }
        if !(target_m.is_finite() && target_m >= self.position_m && target_m <= self.row_end_m) {
            tracing::warn!(
                target_m,
                position_m = self.position_m,
                row_end_m = self.row_end_m,
                "tractor target refused"
            );
            self.status = TractorStatus::Refused;
            return false;
        }
        self.target_m = target_m;
        self.status = TractorStatus::Ok;
        true
    }

    /// Advances the trailer by `dt_s`.
    pub fn step(&mut self, dt_s: f64) {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return;
        }
        let error_m = self.target_m - self.position_m;
        if error_m.abs() <= ARRIVAL_TOLERANCE_M {
            self.position_m = self.target_m;
            self.velocity_m_per_s = 0.0;
            return;
        }
        let velocity = (error_m / APPROACH_TIME_CONSTANT_S).clamp(0.0, self.speed_m_per_s);
        self.velocity_m_per_s = velocity;
        self.position_m = (self.position_m + velocity * dt_s).min(self.target_m);
    }

    fn write_feedback(&self, feedback: &mut TractorFeedback) {
        feedback.position_m = self.position_m;
        feedback.velocity_m_per_s = self.velocity_m_per_s;
        feedback.target_m = self.target_m;
        feedback.row_end_m = self.row_end_m;
        feedback.last_command_ns = self.last_command_ns;
        feedback.in_motion = u8::from(self.in_motion());
        feedback.status.set(self.status);
        feedback._reserved = [0; 6];
    }
}

/// The tractor behind its hardware channels.
pub struct TractorDeviceServer {
    motion: TractorMotion,
    commands: Subscriber<TractorCommand>,
    feedback: Publisher<TractorFeedback>,
    last_tick: Instant,
}

impl TractorDeviceServer {
    pub fn open(
        context: &Context,
        motion: TractorMotion,
    ) -> Result<Self, harvest_ipc::error::OpenChannelError> {
        Ok(Self {
            motion,
            commands: context.subscriber(HW_TRACTOR_COMMAND)?,
            feedback: context.publisher(HW_TRACTOR_FEEDBACK)?,
            last_tick: Instant::now(),
        })
    }

    pub fn position_m(&self) -> f64 {
        self.motion.position_m()
    }

    /// Acts on the commands received, advances by the elapsed host time, publishes feedback.
    pub fn tick(&mut self) -> Result<(), harvest_ipc::error::IpcError> {
        while let Some(command) = self.commands.receive()? {
            self.motion.apply(
                command.stop != 0,
                command.target_m,
                command.header.capture_ns,
            );
        }
        let now = Instant::now();
        let dt_s = now.duration_since(self.last_tick).as_secs_f64().min(1.0);
        self.last_tick = now;
        self.motion.step(dt_s);
        let motion = &self.motion;
        self.feedback
            .publish_with(MonotonicClock::read_ns(), |feedback| {
                motion.write_feedback(feedback);
            })?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drives_forward_at_its_speed_and_refuses_the_rest() {
        let mut motion = TractorMotion::new(0.3, 1.0, 5.0);
        assert!(!motion.apply(false, 0.5, 1), "behind the trailer");
        assert!(!motion.apply(false, 5.5, 2), "past the end");
        assert!(!motion.apply(false, f64::NAN, 3));
        assert!(motion.apply(false, 2.0, 4));
        motion.step(1.0);
        assert!((motion.position_m() - 1.3).abs() < 1e-9);
        for _ in 0..100 {
            motion.step(0.1);
        }
        assert_eq!(motion.position_m(), 2.0);
        assert!(!motion.in_motion());
    }
}
