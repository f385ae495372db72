//! What the console's threads and the server's tasks share.

use std::sync::Arc;
use std::sync::atomic::AtomicU64;
use std::time::Duration;

use tokio::sync::watch;
use tokio_tungstenite::tungstenite::Utf8Bytes;

use crate::admission::Admission;
use crate::camera_view::CameraView;
use crate::command_lane::Lane;
use crate::mark_outlet::MarkOutlet;
use crate::stack_clock::StackClock;

/// The shared state (see [`crate::process`] for who writes what).
pub struct Shared {
    /// The newest camera view.
    pub view: CameraView,
    /// The newest status JSON (`{"type": "status", ...}`), written by the status thread at
    /// its rate; each push connection sends the newest one when it can.
    pub status: watch::Sender<Utf8Bytes>,
    /// The emergency stop's own lane.
    pub estop_lane: Lane,
    /// Every other command.
    pub command_lane: Lane,
    /// The operator's marks (`None` on a station: the link carries no marks).
    pub marks: Option<MarkOutlet>,
    /// How long a lane waits for the executive's answer.
    pub ack_timeout: Duration,
    /// The session the executive says is in control (0: none), from `operator/mode`.
    pub controlling_session: AtomicU64,
    /// Connections and push sessions.
    pub admission: Arc<Admission>,
    /// The stack's clock, for the pages' clock readings.
    pub clock: StackClock,
}
