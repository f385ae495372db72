//! The command lanes: a queryable each (the command key, the e-stop key), a thread each with
//! its own `operator/command` publisher, so a stop goes out at once even while another
//! command waits for its answer. Each query passes `harvest_remote::InboundGate` (one gate for
//! both lanes: its counters are the robot's), then goes to the executive as one more client
//! session; the executive's acknowledgement is the reply. A refusal by the gate is a reply too
//! (`"by": "remote"`), so the station always learns why.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use harvest_ipc::operator_client::OperatorClient;
use harvest_ipc::payloads::{OperatorModeCode, OperatorRefusalCode};
use harvest_ipc::{Context, Domain, MonotonicClock};
use harvest_remote::remote_request::{Answerer, RemoteReply};
use harvest_remote::{InboundGate, RobotKeys};
use tracing::{debug, info, warn};
use zenoh::Wait;
use zenoh::query::Query;

use crate::error::RemoteError;

/// Which lane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaneKind {
    EmergencyStop,
    Command,
}

/// Declares the lane's queryable and starts its thread.
pub fn spawn(
    kind: LaneKind,
    session: &zenoh::Session,
    keys: &RobotKeys,
    domain: &Domain,
    process_name: &str,
    gate: Arc<Mutex<InboundGate>>,
    ack_timeout: Duration,
) -> Result<(), RemoteError> {
    let key = match kind {
        LaneKind::EmergencyStop => keys.estop(),
        LaneKind::Command => keys.command(),
    };
    let queryable = session
        .declare_queryable(key.clone())
        .complete(true)
        .wait()?;
    let domain = domain.clone();
    let node_name = match kind {
        LaneKind::EmergencyStop => format!("{process_name}-estop"),
        LaneKind::Command => format!("{process_name}-command"),
    };
    spawn_with_client(node_name, domain, move |client| {
        info!(%key, "command lane ready");
        while let Ok(query) = queryable.recv() {
            answer(&query, &gate, client, ack_timeout);
        }
    })
}

/// Starts thread `node_name` with its own node in `domain` and its own `operator/command`
/// client (iceoryx2 ports are not Send: each thread opens its own), and runs `serve` with it.
pub fn spawn_with_client(
    node_name: String,
    domain: Domain,
    serve: impl FnOnce(&mut OperatorClient) + Send + 'static,
) -> Result<(), RemoteError> {
    std::thread::Builder::new()
        .name(node_name.clone())
        .spawn(move || {
            let result = (|| -> Result<(), RemoteError> {
                let context = Context::new(&domain, &node_name)?;
                let mut client = OperatorClient::new(&context)?;
                serve(&mut client);
                Ok(())
            })();
            if let Err(error) = result {
                warn!(%error, thread = node_name, "could not start");
            }
        })?;
    Ok(())
}

fn reply(query: &Query, answer: &RemoteReply) {
    if let Err(error) = query
        .reply(query.key_expr().clone(), answer.to_json())
        .wait()
    {
        debug!(%error, "reply not sent (station gone?)");
    }
}

fn answer(
    query: &Query,
    gate: &Mutex<InboundGate>,
    client: &mut OperatorClient,
    ack_timeout: Duration,
) {
    let payload = query
        .payload()
        .map(|p| p.to_bytes().into_owned())
        .unwrap_or_default();
    let key = query.key_expr().as_str().to_owned();
    let admitted = match gate.lock() {
        Ok(mut gate) => gate.admit(&key, &payload, MonotonicClock::read_ns()),
        Err(poisoned) => poisoned
            .into_inner()
            .admit(&key, &payload, MonotonicClock::read_ns()),
    };
    let admitted = match admitted {
        Ok(admitted) => admitted,
        Err(refusal) => {
            warn!(%key, %refusal, "remote command refused");
            reply(
                query,
                &RemoteReply::refused_by_remote(refusal.code(), refusal.to_string()),
            );
            return;
        }
    };
    let message =
        admitted
            .command
            .to_message(0, admitted.session, &admitted.token, &admitted.client);
    let sent = client
        .send(message)
        .and_then(|request| client.wait_ack(admitted.session, request, ack_timeout));
    let answer = match sent {
        Ok(Some(ack)) => RemoteReply {
            accepted: ack.accepted != 0,
            by: Answerer::Executive,
            refusal: (ack.accepted == 0).then(|| {
                OperatorRefusalCode::from_code(ack.refusal)
                    .map_or_else(|| format!("code {}", ack.refusal), |c| format!("{c:?}"))
            }),
            reason: ack.reason.as_str().to_owned(),
            mode: OperatorModeCode::from_code(ack.mode).map(|m| m.name().to_owned()),
            motion_duration_ms: ack.motion_duration_ms,
        },
        Ok(None) => RemoteReply::refused_by_remote(
            "NoAnswer",
            format!(
                "no answer from the executive within {} ms",
                ack_timeout.as_millis()
            ),
        ),
        Err(error) => RemoteReply::refused_by_remote("Unreachable", error.to_string()),
    };
    debug!(
        command = admitted.command.name(),
        accepted = answer.accepted,
        "remote command answered"
    );
    reply(query, &answer);
}
