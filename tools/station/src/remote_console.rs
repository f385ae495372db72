//! `harvest console --remote ROBOT`: the robot's console page served on the station, fed over
//! the remote link. The server, the page, the push connections, the admission limits and the
//! command lanes are the console's own; only what feeds them differs: the robot's link instead
//! of its shared memory ([`crate::link_feed`]), commands as queries to the robot
//! ([`crate::link_port`]). Marks are not carried over the link (the page says so when asked).
//!
//! The status loop (a wait set at 10 Hz, ended by SIGINT/SIGTERM) serializes the board and
//! says on the page when the robot is not seen on the link (its liveliness token gone): the
//! command paths are shown down, so nobody takes an unanswered page for a live one. A station
//! that holds manual control and loses the link stops sending heartbeats; the robot's executive
//! then stops the motion within 500 ms, as for a page on the robot.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use harvest_console::ConsoleArgs;
use harvest_console::command_lane::Lane;
use harvest_console::process::{ConsoleServer, join_threads, publish_status, status_json};
use harvest_ipc::{Flow, RunError, Waiter};
use harvest_remote::RobotName;
use harvest_remote_process::link_session::LinkArgs;
use harvest_remote_process::station_ctl::Station;
use serde_json::json;

use crate::error::StationError;
use crate::link_feed::LinkFeed;
use crate::link_port::link_port_opener;
use crate::relayed_sessions::RelayedSessions;

/// Status refresh period (as on the robot's console).
const STATUS_PERIOD: Duration = Duration::from_millis(100);

/// Runs the station's console for `robot` until SIGINT/SIGTERM.
pub fn run(args: &ConsoleArgs, robot: RobotName, link: &LinkArgs) -> Result<(), StationError> {
    let station = Arc::new(Station::open(robot.clone(), link)?);
    let relayed = Arc::new(RelayedSessions::default());
    let stop = Arc::new(AtomicBool::new(false));
    let (estop_lane, estop_thread) = Lane::spawn(
        "e-stop",
        link_port_opener(station.clone(), relayed.clone()),
        args.ack_timeout(),
        stop.clone(),
    )?;
    let (command_lane, command_thread) = Lane::spawn(
        "command",
        link_port_opener(station.clone(), relayed.clone()),
        args.ack_timeout(),
        stop.clone(),
    )?;
    let shared = args.shared(estop_lane, command_lane, None);
    let mut feed = LinkFeed::start(station, shared.clone(), relayed)?;
    let server = ConsoleServer::start(shared.clone(), args)?;
    tracing::info!(listen = %args.listen, %robot, "station console: the robot's page over the link");

    let waiter = Waiter::new()?;
    let _tick = waiter.attach_interval(STATUS_PERIOD)?;
    let not_seen = format!("robot `{robot}` not seen on the link");
    let result = waiter
        .run(|_| -> Result<Flow, StationError> {
            feed.watch_camera(shared.admission.sessions() > 0)?;
            let now_ns = shared.clock.now_ns();
            let mut status = {
                let board = feed.state.board.lock().unwrap_or_else(|p| p.into_inner());
                status_json(&board, &shared, now_ns)
            };
            let seen = feed.state.robot_seen.load(Ordering::Acquire);
            if !seen {
                for lane in ["estop", "commands"] {
                    status["links"][lane] = json!({"ok": false, "problem": not_seen});
                }
            }
            status["remote"] = json!({
                "robot": robot.as_str(),
                "seen": seen,
                "images": feed.state.images.load(Ordering::Relaxed),
                "undecodable": feed.state.undecodable.load(Ordering::Relaxed),
            });
            publish_status(&shared, &status);
            Ok(Flow::Continue)
        })
        .map_err(RunError::flatten);

    stop.store(true, Ordering::Release);
    server.stop();
    drop(feed);
    join_threads(vec![("e-stop", estop_thread), ("command", command_thread)]);
    result.map(|_| ())
}
