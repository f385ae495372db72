//! `harvest fleet`: the station's fleet page. Every robot seen on the link (its liveliness
//! token under `harvest/v1/*/alive`) is one line: mode, e-stop, apples harvested, success
//! rate, alarms (from the robot's `summary`, which it sends on change and every second) and a
//! link to its console. A robot whose token disappears stays listed as lost, with its last
//! line. Served on `--http` (127.0.0.1:8090 by default): `GET /` the page, `GET /api/fleet`
//! the JSON it reads. Watching only: the page sends no command.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use harvest_remote::LinkSettings;
use harvest_remote::fleet_summary::FleetSummary;
use harvest_remote::keys::{ALL_ALIVE, ALL_SUMMARIES, split_key};
use serde_json::json;
use tracing::{info, warn};
use zenoh::Wait;
use zenoh::sample::SampleKind;

use crate::error::RemoteError;
use crate::link_session::{LinkArgs, open_session};

const PAGE: &str = include_str!("page/fleet.html");
/// Longest a connection may take to send its request.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(5);

/// `harvest fleet` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct FleetArgs {
    /// Address of the page.
    #[arg(long, default_value = "127.0.0.1:8090")]
    pub http: SocketAddr,
    #[command(flatten)]
    pub link: LinkArgs,
}

/// What the station knows of one robot.
#[derive(Debug, Clone)]
struct RobotEntry {
    alive: bool,
    changed: Instant,
    summary: Option<FleetSummary>,
}

/// Every robot seen.
#[derive(Debug, Default)]
pub struct Fleet {
    robots: Mutex<BTreeMap<String, RobotEntry>>,
}

impl Fleet {
    fn entry<R>(&self, robot: &str, update: impl FnOnce(&mut RobotEntry) -> R) -> R {
        let mut robots = self.robots.lock().unwrap_or_else(|p| p.into_inner());
        let entry = robots
            .entry(robot.to_owned())
            .or_insert_with(|| RobotEntry {
                alive: false,
                changed: Instant::now(),
                summary: None,
            });
        update(entry)
    }

    /// The JSON of `/api/fleet`.
    pub fn to_json(&self) -> serde_json::Value {
        let robots = self.robots.lock().unwrap_or_else(|p| p.into_inner());
        json!({
            "robots": robots.iter().map(|(name, entry)| json!({
                "robot": name,
                "alive": entry.alive,
                "lost_s": if entry.alive { 0.0 } else { entry.changed.elapsed().as_secs_f64() },
                "summary": entry.summary,
            })).collect::<Vec<_>>(),
        })
    }
}

/// Subscribes to every robot's liveliness and summary; the subscribers live as long as the
/// session (background).
pub fn watch_fleet(session: &zenoh::Session, fleet: &Arc<Fleet>) -> Result<(), RemoteError> {
    let on_alive = Arc::clone(fleet);
    session
        .liveliness()
        .declare_subscriber(ALL_ALIVE)
        .history(true)
        .callback(move |sample| {
            if let Some((robot, _)) = split_key(sample.key_expr().as_str()) {
                let alive = sample.kind() == SampleKind::Put;
                on_alive.entry(robot.as_str(), |entry| {
                    if entry.alive != alive {
                        entry.changed = Instant::now();
                    }
                    entry.alive = alive;
                });
                info!(%robot, alive, "robot seen on the link");
            }
        })
        .background()
        .wait()?;
    let on_summary = Arc::clone(fleet);
    session
        .declare_subscriber(ALL_SUMMARIES)
        .callback(move |sample| {
            let Some((robot, _)) = split_key(sample.key_expr().as_str()) else {
                return;
            };
            match serde_json::from_slice::<FleetSummary>(&sample.payload().to_bytes()) {
                Ok(summary) => {
                    on_summary.entry(robot.as_str(), |entry| entry.summary = Some(summary))
                }
                Err(error) => warn!(%robot, %error, "summary not understood"),
            }
        })
        .background()
        .wait()?;
    Ok(())
}

fn respond(mut stream: TcpStream, fleet: &Fleet) -> std::io::Result<()> {
    stream.set_read_timeout(Some(REQUEST_TIMEOUT))?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut request_line = String::new();
    reader.read_line(&mut request_line)?;
    // Headers up to the blank line (no body is read: only GET is served).
    let mut line = String::new();
    while reader.read_line(&mut line)? > 2 {
        line.clear();
    }
    let mut parts = request_line.split_whitespace();
    let (method, path) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    let (status, content_type, body) = match (method, path) {
        ("GET", "/") => (
            "200 OK",
            "text/html; charset=utf-8",
            PAGE.as_bytes().to_vec(),
        ),
        ("GET", "/api/fleet") => (
            "200 OK",
            "application/json",
            fleet.to_json().to_string().into_bytes(),
        ),
        ("GET", _) => ("404 Not Found", "text/plain", b"not found\n".to_vec()),
        _ => (
            "405 Method Not Allowed",
            "text/plain",
            b"GET only\n".to_vec(),
        ),
    };
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    stream.write_all(&body)
}

/// Runs `harvest fleet` until SIGINT/SIGTERM.
pub fn run(args: &FleetArgs) -> Result<(), RemoteError> {
    let settings = args.link.settings(LinkSettings::station_default())?;
    let session = open_session(&settings, harvest_remote::keys::ROOT)?;
    let fleet = Arc::new(Fleet::default());
    watch_fleet(&session, &fleet)?;
    let listener = TcpListener::bind(args.http)?;
    listener.set_nonblocking(false)?;
    info!(http = %args.http, connect = ?settings.connect, "fleet page served");
    // A thread per connection; the accept loop ends with the process (SIGTERM).
    let accept_fleet = Arc::clone(&fleet);
    std::thread::Builder::new()
        .name("fleet-http".to_owned())
        .spawn(move || {
            for stream in listener.incoming().flatten() {
                let fleet = Arc::clone(&accept_fleet);
                let _ = std::thread::Builder::new()
                    .name("fleet-conn".to_owned())
                    .spawn(move || {
                        if let Err(error) = respond(stream, &fleet) {
                            tracing::debug!(%error, "fleet page connection");
                        }
                    });
            }
        })?;
    // The main thread only waits for SIGINT/SIGTERM (a wait set with a slow interval).
    let waiter = harvest_ipc::Waiter::new()?;
    let _idle = waiter.attach_interval(Duration::from_secs(1))?;
    waiter
        .run(|_| Ok::<_, RemoteError>(harvest_ipc::Flow::Continue))
        .map_err(harvest_ipc::waiter::RunError::flatten)?;
    drop(session);
    Ok(())
}
