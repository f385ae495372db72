//! A console lane's port over the remote link: each command goes as the station's request to
//! the robot's command key (the e-stop to its own key, without a token), and the answer is the
//! executive's own, or the robot link's refusal (rate, size, syntax) saying so.

use std::sync::Arc;
use std::time::Duration;

use harvest_console::command_lane::{CommandAnswer, CommandPort, LaneCommand, PortOpener};
use harvest_operator::Command;
use harvest_remote::remote_request::{Answerer, RemoteReply, RemoteRequest};
use harvest_remote_process::station_ctl::{Station, command_request};

use crate::relayed_sessions::RelayedSessions;

struct LinkPort {
    station: Arc<Station>,
    relayed: Arc<RelayedSessions>,
}

/// The console's answer for a reply from the robot's link.
pub fn answer_of(reply: RemoteReply) -> CommandAnswer {
    let reason = match reply.by {
        Answerer::Executive => reply.reason,
        Answerer::Remote => format!("refused by the robot's link: {}", reply.reason),
    };
    CommandAnswer {
        accepted: reply.accepted,
        reason,
        refusal: reply.refusal,
        mode: reply.mode,
        motion_duration_ms: reply.motion_duration_ms,
    }
}

impl CommandPort for LinkPort {
    fn send(
        &mut self,
        command: &LaneCommand,
        ack_timeout: Duration,
    ) -> Result<Option<CommandAnswer>, String> {
        self.relayed.note(command.session);
        let request = RemoteRequest {
            session: command.session,
            token: (!command.token.is_empty()).then(|| command.token.clone()),
            client: format!("station {}", command.client),
            command: command_request(command.command),
        };
        let estop = command.command == Command::EmergencyStop;
        let reply = self
            .station
            .send_request(&request, estop, ack_timeout)
            .map_err(|error| format!("the link to the robot failed: {error}"))?;
        Ok(reply.map(answer_of))
    }
}

/// Ports that send through `station`.
pub fn link_port_opener(station: Arc<Station>, relayed: Arc<RelayedSessions>) -> PortOpener {
    Box::new(move || {
        Ok(Box::new(LinkPort {
            station: station.clone(),
            relayed: relayed.clone(),
        }) as Box<dyn CommandPort>)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refusal_by_the_link_says_so() {
        let answer = answer_of(RemoteReply::refused_by_remote(
            "RateLimited",
            "too many commands".to_owned(),
        ));
        assert!(!answer.accepted);
        assert_eq!(answer.refusal.as_deref(), Some("RateLimited"));
        assert!(answer.reason.starts_with("refused by the robot's link"));
    }
}
