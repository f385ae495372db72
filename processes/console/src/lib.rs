//! `harvest console`: the operator's page in a browser ([dual-arm sec. 3.4, Fig. 10]: a
//! control panel and a status panel; plus the camera view with the detections, the top view
//! and the process table). A small HTTP server ([`http`]) serves the page (HTML, JS and CSS
//! inside the binary, [`page`]), the status as JSON ([`status_board`]), the camera view as JPEG
//! ([`camera_view`]) and takes operator commands, which go to the executive on
//! `operator/command` with the token the operator typed ([`process`]).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod camera_view;
pub mod command_lane;
pub mod error;
pub mod http;
pub mod page;
pub mod process;
pub mod status_board;

pub use error::ConsoleError;
pub use process::{ConsoleArgs, run};
