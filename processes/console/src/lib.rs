//! `harvest console`: the operator's page in a browser ([dual-arm sec. 3.4, Fig. 10]: a
//! control panel and a status panel; plus the camera view with the detections, the top view
//! and the process table). An HTTP server on hyper ([`server`], [`routes`]) serves the page
//! (HTML, JS and CSS inside the binary, [`page`]) and one push connection per page ([`push`]):
//! the status ([`status_board`]) and the camera view as JPEG ([`camera_view`]) go out as they
//! are made, the operator's commands come in and go to the executive on `operator/command`
//! with the token the operator typed ([`command_lane`], [`operator_api`]), the marks go on
//! `operator/mark` ([`mark_outlet`]). Connections and push sessions are bounded
//! ([`admission`]); the controlling page is never locked out ([`process`]).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod admission;
pub mod camera_view;
pub mod command_lane;
pub mod error;
pub mod mark_outlet;
pub mod operator_api;
pub mod page;
pub mod process;
pub mod push;
pub mod routes;
pub mod server;
pub mod shared;
pub mod stack_clock;
pub mod status_board;

pub use error::ConsoleError;
pub use process::{ConsoleArgs, run};
