//! harvest-node: the contract every node of the robot implements, and the one tick that runs
//! it, written once for every process, evaluation and test.
//!
//! The models are copper's tasks and ros2_control's read -> update -> write: a node declares
//! its inputs per channel and how each is read ([`ports::Latest`]: the newest sample heard,
//! [`ports::Drain`]: every sample since the last tick), its outputs ([`ports::Out`]), its
//! devices ([`node::Devices`]: read, write and the safe state) and its period, and has a
//! transport-free [`node::Node::step`]. [`tick::Runner`] does what each process used to
//! hand-write around its node, in this order, on every tick:
//!
//! 1. the emergency stop is read first; while it is engaged the devices are stopped (brake,
//!    close every valve) before anything else, whatever the devices do;
//! 2. the devices are read; a failed read means hold (the arm brakes; the valves stay as they
//!    are) and is counted (a streak as long as the node's limit ends the run, so the
//!    supervisor restarts the process);
//! 3. the operator's mode is read and turned into what the node may do by the one rule
//!    ([`harvest_robot_model::obedience`](mod@harvest_robot_model::obedience): no mode heard means hold unless the node was told
//!    it runs without an operator);
//! 4. the declared inputs are read, the node steps, and its device commands are written unless
//!    step 1 or 2 stopped or held the devices (a refused write means hold);
//! 5. the node learns what became of its commands ([`node::Node::finish`]) and its outputs are
//!    published.
//!
//! The runner is generic over a [`transport::Transport`]: `harvest-runtime` runs it on
//! iceoryx2 channels (the processes); [`in_process`] runs nodes on a simulated clock in a
//! deterministic order, exchanging messages through an in-memory bus (the evaluations, the
//! tests).
//!
//! No transport here: a node implements the contract without iceoryx2.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod in_place;
pub mod in_process;
pub mod node;
pub mod ports;
pub mod source;
pub mod tick;
pub mod tick_record;
pub mod transport;

pub use in_place::{LatestInPlace, Loaned, SampleHolder};
pub use in_process::{Bus, Schedule};
pub use node::{Applied, Devices, Node, NodeHealth, NodeTick};
pub use ports::{Drain, Latest, Out};
pub use source::{Capture, Source, SourceCounts, SourceError};
pub use tick::{Runner, RunnerConfig, TickError};
pub use tick_record::TickRecorder;
pub use transport::{InputVisitor, Inputs, OutputVisitor, Outputs, Transport};
