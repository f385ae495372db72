//! What `harvest replay --check` found, per channel, and why it could not run.

use std::path::PathBuf;

use serde_json::Value;

use crate::check::json_diff::{FieldDifference, first_difference};

/// Where a channel's re-run output first differs from the recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Difference {
    /// Log time of the recorded message, seconds from the recording's first message.
    pub at_s: f64,
    /// Position of the message among those compared on its channel (from 0).
    pub message_index: u64,
    pub field: FieldDifference,
}

/// One output channel's comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelCheck {
    pub topic: &'static str,
    /// Messages compared with their recorded counterpart.
    pub compared: u64,
    /// Of those, identical in every compared field.
    pub identical: u64,
    /// Recorded messages the re-run did not send at all.
    pub missing_in_rerun: u64,
    /// Recorded messages not re-run, and why.
    pub not_rerun: u64,
    pub not_rerun_reason: Option<String>,
    /// Messages recorded vs sent by the re-run, when they differ in number.
    pub count_mismatch: Option<(u64, u64)>,
    pub first_difference: Option<Difference>,
}

impl ChannelCheck {
    pub fn new(topic: &'static str) -> Self {
        Self {
            topic,
            compared: 0,
            identical: 0,
            missing_in_rerun: 0,
            not_rerun: 0,
            not_rerun_reason: None,
            count_mismatch: None,
            first_difference: None,
        }
    }

    /// Compares the next recorded message (its log time and JSON view) with the re-run's
    /// message at the same place; either may be missing. A recorded message counts as
    /// compared (and as not sent when the re-run lacks it); the first difference is kept, at
    /// the recorded message's log time or, for a message only the re-run sent,
    /// `rerun_only_at_ns` (`start_ns`: the recording's first log time). Fields `ignored` names
    /// are left out; numbers within `tolerance` are equal.
    pub fn compare_message(
        &mut self,
        recorded: Option<(u64, Value)>,
        rerun: Option<Value>,
        ignored: &[&str],
        tolerance: Option<f64>,
        start_ns: u64,
        rerun_only_at_ns: u64,
    ) {
        let message_index = self.compared;
        let at_ns = recorded
            .as_ref()
            .map_or(rerun_only_at_ns, |(at_ns, _)| *at_ns);
        let difference = match (recorded, rerun) {
            (Some((_, recorded)), Some(rerun)) => {
                self.compared += 1;
                let found = first_difference(&recorded, &rerun, ignored, tolerance);
                self.identical += u64::from(found.is_none());
                found
            }
            (Some((_, recorded)), None) => {
                self.compared += 1;
                self.missing_in_rerun += 1;
                Some(FieldDifference::whole_message(recorded, Value::Null))
            }
            (None, Some(rerun)) => Some(FieldDifference::whole_message(Value::Null, rerun)),
            (None, None) => None,
        };
        if let Some(field) = difference
            && self.first_difference.is_none()
        {
            self.first_difference = Some(Difference {
                at_s: at_ns.saturating_sub(start_ns) as f64 * 1e-9,
                message_index,
                field,
            });
        }
    }

    /// Whether the re-run decided anything other than the recording says.
    pub fn differs(&self) -> bool {
        self.identical != self.compared || self.count_mismatch.is_some()
    }
}

impl std::fmt::Display for ChannelCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "  {:<22} {} compared, {} identical",
            self.topic, self.compared, self.identical
        )?;
        if self.missing_in_rerun > 0 {
            write!(f, ", {} not sent by the re-run", self.missing_in_rerun)?;
        }
        writeln!(f)?;
        if let Some(reason) = &self.not_rerun_reason {
            writeln!(
                f,
                "    {} recorded message(s) not re-run: {reason}",
                self.not_rerun
            )?;
        }
        if let Some((recorded, rerun)) = self.count_mismatch {
            writeln!(f, "    {recorded} recorded, {rerun} sent by the re-run")?;
        }
        if let Some(difference) = &self.first_difference {
            writeln!(
                f,
                "    first difference: message {} at {:.3} s, {}: recorded {}, re-run {}",
                difference.message_index,
                difference.at_s,
                difference.field.field,
                difference.field.recorded,
                difference.field.rerun
            )?;
        }
        Ok(())
    }
}

/// Why the check could not run.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    #[error("{}: {message}", file.display())]
    Read { file: PathBuf, message: String },
    /// A recorded message of a channel the check reads has another schema or does not decode.
    #[error(
        "{topic} at log time {log_time_ns} ns: not this build's schema or undecodable (a recording from another software version?)"
    )]
    Undecodable { topic: String, log_time_ns: u64 },
    /// The recording holds nothing the check can re-run.
    #[error("nothing to check: {0}")]
    NothingToCheck(String),
    /// The node is configured in a way the check cannot re-run.
    #[error("not supported by the check: {0}")]
    Unsupported(String),
    /// A node could not be built from the arguments given for it.
    #[error("settings of a re-run node: {0}")]
    Settings(String),
    /// The re-run node ended the run.
    #[error("the re-run node stopped: {0}")]
    Node(String),
}
